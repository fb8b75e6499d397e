#!/usr/bin/env python3
"""The meshes of the assembly example: the bundled bar's box (1.0 x 0.05 x 0.08 m) in two halves.

* ``left.msh``, ``right.msh``: the two halves of ONE conformal tet10 mesh (gmsh fragments the
  box at x = 0.5 m and meshes it once), so their ``joint`` faces carry the same nodes: a shared
  join; ``bar.msh`` is that same mesh in one piece (the monolithic reference);
* ``tied_left.msh`` (h = 40 mm) and ``tied_right.msh`` (h = 30 mm): the halves meshed apart, so
  their joint faces do not match: a tied join.

Node sets: ``fixed_end`` (x = 0), ``free_end`` (x = 1 m), ``joint`` (x = 0.5 m).  Deterministic.

    python examples/assembly/make_meshes.py            # writes the five meshes beside this script
"""

import argparse
from pathlib import Path

import gmsh

HERE = Path(__file__).resolve().parent
#: the bundled validation bar's box (m) and the joint's position
BOX = (1.0, 0.05, 0.08)
JOINT_X = 0.5
#: element sizes (m): the shared halves and the tied halves
SIZE = 0.04
TIED_SIZES = (0.04, 0.03)


def faces_at(x: float) -> list[int]:
    """The surface tags of the plane x (a bounding-box query wider than OCC's tolerance)."""
    _, b, h = BOX
    eps = 1e-3 * min(b, h)
    return [t for _, t in gmsh.model.getEntitiesInBoundingBox(x - eps, -eps, -eps, x + eps, b + eps, h + eps, dim=2)]


def write_groups(path: Path, volumes: list[int], faces: dict) -> None:
    """Write the current mesh with one physical volume ``body`` and node sets ``faces`` {name: x}
    (only the elements of ``volumes`` are written: gmsh saves physical groups only)."""
    gmsh.model.removePhysicalGroups()
    for name in ("body", "fixed_end", "free_end", "joint"):
        gmsh.model.removePhysicalName(name)
    gmsh.model.setPhysicalName(3, gmsh.model.addPhysicalGroup(3, volumes, tag=1), "body")
    for k, (name, x) in enumerate(faces.items()):
        gmsh.model.setPhysicalName(2, gmsh.model.addPhysicalGroup(2, faces_at(x), tag=k + 1), name)
    gmsh.write(str(path))


def session(name: str, size: float):
    gmsh.initialize(readConfigFiles=False, interruptible=False)
    for key, value in (("General.Terminal", 0), ("General.NumThreads", 1), ("Mesh.RandomSeed", 1),
                       ("Mesh.MeshSizeMin", size), ("Mesh.MeshSizeMax", size), ("Mesh.ElementOrder", 2),
                       ("Mesh.SecondOrderLinear", 1), ("Mesh.MshFileVersion", 4.1), ("Mesh.Binary", 1)):
        gmsh.option.setNumber(key, value)
    gmsh.model.add(name)


def shared_halves(folder: Path, size: float = SIZE) -> None:
    """bar.msh, left.msh, right.msh: one conformal mesh of the box cut at JOINT_X (module docstring)."""
    L, b, h = BOX
    session("bar", size)
    try:
        left = gmsh.model.occ.addBox(0, 0, 0, JOINT_X, b, h)
        right = gmsh.model.occ.addBox(JOINT_X, 0, 0, L - JOINT_X, b, h)
        gmsh.model.occ.fragment([(3, left)], [(3, right)])
        gmsh.model.occ.synchronize()
        gmsh.model.mesh.generate(3)
        vols = sorted(t for _, t in gmsh.model.getEntities(3))
        write_groups(folder / "bar.msh", vols, {"fixed_end": 0.0, "free_end": L})
        write_groups(folder / "left.msh", vols[:1], {"fixed_end": 0.0, "joint": JOINT_X})
        write_groups(folder / "right.msh", vols[1:], {"free_end": L, "joint": JOINT_X})
    finally:
        gmsh.finalize()


def half(path: Path, x0: float, x1: float, size: float, faces: dict) -> None:
    """The box between x0 and x1 meshed on its own at ``size``."""
    _, b, h = BOX
    session("half", size)
    try:
        vol = gmsh.model.occ.addBox(x0, 0, 0, x1 - x0, b, h)
        gmsh.model.occ.synchronize()
        gmsh.model.mesh.generate(3)
        write_groups(path, [vol], faces)
    finally:
        gmsh.finalize()


def tied_halves(folder: Path, sizes=TIED_SIZES) -> None:
    """tied_left.msh and tied_right.msh, meshed apart at ``sizes`` (non-matching joint faces)."""
    L = BOX[0]
    half(folder / "tied_left.msh", 0.0, JOINT_X, sizes[0], {"fixed_end": 0.0, "joint": JOINT_X})
    half(folder / "tied_right.msh", JOINT_X, L, sizes[1], {"free_end": L, "joint": JOINT_X})


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--out", type=Path, default=HERE, help="folder of the meshes (default: beside this script)")
    args = p.parse_args(argv)
    shared_halves(args.out)
    tied_halves(args.out)


if __name__ == "__main__":
    main()
