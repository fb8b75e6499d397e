#!/usr/bin/env python3
"""What the effects report's estimates cost (at most 10 % of the run), on demand.

For each example scene: the CPU (process time) of the whole run, of its post-processing and of
the effects estimates inside it (``solver.effects.estimate_changes``, timed where the
post-processing calls it), medians of ``--repeat`` runs after a warm-up run, and the load average.

    python benchmarks/effects_estimate.py               # three scenes, 7 runs each (~1 min)
    python benchmarks/effects_estimate.py --repeat 3
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from sidprep.solver import postprocess as post  # noqa: E402
from sidprep.solver import run as solver_run  # noqa: E402
from sidprep.solver.scene import load_scene, simulate  # noqa: E402

#: example scenes with left-out effects: centrifugal stiffening (Kom only), 1 s and 10 s; load
#: stiffening left out of the beam under a rising compression
SCENES = ("flexible_pendulum/scene.toml", "spinning_body/scene.toml", "beam_buckling/scene_no_stiffening.toml")


class Timed:
    """A function replaced by itself plus a CPU clock: ``spent`` holds the seconds of each call."""

    def __init__(self, module, name: str):
        self.module, self.name, self.real, self.spent = module, name, getattr(module, name), []
        setattr(module, name, self)

    def __call__(self, *args):
        start = time.process_time()
        out = self.real(*args)
        self.spent.append(time.process_time() - start)
        return out


def measure(scene_file: str, repeat: int) -> tuple[float, float, float]:
    """Median CPU s of the run, its post-processing and its effects estimates."""
    estimates, postprocess = Timed(post, "estimate_changes"), Timed(solver_run, "postprocess")
    rows = []
    for k in range(repeat + 1):  # the first run is a warm-up
        estimates.spent.clear()
        postprocess.spent.clear()
        scene = load_scene(ROOT / "examples" / scene_file)
        start = time.process_time()
        simulate(scene)
        if k:
            rows.append((time.process_time() - start, sum(postprocess.spent), sum(estimates.spent)))
    setattr(post, "estimate_changes", estimates.real)
    setattr(solver_run, "postprocess", postprocess.real)
    return tuple(np.median(np.array(rows), axis=0))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeat", type=int, default=7)
    args = p.parse_args()
    print(f"load average before: {os.getloadavg()[0]:.1f} ({os.cpu_count()} cores)")
    print("| scene | run CPU ms | post-processing ms | estimates ms | % of the run | % of the run without the rest of "
          "the post-processing |")
    print("|---|---|---|---|---|---|")
    for scene_file in SCENES:
        run_s, post_s, est_s = measure(scene_file, args.repeat)
        print(f"| {scene_file} | {1e3 * run_s:.1f} | {1e3 * post_s:.1f} | {1e3 * est_s:.2f} | {100 * est_s / run_s:.1f} "
              f"| {100 * est_s / (run_s - post_s + est_s):.1f} |")
    print(f"load average after: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
