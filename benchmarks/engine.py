#!/usr/bin/env python3
"""The one-cylinder engine with the flexible piston rod (examples/engine target):
CPU s per simulated second of the time integration against the step size, and the error of
each step against a run at h = 25 us (crank speed, relative to its peak; the rod's largest modal
coordinate q3, relative to its peak), flexible and with the rigid rod of the same mass
properties.  The rod's first in-mechanism mode (linearised at the start, sidprep/solver/linear.py) is
given with the steps per period.

CPU = process time, median of ``--repeat`` runs after a warm-up run.

    python benchmarks/engine.py              # ~2 min
    python benchmarks/engine.py --repeat 1
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "engine"
#: the issue's target: CPU s per simulated second at a step resolving the first in-mechanism mode
ENGINE_TARGET = 0.5
STEPS = (1e-4, 2e-4, 3e-4, 5e-4)
REFERENCE_STEP = 2.5e-5


def prepared_folder(tmp: Path) -> Path:
    """The example's scenes with the rod reduced by its make line."""
    for name in ("scene.toml", "scene_rigid.toml", "crank.obj", "piston.obj"):
        shutil.copy(EXAMPLE / name, tmp / name)
    subprocess.run([sys.executable, "-m", "sidprep.cli.main", "reduce", str(ROOT / "data/meshes/piston_rod.msh"),
                    "-o", "piston_rod.sid.h5", "-q", "--no-sid-fem", "--no-obj"], cwd=tmp, check=True)
    return tmp


def main() -> None:
    from sidprep.solver.linear import mechanism_modes
    from sidprep.solver.scene import load_scene, simulate as run_scene

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = prepared_folder(Path(tmp))
        flexible, rigid = load_scene(folder / "scene.toml"), load_scene(folder / "scene_rigid.toml")
        first = mechanism_modes(flexible.system).frequencies_hz
        first = float(first[first > 150.0][0])
        print(f"\n### Engine (examples/engine, 1 s): first in-mechanism mode of the rod {first:.1f} Hz\n")
        print("| rod | h (s) | steps per period of the first mode | CPU s / simulated s | crank speed error | "
              "q3 error | target |")
        print("|---|---|---|---|---|---|---|")
        for label, scene in (("flexible", flexible), ("rigid", rigid)):
            def run(h):
                return run_scene(scene, h=h)

            ref = run(REFERENCE_STEP)
            for h in STEPS:
                run(h)
                results = [run(h) for _ in range(args.repeat)]
                cpu = float(np.median([r.stats.cpu_integration for r in results])) / scene.t_end
                r = results[-1]
                w, w_ref = r.joints["crank_joint"].rate, np.interp(r.t, ref.t, ref.joints["crank_joint"].rate)
                err_w = np.max(np.abs(w - w_ref)) / np.max(np.abs(w_ref))
                err_q = "-"
                if label == "flexible":
                    q, q_ref = r.bodies["rod"].q[:, 2], np.interp(r.t, ref.t, ref.bodies["rod"].q[:, 2])
                    err_q = f"{np.max(np.abs(q - q_ref)) / np.max(np.abs(q_ref)):.2e}"
                print(f"| {label} | {h:g} | {1 / (first * h):.1f} | {cpu:.3f} | {err_w:.2e} | {err_q} | "
                      f"<= {ENGINE_TARGET} |", flush=True)


if __name__ == "__main__":
    main()
