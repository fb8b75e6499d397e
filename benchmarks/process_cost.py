#!/usr/bin/env python3
"""What a warm `sidprep simulate` process spends, split up: imports, scene
building, the start (consistent initial state), the first-call costs, the integration and the
post-processing, each in CPU seconds, medians of ``--repeat`` fresh processes; with ``--before``
the same for another checkout (e.g. /work/main), the two alternating, so that the pairs share the
machine's load.

Every child process runs the scene twice: the second run has every kernel loaded, so the first
run's excess over it is the first-call costs of that stage (for a checkout on numba kernels: their
loading from numba's cache).  Per
step and per sample (second run): the compiled samples' outputs (``sample_outputs`` called once
more from Python on the second run's samples, timed) per output sample, and the steps' CPU per
step (the integration less those outputs where the compiled loop computes them: a checkout from
the fourth pass on, where "integration" includes the outputs and "post" does not); "whole run /
steps" is start + integration + post over the steps alone).

    python benchmarks/process_cost.py examples/beam_slider_crank/scene.toml --repeat 5
    python benchmarks/process_cost.py examples/engine/scene_rigid.toml --before /work/main --h 1e-4
    python benchmarks/process_cost.py examples/beam_slider_crank/scene.toml --cli --before /work/main

With ``--cli`` each child is the command itself (``python -m sidprep.cli.main simulate SCENE -q``,
results into a temporary folder) and the figure is its whole life in CPU s (user + system of the
child, every thread: start-up, imports, scene, run, results file, the process's exit).

With ``--installed PYTHON ...`` the children are those interpreters with the sidprep they have
installed (no PYTHONPATH; e.g. two venvs, a wheel of this branch and one of main), so the
install's compiled kernels are what is measured:

    python benchmarks/process_cost.py examples/flexible_pendulum/scene.toml --cli --installed /tmp/a/bin/python /tmp/b/bin/python

One process per checkout runs first, not counted (a numba checkout fills its kernel cache there); the
load average is printed.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

#: the child: one process, timed stage by stage (CPU s), printed as JSON
CHILD = r"""
import json, sys, time
t0 = time.process_time()
try:  # what `sidprep simulate` does to its process (absent in older checkouts)
    from sidprep.cli.options import process_setup
    process_setup()
except ImportError:
    pass
from sidprep.solver.scene import load_scene, simulate
import sidprep.solver.run as run_module
t_import = time.process_time() - t0
try:  # the compiled core (Cython): the loops compute their samples' outputs
    from sidprep.solver.core.outputs import sample_outputs
    from sidprep.solver.core.steps import SampleArrays as SampleBuffers
    inside = True
except ImportError:  # numba kernels
    try:  # the samples' outputs computed inside the compiled loops
        from sidprep.solver.integrators.outputs import sample_outputs
        inside = True
    except ImportError:  # before: post-processing called them from Python
        from sidprep.solver.postprocess import sample_outputs
        inside = False
    from sidprep.solver.integrators.base import SampleBuffers
import numpy as np
captured = []
postprocess = run_module.postprocess
def capturing_postprocess(run, samples, *rest):
    captured.append((run, samples))
    return postprocess(run, samples, *rest)
run_module.postprocess = capturing_postprocess
kwargs = {key: float(value) for key, value in zip(("output_dt", "h"), sys.argv[2:4]) if value != "-"}
runs = []
for _ in range(2):
    t1 = time.process_time()
    scene = load_scene(sys.argv[1])
    t2 = time.process_time()
    result = simulate(scene, **kwargs)
    t3 = time.process_time()
    s = result.stats
    runs.append({"scene": t2 - t1, "start": s.cpu_setup, "integration": s.cpu_integration,
                 "post": t3 - t2 - s.cpu_setup - s.cpu_integration, "samples": int(result.t.size),
                 "steps": int(s.steps)})
first, second = runs
# sample_outputs alone on the second run's samples, called from Python (twice: the second call timed)
run, samples = captured[-1]
try:
    from sidprep.solver.postprocess import post_setup
    setup = post_setup(run)
    args = (setup.L, setup.L0)
    c = setup.c
except ImportError:
    from sidprep.solver.postprocess import base_layout, post_constants
    from sidprep.solver.equations.assemble import every_marker
    L0 = base_layout(run)
    c = post_constants(run, L0 is not None)
    args = (every_marker(run.L), every_marker(run.L if L0 is None else L0))
