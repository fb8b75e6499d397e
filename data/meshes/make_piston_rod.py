#!/usr/bin/env python3
"""Parametric connecting rod ("piston rod", cf. Heckmann et al. 2006 section 6.4) as a tet10 gmsh mesh.

A big-end eye and a small-end eye (annular cylinders, axis z, centres (0,0,0) and (L,0,0))
joined by an I-section shank along x (web in the plane of motion z = 0, flanges at the
in-plane edges y = +-w/2).  Built with the gmsh OpenCASCADE kernel, meshed with straight-sided
tet10 (Mesh.SecondOrderLinear, so every mid-edge node sits at its edge midpoint).

Physical groups: ``big_end`` / ``small_end`` = the eyes' inner cylindrical surfaces (node sets),
``rod`` = the volume.  Units: metres.  Deterministic for given arguments (one thread).

    python make_piston_rod.py                   # writes piston_rod.msh beside this script
    python make_piston_rod.py --check           # + lowest frequencies with both eyes held
"""

import argparse
from pathlib import Path

import gmsh
from _gmsh_tet10 import gmsh_model, read_back, write_tet10

HERE = Path(__file__).resolve().parent

#: steel (SI), the material the frequencies in the README were computed with
STEEL = dict(E=210e9, nu=0.3, rho=7850.0)


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    a = p.add_argument
    a("--length", type=float, default=0.42, help="eye centre distance L [m]")
    a("--big-bore", type=float, default=0.030, help="big-end inner radius [m]")
    a("--big-outer", type=float, default=0.048, help="big-end outer radius [m]")
    a("--small-bore", type=float, default=0.014, help="small-end inner radius [m]")
    a("--small-outer", type=float, default=0.026, help="small-end outer radius [m]")
    a("--eye-thickness", type=float, default=0.026, help="eye width along z [m]")
    a("--shank-width", type=float, default=0.021, help="shank depth in the plane, along y [m]")
    a("--flange-thickness", type=float, default=0.0035, help="flange thickness along y [m]")
    a("--flange-width", type=float, default=0.022, help="flange width along z [m]")
    a("--web-thickness", type=float, default=0.003, help="web thickness along z [m]")
    a("--size", type=float, default=0.012, help="target element size [m]")
    a("--out", type=Path, default=HERE / "piston_rod.msh")
    a("--check", action="store_true", help="print the lowest 3 frequencies, eyes held")
    return p.parse_args(argv)


def _inner_surfaces(cx, r, half_t):
    """Surface tags of the bore of the eye centred at (cx, 0): inside its bounding box."""
    eps = 1e-3 * r  # larger than OCC's bounding-box tolerance, far below the eye wall
    box = (cx - r - eps, -r - eps, -half_t - eps, cx + r + eps, r + eps, half_t + eps)
    tags = [tag for _, tag in gmsh.model.getEntitiesInBoundingBox(*box, dim=2)]
    assert tags, f"no bore surface found at x = {cx}"
    return tags


def build(args):
    occ = gmsh.model.occ
    te, L = args.eye_thickness, args.length
    big = occ.addCylinder(0, 0, -te / 2, 0, 0, te, args.big_outer)
    small = occ.addCylinder(L, 0, -te / 2, 0, 0, te, args.small_outer)
    w, tf, bf, tw = args.shank_width, args.flange_thickness, args.flange_width, args.web_thickness
    web = occ.addBox(0, -w / 2, -tw / 2, L, w, tw)
    f1 = occ.addBox(0, -w / 2, -bf / 2, L, tf, bf)
    f2 = occ.addBox(0, w / 2 - tf, -bf / 2, L, tf, bf)
    body, _ = occ.fuse([(3, big)], [(3, small), (3, web), (3, f1), (3, f2)])
    bores = [
        (3, occ.addCylinder(0, 0, -te, 0, 0, 2 * te, args.big_bore)),
        (3, occ.addCylinder(L, 0, -te, 0, 0, 2 * te, args.small_bore)),
    ]
    rod, _ = occ.cut(body, bores)
    occ.synchronize()
    assert len(rod) == 1, rod
    gmsh.model.addPhysicalGroup(3, [rod[0][1]], name="rod")
    gmsh.model.addPhysicalGroup(2, _inner_surfaces(0, args.big_bore, te / 2), name="big_end")
    gmsh.model.addPhysicalGroup(2, _inner_surfaces(L, args.small_bore, te / 2), name="small_end")


def mesh_and_write(args):
    with gmsh_model("piston_rod"):
        build(args)
        write_tet10(args.out, args.size)


def main(argv=None):
    args = parse_args(argv)
    mesh_and_write(args)
    mesh = read_back(args.out)
    if args.check:
        from _modal_check import clamped_frequencies_hz

        f = clamped_frequencies_hz(mesh, ["big_end", "small_end"], **STEEL)
        print("lowest frequencies, both bores held [Hz]:", " ".join(f"{x:.1f}" for x in f))


if __name__ == "__main__":
    main()
