#!/usr/bin/env python3
"""CPU per simulated second of Kisu Lee's two-link manipulator in absolute nodal coordinates.

examples/two_link_manipulator/scene.toml (2 links x 4 elements, 16 DOF), classic RK4 at the
paper's step 2.5e-4 s, 2 s simulated; also 8 and 16 elements per link at the steps their axial
modes allow (RK4 stability).  CPU = process time of the compiled integration loop only
(``stats.cpu_time``; set-up and the post-processing of the samples excluded), median
of ``--repeat`` runs after a warm-up run.  Target: <= 0.1 CPU-s per simulated second;
the paper took ~15 s for its run on a 100 MHz Pentium.

    python benchmarks/absolute_nodal.py [--repeat 7]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

#: target, CPU seconds per simulated second
TARGET = 0.1
T_END = 2.0
#: (elements per link, RK4 step s)
CASES = ((4, 2.5e-4), (8, 1.25e-4), (16, 5e-5))


def main(argv=None):
    from dataclasses import replace

    from sidprep.solver.absolute_nodal.assembly import assemble
    from sidprep.solver.absolute_nodal.run import integrate
    from sidprep.solver.absolute_nodal.scene import load_absolute_nodal_scene
    from sidprep.solver.integrators.settings import SolverSettings
    from sidprep.tables import read_toml

    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--repeat", type=int, default=7)
    args = p.parse_args(argv)
    path = ROOT / "examples" / "two_link_manipulator" / "scene.toml"
    model = load_absolute_nodal_scene(read_toml(path), path).model
    print(f"two-link manipulator, RK4, {T_END:g} s simulated, median of {args.repeat} (machine shared, loaded)")
    print("| elements/link | DOF | step [s] | steps | CPU [s] | CPU per simulated s | target <= 0.1 |")
    print("|---|---|---|---|---|---|---|")
    for ne, h in CASES:
        m = replace(model, beams=tuple(replace(b, elements=ne) for b in model.beams))
        asm = assemble(m)
        settings = SolverSettings(method="rk4", h=h, output_dt=1 / 100.0)
        integrate(asm, 10 * h, settings)                               # warm-up
        cpu = []
        for _ in range(args.repeat):
            _, _, c = integrate(asm, T_END, settings)
            cpu.append(c)
        med = float(np.median(cpu))
        print(f"| {ne} | {2 * len(asm.free)} | {h:g} | {round(T_END / h)} | {med:.4f} | {med / T_END:.4f} | "
              f"{'yes' if med / T_END <= TARGET else 'no'} |", flush=True)


if __name__ == "__main__":
    main()
