"""Compile the solver's kernels ahead of the first run: a few steps of each given scene with
each integration method, so that every kernel signature a scene can reach is compiled and
cached (kernel_cache.py), and every kernel call made from Python is recorded and compiled ahead
of time into one extension (aot.py; ``SIDPREP_AOT=0`` skips it).  The install runs it
(setup.py) on the bundled example scenes::

    python -m sidprep.solver.prebuild examples/*/scene*.toml
"""

from __future__ import annotations

import os
import sys
import time

from sidprep.errors import InputError, SimulationFailed
from sidprep.solver.equations import aot
from sidprep.solver.integrators.settings import ADAPTIVE_ONLY, METHODS
from sidprep.solver.scene import load_scene, simulate

#: steps of each short run: enough for the start, the loop, dense output and the post-processing
PREBUILD_STEPS = 4
#: error tolerance of the error-controlled methods in the short runs
PREBUILD_RTOL = 1e-4


def prebuild_scene(path: str) -> list[str]:
    """Run ``path`` for PREBUILD_STEPS steps with every method it accepts, at a fixed step and
    error-controlled -> the runs made."""
    scene = load_scene(path)
    h = scene.settings.h
    done = []
    for method in METHODS:
        for rtol in (PREBUILD_RTOL,) if method in ADAPTIVE_ONLY else (None, PREBUILD_RTOL):
            try:
                simulate(scene, t_end=PREBUILD_STEPS * h, method=method, rtol=rtol, output_dt=h)
            except (InputError, SimulationFailed):  # a method this kind of scene does not take
                continue
            except Exception as exc:  # noqa: BLE001 - a failing scene must not stop the others' kernels
                done.append(f"{method} failed ({type(exc).__name__}: {exc})")
                continue
            done.append(method if rtol is None else f"{method} rtol")
    return done


def compile_ahead_of_time() -> None:
    """Compile the kernel calls recorded from Python into the entry-kernel extension; one line."""
    start = time.process_time()
    try:
        entries = aot.compile_recorded()
    except Exception as exc:  # noqa: BLE001 - the JIT kernels above stay usable without it
        print(f"prebuild: ahead-of-time kernels not compiled ({type(exc).__name__}: {exc})")
        return
    kernels = {entry["kernel"] for entry in entries}
    print(f"prebuild: {len(entries)} entry signatures of {len(kernels)} kernels compiled ahead of time "
          f"({time.process_time() - start:.1f} CPU s)")


def main(paths: list[str]) -> int:
    """Prebuild every scene in ``paths``, then compile the recorded entry calls ahead of time
    (unless SIDPREP_AOT=0); one line per scene on stdout; 0 unless none ran."""
    ahead_of_time = os.environ.get(aot.SWITCH, "1") != "0"
    if ahead_of_time:
        aot.record_calls()
    ran = 0
    for path in paths:
        start = time.process_time()
        try:
            methods = prebuild_scene(path)
        except (InputError, SimulationFailed) as exc:
            print(f"prebuild: {path}: skipped ({exc})")
            continue
        ran += bool(methods)
        print(f"prebuild: {path}: {', '.join(methods) or 'no method ran'} "
              f"({time.process_time() - start:.1f} CPU s)")
    if ran and ahead_of_time:
        compile_ahead_of_time()
    return 0 if ran else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
