#!/usr/bin/env python3
"""Slender cantilever bar [0,L] x [0,b] x [0,h] as a straight-sided tet10 gmsh mesh.

Physical groups: ``fixed_end`` (face x = 0) and ``free_end`` (face x = L) as node sets,
``bar`` = the volume.  Units: metres.  Deterministic for given arguments (one thread).
The default box is the validation bar (1.0 x 0.05 x 0.08 m, ../shared/validation).

    python make_bar.py                 # writes bar.msh beside this script
    python make_bar.py --check         # + lowest cantilever frequencies vs Euler-Bernoulli
"""

import argparse
from pathlib import Path

import gmsh
import numpy as np
from _gmsh_tet10 import gmsh_model, read_back, write_tet10

HERE = Path(__file__).resolve().parent
STEEL = dict(E=210e9, nu=0.3, rho=7850.0)
#: first root of 1 + cos(x) cosh(x) = 0 (clamped-free Euler-Bernoulli beam)
CANTILEVER_ROOT_1 = 1.8751040687


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--box", type=float, nargs=3, default=(1.0, 0.05, 0.08), metavar=("L", "B", "H"))
    p.add_argument("--size", type=float, default=0.04, help="target element size [m]")
    p.add_argument("--out", type=Path, default=HERE / "bar.msh")
    p.add_argument("--check", action="store_true", help="print the lowest cantilever frequencies")
    return p.parse_args(argv)


def mesh_and_write(args):
    L, b, h = args.box
    with gmsh_model("bar"):
        vol = gmsh.model.occ.addBox(0, 0, 0, L, b, h)
        gmsh.model.occ.synchronize()
        eps = 1e-3 * min(b, h)  # larger than OCC's bounding-box tolerance

        def face_at(x):
            box = (x - eps, -eps, -eps, x + eps, b + eps, h + eps)
            tags = [tag for _, tag in gmsh.model.getEntitiesInBoundingBox(*box, dim=2)]
            assert len(tags) == 1, (x, tags)
            return tags

        gmsh.model.addPhysicalGroup(3, [vol], name="bar")
        gmsh.model.addPhysicalGroup(2, face_at(0.0), name="fixed_end")
        gmsh.model.addPhysicalGroup(2, face_at(L), name="free_end")
        write_tet10(args.out, args.size)


def euler_bernoulli_first_hz(L, b, h, E, rho):
    """First cantilever bending frequencies [Hz] about the two cross-section axes."""
    return [CANTILEVER_ROOT_1**2 / (2 * np.pi * L**2) * np.sqrt(E * t**2 / (12 * rho)) for t in (b, h)]


def main(argv=None):
    args = parse_args(argv)
    mesh_and_write(args)
    mesh = read_back(args.out)
    if args.check:
        from _modal_check import clamped_frequencies_hz

        f = clamped_frequencies_hz(mesh, ["fixed_end"], **STEEL)
        eb = euler_bernoulli_first_hz(*args.box, STEEL["E"], STEEL["rho"])
        print("lowest cantilever frequencies [Hz]:", " ".join(f"{x:.2f}" for x in f))
        print("Euler-Bernoulli first bending (b, h) [Hz]:", " ".join(f"{x:.2f}" for x in eb))


if __name__ == "__main__":
    main()
