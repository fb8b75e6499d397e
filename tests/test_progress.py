"""The simulation progress display (sidprep.progress.SimulationProgress): plain lines off a
terminal, a rich bar on one, called by the run between chunks of steps (SolverSettings.progress)."""

import io
import os
import subprocess
import sys
from pathlib import Path

import pytest

from sidprep.progress import PLAIN_FRACTION, SimulationProgress
from sidprep.solver.scene import load_scene, simulate

ROOT = Path(__file__).resolve().parents[1]


class Terminal(io.StringIO):
    def isatty(self):
        return True


def test_plain_lines_one_per_tenth_with_rate_and_time_left():
    stream = io.StringIO()
    with SimulationProgress(10.0, stream=stream) as progress:
        for k in range(1, 101):
            progress(0.1 * k, 10.0, 100 * k)
    lines = stream.getvalue().splitlines()
    assert len(lines) == round(1 / PLAIN_FRACTION)
    assert lines[0].startswith("  simulate t = 1 / 10 s (10 %)") and "steps/s" in lines[0] and "s left" in lines[0]
    assert "(100 %)" in lines[-1]


def test_a_terminal_gets_the_bar_and_quiet_gets_nothing():
    stream = Terminal()
    with SimulationProgress(2.0, stream=stream) as progress:
        progress(1.0, 2.0, 500)
        assert progress.bar is not None and progress.bar.tasks[0].completed == pytest.approx(1.0)
    quiet = io.StringIO()
    with SimulationProgress(2.0, enabled=False, stream=quiet) as progress:
        progress(1.0, 2.0, 500)
    assert quiet.getvalue() == ""


def test_the_run_reports_between_chunks_and_ends_at_t_end():
    """Output every step over 0.5 s of the pendulum at h = 0.1 ms: 5000 samples, two chunks."""
    calls = []
    scene = load_scene(ROOT / "examples/flexible_pendulum/scene.toml", t_end=0.5)
    plain = simulate(scene, h=1e-4, output_dt=1e-4)
    reported = simulate(scene, h=1e-4, output_dt=1e-4, progress=lambda t, t_end, steps: calls.append((t, steps)))
    assert len(calls) >= 2 and calls[-1][0] == pytest.approx(0.5) and calls[-1][1] == 5000
    assert [c[0] for c in calls] == sorted(c[0] for c in calls)
    assert (plain.joints["hinge"].coordinate == reported.joints["hinge"].coordinate).all()   # numerics untouched


HEAP_HOLES_SCRIPT = """
import numpy as np
from sidprep.progress import return_freed_memory
def resident():
    with open("/proc/self/status") as fh:
        return 1024 * int(next(line for line in fh if line.startswith("VmRSS")).split()[1])
np.ones(4_000_000).sum()                 # a 32 MB block freed: glibc raises its mmap threshold to it
blocks = [np.ones(100_000) for _ in range(2000)]   # 0.8 MB each, now from the heap
del blocks[::2]                          # every other one freed: holes, not the heap's top
before = resident()
return_freed_memory()
print(before - resident())
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's malloc_trim")
def test_freed_heap_memory_goes_back_to_the_system():
    # 1000 freed 0.8 MB arrays amid live ones: the resident set (VmRSS, the reference) drops by most of
    # their 800 MB (without MALLOC_TRIM_THRESHOLD_, as in a local pool's worker)
    env = {k: v for k, v in os.environ.items() if not k.startswith("MALLOC_")} | {"PYTHONPATH": str(ROOT)}
    run = subprocess.run([sys.executable, "-c", HEAP_HOLES_SCRIPT], capture_output=True, text=True, env=env,
                         timeout=120, check=True)
    assert float(run.stdout) > 0.5 * 1000 * 0.8e6
