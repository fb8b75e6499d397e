#!/usr/bin/env python3
"""The solver core's targets (issue "Solver core, rebuilt once"), on demand:

1. The flexible pendulum of ``examples/flexible_pendulum`` (10-mode bar, h = 1 ms, 3D):
   CPU s per simulated second of the time integration.
2. A rigid one-cylinder engine: crank with flywheel (free, started at 150 rad/s), connecting
   rod, piston on a prismatic joint, a gas force over the crank angle (Table, period 4 pi, a
   four-stroke cycle); CPU s per simulated second at h = 1e-4 and 1e-3 s, and the error of the
   crank speed against a run at h = 1e-5 s.
3. The seed's slider crank (``examples/beam_slider_crank``: two analytical Beams, 1 Hz and
   3.9 Hz, crank at constant speed, gravity, Coulomb friction, 10 s): whole-run CPU s and the
   solution error (max over slider position and modal coordinates, relative to each signal's
   peak) against a run at h = 0.25 ms, for fixed steps and for error-controlled steps.

CPU = process time, median of ``--repeat`` runs after a warm-up run.  The cost of building the
compiled core (install) and of a first run is ``benchmarks/build_cost.py``.

    python benchmarks/solver_core.py             # all three
    python benchmarks/solver_core.py --repeat 1
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

#: the issue's targets
PENDULUM_TARGET, ENGINE_TARGET, SLIDER_CRANK_TARGET = 0.015, 0.05, 0.3
SLIDER_CRANK_ERROR = 1e-4
ALONG_X = np.array([0.0, np.pi / 2, 0.0])


def median_cpu(make_and_run, repeat: int):
    """(median cpu_integration, median total CPU, last result) over ``repeat`` runs."""
    make_and_run()
    runs = []
    for _ in range(repeat):
        t0 = time.process_time()
        r = make_and_run()
        runs.append((r.stats.cpu_integration, time.process_time() - t0, r))
    integ = float(np.median([x[0] for x in runs]))
    total = float(np.median([x[1] for x in runs]))
    return integ, total, runs[-1][2]


def pendulum(repeat: int) -> None:
    from sidprep.solver.scene import load_scene, simulate as run_scene

    scene = load_scene(ROOT / "examples/flexible_pendulum/scene.toml")
    integ, total, r = median_cpu(lambda: run_scene(scene), repeat)
    t_end = scene.t_end
    print("\n### Flexible pendulum (examples/flexible_pendulum, h = 1 ms)\n")
    print("| coordinates | steps | CPU s / simulated s (integration) | total CPU s | target |")
    print("|---|---|---|---|---|")
    print(f"| {r.stats.n_coordinates} | {r.stats.steps} | {integ / t_end:.4f} | {total:.3f} | "
          f"<= {PENDULUM_TARGET} |")


def engine_system():
    """Crank (flywheel 0.05 kg m^2, radius 0.05 m), rod 0.15 m, 0.5 kg piston, gas force."""
    from sidprep.solver import PointForce, Prismatic, Revolute, RigidBody, System, Table

    crank_r, rod_l = 0.05, 0.15
    s = System(gravity=(0, -9.81, 0))
    crank = s.add(RigidBody(5.0, (0, 0, 0), [0.05, 0.05, 0.05], name="crank", omega=(0, 0, 150.0)))
    x_pin = crank_r
    rod = s.add(RigidBody(0.8, (rod_l / 2, 0, 0), [1e-4, 2e-3, 2e-3], name="rod", position=(x_pin, 0, 0)))
    piston = s.add(RigidBody(0.5, name="piston", position=(x_pin + rod_l, 0, 0)))
    main = s.add(Revolute(s.ground.marker(), crank.marker(), name="main"))
    s.add(Revolute(crank.marker((crank_r, 0, 0)), rod.marker(), name="crankpin"))
    s.add(Revolute(rod.marker((rod_l, 0, 0)), piston.marker(), name="wristpin"))
    s.add(Prismatic(s.ground.marker(rotation=ALONG_X), piston.marker(rotation=ALONG_X), name="cylinder"))
    angle = np.linspace(0.0, 4 * np.pi, 73)
    pressure = np.where((angle > 0.1) & (angle < 1.2), 3000.0 * np.sin((angle - 0.1) / 1.1 * np.pi), 0.0)
    s.add(PointForce(piston.marker(), Table(angle, -pressure, period=4 * np.pi), direction=(1.0, 0, 0),
                     argument=main, name="gas"))
    return s


def engine(repeat: int) -> None:
    from sidprep.solver.run import simulate

    t_end = 1.0
    ref = simulate(engine_system(), t_end, h=1e-5, output_dt=0.01).joints["main"].rate
    print("\n### Rigid one-cylinder engine (gas force over crank angle, 1 s from 150 rad/s)\n")
    print("| h (s) | coordinates | CPU s / simulated s | crank speed error (rad/s, max) | target |")
    print("|---|---|---|---|---|")
    for h in (1e-4, 1e-3):
        integ, _, r = median_cpu(lambda: simulate(engine_system(), t_end, h=h, output_dt=0.01), repeat)
        err = np.max(np.abs(r.joints["main"].rate - ref))
        print(f"| {h:g} | {r.stats.n_coordinates} | {integ / t_end:.4f} | {err:.2e} | <= {ENGINE_TARGET} |")


def slider_crank(repeat: int) -> None:
    from sidprep.solver.scene import load_scene, simulate as run_scene

    scene = load_scene(ROOT / "examples/beam_slider_crank/scene.toml")

    def run(**kw):
        return run_scene(scene, **kw)

    def signals(r):
        return [r.joints["slider_joint"].coordinate, r.bodies["conrod"].q[:, 0], r.bodies["crank"].q[:, 0]]

    reference = signals(run(h=2.5e-4))
    print("\n### Seed slider crank (examples/beam_slider_crank, 10 s)\n")
    print("| settings | steps | error | integration CPU s | total CPU s | target |")
    print("|---|---|---|---|---|---|")
    for kw in (dict(h=1e-2), dict(h=5e-3), dict(h=2e-3), dict(h=1e-3), dict(h=5e-4), dict(h=1e-2, rtol=1e-5),
               dict(h=1e-2, rtol=1e-6)):
        integ, total, r = median_cpu(lambda: run(**kw), repeat)
        err = max(np.max(np.abs(a - b)) / np.max(np.abs(b)) for a, b in zip(signals(r), reference))
        label = ", ".join(f"{k} = {v:g}" for k, v in kw.items())
        print(f"| genalpha {label} | {r.stats.steps} | {err:.2e} | {integ:.3f} | {total:.3f} | "
              f"<= {SLIDER_CRANK_TARGET} s at <= {SLIDER_CRANK_ERROR:g} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    pendulum(args.repeat)
    engine(args.repeat)
    slider_crank(args.repeat)


if __name__ == "__main__":
    main()
