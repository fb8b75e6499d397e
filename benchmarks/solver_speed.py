#!/usr/bin/env python3
"""Accuracy vs CPU of the FFR solver: the 10-mode flexible pendulum at step sizes 1e-4 ... 1e-2 s.

Body: the bundled bar (``data/meshes/bar.msh``) reduced by ``sidprep reduce`` to 10 free-free
eigenmodes with interface masters at both end faces (SID nodes: hinge and tip), steel, the
default modal damping 0.02.  Scene: revolute joint about y at the hinge node, gravity -z,
released horizontally with the modes in quasi-static equilibrium (static_start), 1 s,
generalised-alpha rho_inf = 0.9, auto effects, output every 10 ms.  Each step size runs with
the 3D coordinates (planar = False) and with the planar coordinate set (detected).

Errors against a reference run of the same solver (h = H_REF, Newton tolerance 1e-12):

* angle: max over the output times of |hinge angle - reference|, degrees;
* tip: max over the output times of |tip deflection - reference| / max |reference deflection|,
  with the tip deflection = elastic displacement of the tip node, Phi_tip q (body frame).

CPU = ``stats.cpu_integration`` (process time of the time integration only) per simulated
second, median of ``--repeat`` runs, after a warm-up run.  The last column
flags runs meeting both targets (ANGLE_TARGET_DEG, TIP_TARGET).

    python benchmarks/solver_speed.py            # full table (~1 min)
    python benchmarks/solver_speed.py --quick    # 3 step sizes, one run each
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

T_END = 1.0
OUTPUT_DT = 0.01
H_REF = 2.5e-5
STEPS = (1e-4, 2.5e-4, 5e-4, 1e-3, 2e-3, 5e-3, 1e-2)
#: accuracy targets of the study: hinge angle (deg) and relative tip deflection
ANGLE_TARGET_DEG, TIP_TARGET = 1e-3, 1e-3
#: Exudyn 1.13.6, same reduced bar, h = 1e-3 (helper F, benchmarks/simulate.py), CPU s / sim s
EXUDYN_CPU_H1E3 = 0.09
_Z_TO_Y = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]).T   # marker z along y


def reduced_bar(folder: Path) -> Path:
    """``sidprep reduce`` of the bundled bar with hinge and tip interface nodes -> SID path."""
    out = folder / "bar.sid.h5"
    exe = Path(sys.executable).with_name("sidprep")
    subprocess.run([str(exe), "reduce", str(ROOT / "data/meshes/bar.msh"), "-o", str(out),
                    "--interface", "fixed_end", "--interface", "free_end", "--modes", "10", "--no-frm",
                    "--no-sid-fem", "--no-obj", "--no-check-frequencies", "-q"], check=True)
    return out


def pendulum(sid, planar=None):
    """The hinged bar as a System, its tip node marker (hinge = SID node 0, tip = node 1)."""
    from sidprep.solver import FlexibleBody, Revolute, System

    system = System(gravity=(0.0, 0.0, -9.81))
    if planar is not None:
        system.planar = planar
    bar = system.add(FlexibleBody(sid, name="bar"))
    hinge = bar.node_marker(0, rotation=_Z_TO_Y, name="hinge")
    bar.node_marker(1, name="tip")
    system.add(Revolute(system.ground.marker(rotation=_Z_TO_Y, name="pivot"), hinge, name="hinge"))
    return system


def run(sid, h, *, rtol=None, newton_tol=1e-8, planar=None):
    """(angle (nt,) rad, tip deflection (nt, 3) m, CPU s per simulated s, stats)."""
    from sidprep.solver.run import simulate

    system = pendulum(sid, planar)
    res = simulate(system, T_END, h=h, rtol=rtol, newton_tol=newton_tol, output_dt=OUTPUT_DT, static_start=True)
    phi_tip = sid.nodes[1].phi.M0
    deflection = res.bodies["bar"].q @ phi_tip.T
    return res.joints["hinge"].coordinate, deflection, res.stats.cpu_integration / T_END, res.stats


def table(sid, runs, ref, repeat):
    """Print one markdown row per run spec (label, h, kwargs); returns the rows."""
    rows = []
    scale = np.max(np.linalg.norm(ref[1], axis=1))
    for label, h, kw in runs:
        out = [run(sid, h, **kw) for _ in range(repeat)]
        angle, defl, _, stats = out[0]
        if angle.shape != ref[0].shape:
            print(f"| {label} | {h:g} | output grid differs from the reference |")
            continue
        cpu = float(np.median([o[2] for o in out]))
        e_angle = float(np.degrees(np.max(np.abs(angle - ref[0]))))
        e_tip = float(np.max(np.linalg.norm(defl - ref[1], axis=1)) / scale)
        ok = e_angle <= ANGLE_TARGET_DEG and e_tip <= TIP_TARGET
        iters = stats.newton_iterations / max(stats.steps, 1)
        print(f"| {label} | {h:g} | {stats.steps} | {iters:.2f} | {e_angle:.2e} | {e_tip:.2e} | {cpu:.4f} | "
              f"{cpu / EXUDYN_CPU_H1E3:.2f} | {'yes' if ok else 'no'} |", flush=True)
        rows.append((label, h, e_angle, e_tip, cpu, ok))
    return rows


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--quick", action="store_true", help="three step sizes, one run each")
    p.add_argument("--repeat", type=int, default=3, help="runs per configuration (median CPU)")
    p.add_argument("--adaptive", type=float, nargs="*", default=[1e-4, 1e-5, 1e-6],
                   help="rtol values of step-size-controlled runs")
    args = p.parse_args(argv)
    from sidprep.sid.io import read_sid

    with tempfile.TemporaryDirectory() as tmp:
        sid = read_sid(reduced_bar(Path(tmp)))
    run(sid, 1e-3)  # warm-up
    ref = run(sid, H_REF, newton_tol=1e-12, planar=False)[:2]
    steps = (1e-3, 2e-3, 5e-3) if args.quick else STEPS
    repeat = 1 if args.quick else args.repeat
    specs = [(label, h, {"planar": planar}) for h in steps for label, planar in (("3D", False), ("planar", True))]
    specs += [(f"planar rtol {r:g}", 1e-3, {"rtol": r, "planar": True}) for r in ([] if args.quick else args.adaptive)]
    print(f"10-mode flexible pendulum, 1 s; reference h = {H_REF:g} s; targets {ANGLE_TARGET_DEG:g} deg, "
          f"{TIP_TARGET:g} relative tip deflection (max |ref| = {np.max(np.linalg.norm(ref[1], axis=1)):.3e} m)")
    print("| run | h [s] | steps | Newton it./step | angle error [deg] | tip error [rel] | CPU s / sim s | "
          f"/ Exudyn {EXUDYN_CPU_H1E3} | meets targets |")
    print("|---|---|---|---|---|---|---|---|---|")
    rows = table(sid, specs, ref, repeat)
    ok = [r for r in rows if r[5]]
    if ok:
        best = min(ok, key=lambda r: r[4])
        print(f"\ncheapest run meeting the targets: {best[0]} h = {best[1]:g} s, {best[4]:.4f} s CPU per simulated s "
              f"= {best[4] / EXUDYN_CPU_H1E3:.2f} x Exudyn's {EXUDYN_CPU_H1E3} at h = 1e-3")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