buffers = SampleBuffers(*(np.ascontiguousarray(getattr(samples, f)) for f in SampleBuffers._fields))
sample_outputs(*args, buffers, c)
t4 = time.process_time()
sample_outputs(*args, buffers, c)
outputs = time.process_time() - t4
loading = sum(first[k] - second[k] for k in ("start", "integration", "post"))
steps = second["integration"] - (outputs if inside else 0.0)
whole = second["start"] + second["integration"] + second["post"]
print(json.dumps({"imports": t_import, "scene": first["scene"], "start": second["start"],
                  "kernel loading": loading, "integration": second["integration"], "post": second["post"],
                  "start + integration + post": whole, "samples": second["samples"],
                  "steps per step (us)": 1e6 * steps / max(second["steps"], 1),
                  "sample_outputs per sample (us)": 1e6 * outputs / max(second["samples"], 1),
                  "whole run / steps": whole / steps,
                  "before first step": t_import + first["scene"] + first["start"]
                  + first["integration"] - second["integration"],
                  "process (one run)": t_import + first["scene"] + first["start"] + first["integration"]
                  + first["post"]}))
"""
STAGES = ("imports", "scene", "start", "kernel loading", "integration", "post", "start + integration + post",
          "before first step", "process (one run)", "steps per step (us)", "sample_outputs per sample (us)",
          "whole run / steps")


def child_env(root: Path | None) -> dict:
    """The environment of a child importing sidprep from ``root`` (None: its installed one)."""
    env = dict(os.environ)
    env.pop("PYTHONPATH", None)
    return env | ({"PYTHONPATH": str(root)} if root else {})


def child_run(python: str, root: Path | None, scene: Path, output_dt: str, h: str) -> dict:
    """The stage costs of one fresh process of ``python`` importing sidprep from ``root``."""
    out = subprocess.run([python, "-c", CHILD, str(scene), output_dt, h], env=child_env(root), cwd=scene.parent,
                         check=True, capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def command_run(python: str, root: Path | None, scene: Path, output_dt: str, h: str) -> dict:
    """CPU s of one ``sidprep simulate`` process (the command of ``root``, None: ``python``'s
    installed one), user + system."""
    extra = (["--rate", repr(1.0 / float(output_dt))] if output_dt != "-" else []) + (
        ["--step", h] if h != "-" else [])
    with tempfile.TemporaryDirectory() as tmp:
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        subprocess.run([python, "-m", "sidprep.cli.main", "simulate", str(scene), "-q", "-o",
                        str(Path(tmp) / "r.results.h5"), *extra], env=child_env(root), cwd=scene.parent, check=True,
                       capture_output=True)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return {"process": (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("scene", type=Path)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--before", type=Path, help="another checkout to run side by side (e.g. /work/main)")
    parser.add_argument("--output-dt", default="-", help="output interval, s (default: the scene's)")
    parser.add_argument("--h", default="-", help="step, s (default: the scene's)")
    parser.add_argument("--cli", action="store_true", help="whole `sidprep simulate` processes instead of stages")
    parser.add_argument("--installed", nargs="+", metavar="PYTHON",
                        help="compare these interpreters' installed sidprep instead of checkouts")
    args = parser.parse_args()
    scene = args.scene.resolve()
    if args.installed:
        roots = {python: (python, None) for python in args.installed}
    else:
        roots = {"this": (sys.executable, ROOT)} | (
            {"before": (sys.executable, args.before.resolve())} if args.before else {})
    rows: dict[str, list[dict]] = {name: [] for name in roots}
    run, stages = (command_run, ("process",)) if args.cli else (child_run, STAGES)
    for python, root in roots.values():  # warm-up (a numba checkout's kernel cache filled)
        run(python, root, scene, args.output_dt, args.h)
    loads = [os.getloadavg()[0]]
    for _ in range(args.repeat):
        for name, (python, root) in roots.items():
            rows[name].append(run(python, root, scene, args.output_dt, args.h))
        loads.append(os.getloadavg()[0])
    print(f"{scene.relative_to(ROOT) if scene.is_relative_to(ROOT) else scene}, output_dt {args.output_dt}, "
          f"h {args.h}, medians of {args.repeat} processes, load average {min(loads):.1f}-{max(loads):.1f}, CPU s")
    names = list(roots)
    print("| stage | " + " | ".join(names) + (" | ratio |" if len(names) == 2 else " |"))
    print("|---" * (len(names) + 1 + (len(names) == 2)) + "|")
    for stage in stages:
        med = [float(np.median([r[stage] for r in rows[n]])) for n in names]
        ratio = f" | {med[0] / med[1]:.2f}" if len(med) == 2 and med[1] > 0 else ""
        print(f"| {stage} | " + " | ".join(f"{m:.3f}" for m in med) + ratio + " |")
    if not args.cli:
        print(f"samples per run: {rows[names[0]][0]['samples']}")


if __name__ == "__main__":
    main()
