"""Progress and per-phase timing for long steps (assembly, factorisation, eigen solves, ...)."""

from __future__ import annotations

import contextlib
import ctypes
import resource
import sys
import time


class Phases:
    """Collects wall-clock seconds per named phase and prints progress lines to stderr.

    >>> ph = Phases(verbose=False)
    >>> with ph("assemble"):
    ...     pass
    >>> sorted(ph.timings_s)
    ['assemble']
    """

    def __init__(self, verbose: bool = True, stream=None):
        self.verbose = verbose
        self.stream = stream if stream is not None else sys.stderr
        self.timings_s: dict[str, float] = {}

    def note(self, text: str) -> None:
        """A one-line remark (an estimate, a choice) on the progress stream."""
        if self.verbose:
            print(f"  {text}", file=self.stream, flush=True)

    @contextlib.contextmanager
    def __call__(self, name: str, detail: str = ""):
        if self.verbose:
            print(f"  {name}{' ' + detail if detail else ''} ...", file=self.stream, flush=True)
        t0 = time.perf_counter()
        try:
            yield
        finally:
            dt = time.perf_counter() - t0
            self.timings_s[name] = self.timings_s.get(name, 0.0) + dt
        if self.verbose:              # only when the phase succeeded: an error line follows otherwise
            print(f"  {name} done in {dt:.2f} s", file=self.stream, flush=True)


#: plain progress lines (stderr not a terminal): one per this fraction of the simulated time
PLAIN_FRACTION = 0.1


class SimulationProgress:
    """The progress of a simulation on stderr: simulated time, steps per second and the time left.

    A rich progress bar when ``stream`` is a terminal, plain lines (one per PLAIN_FRACTION of the
    run) otherwise; nothing when ``enabled`` is False.  Use as a context manager; the instance is
    the ``progress`` callable(t, t_end, steps) of SolverSettings.
    """

    def __init__(self, t_end: float, enabled: bool = True, stream=None):
        self.t_end, self.enabled = float(t_end), enabled
        self.stream = stream if stream is not None else sys.stderr
        self.bar = self.task = None
        self.t0 = time.perf_counter()
        self.next_line = PLAIN_FRACTION

    def __enter__(self):
        self.t0 = time.perf_counter()
        if self.enabled and self.stream.isatty():
            # rich costs ~0.2 s to import: only a run drawn on a terminal pays it
            from rich.console import Console  # deferred: 0.2 s import, terminals only
            from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

            self.bar = Progress(TextColumn("  simulate"), BarColumn(),
                                TextColumn("t = {task.completed:.4g} / {task.total:g} s"),
                                TextColumn("{task.fields[rate]}"), TimeRemainingColumn(),
                                console=Console(file=self.stream), transient=True)
            self.bar.start()
            self.task = self.bar.add_task("", total=self.t_end, rate="")
        return self

    def __exit__(self, *exc):
        if self.bar is not None:
            self.bar.stop()

    def __call__(self, t: float, t_end: float, steps: int) -> None:
        if not self.enabled:
            return
        elapsed = max(time.perf_counter() - self.t0, 1e-9)
        rate = f"{steps / elapsed:.0f} steps/s"
        if self.bar is not None:
            self.bar.update(self.task, completed=min(t, t_end), rate=rate)
            return
        fraction = t / t_end if t_end > 0 else 1.0
        if fraction >= self.next_line or fraction >= 1.0:
            left = elapsed * (1.0 - fraction) / max(fraction, 1e-12)
            print(f"  simulate t = {t:.4g} / {t_end:g} s ({100 * fraction:.0f} %), {rate}, about {left:.0f} s left",
                  file=self.stream, flush=True)
            while self.next_line <= fraction:
                self.next_line += PLAIN_FRACTION


def _status_kib(field: str) -> float | None:
    """A field of Linux /proc/self/status in KiB ("VmHWM", "VmRSS"); None elsewhere."""
    try:
        with open("/proc/self/status") as status:
            return next(float(line.split()[1]) for line in status if line.startswith(field + ":"))
    except (OSError, StopIteration):
        return None


def peak_memory_mb() -> float:
    """Peak resident set size of this process's own memory so far, MiB: Linux VmHWM, else ru_maxrss.

    ru_maxrss keeps the parent's RSS at the fork before a child's exec: a pool spawned by a 2 GB
    driver reported 2 GB workers (tests/test_parts.py); VmHWM starts afresh at the exec."""
    peak = _status_kib("VmHWM")
    if peak is None:
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # KiB on Linux and BSD
    return peak / 1024.0


def resident_memory_bytes() -> float:
    """This process's resident memory now, bytes: Linux VmRSS, else its peak (``peak_memory_mb``)."""
    rss = _status_kib("VmRSS")
    return 1024.0 * rss if rss is not None else 2.0**20 * peak_memory_mb()


def return_freed_memory() -> None:
    """Give the heap's freed pages back to the system (glibc ``malloc_trim(0)``; nothing elsewhere).

    A local pool worker's freed arrays below glibc's mmap threshold (raised up to 32 MB as large
    blocks are freed) stay in its heap: three parts reduced and solved one after another in a thread,
    nothing kept, left 444 MB resident of which malloc_trim returned 228 (475k bar in 8).  Dask's
    nanny sets MALLOC_TRIM_THRESHOLD_, which keeps that threshold fixed, yet a 2.5 GB Dask worker idle
    after the parts' substructured solves gave back 320 of its 1114 MB anonymous memory."""
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None).malloc_trim(0)                   # the process's own symbols: libc's, on Linux
