"""Progress and per-phase timing for long steps (assembly, factorisation, eigen solves, ...)."""

from __future__ import annotations

import contextlib
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


def peak_memory_mb() -> float:
    """Peak resident set size of this process so far, in MiB (Linux ru_maxrss is in KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
