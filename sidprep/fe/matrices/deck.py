"""MODEL of an import: nodes, node sets and outer surface of an FE deck of solid, shell and beam elements.

Tetrahedral models are read by sidprep.fe.mesh.read_mesh (all of sidprep's features).  Decks with
hexahedra, wedges or pyramids (linear or quadratic), shells (triangles, quadrilaterals) or beams
(``.inp``, Nastran ``.bdf``/``.nas``/``.dat`` read by sidprep.fe.matrices.nastran_deck, the other
formats meshio reads) become an FEMesh whose ``surface`` holds the outer faces of the FE code's
solid elements and both sides of its shell elements (corner nodes, quadrilaterals split in two),
for the OBJ surface, the surface mode shapes and RBE3 weights, and whose ``cells`` are a split of
each solid element's corner nodes into tetrahedra (6 per hexahedron, 3 per wedge, 2 per pyramid;
none for a model of shells and beams): used only to locate path points, which are then
interpolated linearly between corner nodes.  Beams are drawn by sidprep.fe.matrices.tubes.  Nodes
on no element are dropped (the FE code gives them no DOF).  Stiffness and mass come from the FE
code (sidprep.fe.matrices), never from these cells.
"""

from __future__ import annotations

import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

from sidprep.errors import InputError
from sidprep.fe.matrices.keywords import deck_text_path, single_node_block
from sidprep.fe.matrices.nastran_deck import is_nastran, nastran_mesh
from sidprep.fe.mesh import FEMesh, file_sha256, read_mesh
from sidprep.fe.readers.abaqus import abaqus_ids, abaqus_lines
from sidprep.fe.readers.meshio import meshio_read
from sidprep.fe.topology import TET_FACES


#: corner-node tetrahedra of one element, per meshio cell type (VTK node order)
TETS = {"tetra": [(0, 1, 2, 3)],
        "hexahedron": [(0, 1, 2, 6), (0, 2, 3, 6), (0, 3, 7, 6), (0, 7, 4, 6), (0, 4, 5, 6), (0, 5, 1, 6)],
        "wedge": [(0, 1, 2, 3), (1, 2, 3, 4), (2, 3, 4, 5)],
        "pyramid": [(0, 1, 2, 4), (0, 2, 3, 4)]}
#: corner-node faces of one element, outward for a positive element (VTK node order)
FACES = {"tetra": [tuple(f) for f in TET_FACES],
         "hexahedron": [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)],
         "wedge": [(0, 2, 1), (3, 4, 5), (0, 1, 4, 3), (1, 2, 5, 4), (2, 0, 3, 5)],
         "pyramid": [(0, 3, 2, 1), (0, 1, 4), (1, 2, 4), (2, 3, 4), (3, 0, 4)]}
#: corner nodes of each family
CORNERS = {"tetra": 4, "hexahedron": 8, "wedge": 6, "pyramid": 5, "triangle": 3, "quad": 4, "line": 2, "vertex": 1}
#: meshio cell type -> its linear family
FAMILY = {"tetra": "tetra", "tetra10": "tetra", "hexahedron": "hexahedron", "hexahedron20": "hexahedron",
          "hexahedron27": "hexahedron", "wedge": "wedge", "wedge15": "wedge", "pyramid": "pyramid",
          "pyramid13": "pyramid"}
#: meshio cell types of shells, beams and point masses -> their linear family
STRUCTURAL = {"triangle": "triangle", "triangle6": "triangle", "quad": "quad", "quad8": "quad", "quad9": "quad",
              "line": "line", "line3": "line", "vertex": "vertex"}


def read_model(path, *, size=None, order: int = 2) -> FEMesh:
    """MODEL of ``sidprep reduce MODEL --matrices FILE`` (module docstring); lengths as in the file."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: file not found; check the path")
    if path.suffix.lower() in (".msh", ".geo", ".step", ".stp", ".brep", ".iges", ".igs"):
        return read_mesh(path, size=size, order=order)
    if path.suffix.lower() == ".inp" and single_node_block(path) is not None:
        return several_node_blocks(path)
    if path.suffix.lower() == ".inp" and abaqus_types(path) <= {"C3D4", "C3D10"} and abaqus_types(path):
        return read_mesh(path)                             # a tetrahedral deck: read once, as a sidprep mesh
    m, ids = nastran_mesh(path) if is_nastran(path) else (
        meshio_read(path, abaqus_lines(path) if path.suffix.lower() == ".inp" else None), None)
    structural = has_structural_elements(path)
    types = {b.type for b in m.cells if b.type in FAMILY or structural and b.type in STRUCTURAL}
    if types and types <= {"tetra", "tetra10"}:
        return read_mesh(path)
    return element_model(m, path, ids, structural)


def has_structural_elements(path) -> bool:
    """Whether the deck's triangles, quadrilaterals and lines are shells and beams: every one of a
    Nastran deck (CTRIA3, CQUAD4, CBAR, ...), those of an Abaqus / CalculiX deck with shell or beam
    types (S4, B31, ...); in other formats and other decks they are boundary faces or edges (plane
    elements, gmsh's physical groups) and only name node sets."""
    path = Path(path)
    return is_nastran(path) or path.suffix.lower() == ".inp" and bool(abaqus_types(path) & set(STRUCTURAL_NODES))


def several_node_blocks(path) -> FEMesh:
    """MODEL of a deck with several ``*NODE`` blocks (as CalculiX reads it: sidprep.fe.matrices.keywords),
    read from a copy with one block; messages and the mesh name ``path``."""
    with tempfile.TemporaryDirectory() as tmp:
        flat = deck_text_path(path, tmp)
        try:
            m = read_model(flat)
        except InputError as exc:
            raise InputError(str(exc).replace(str(flat), str(path))) from None
    return replace(m, source=str(path), sha256=file_sha256(path),
                   notes=tuple(n.replace(str(flat), str(path)) for n in m.notes))


def abaqus_types(path) -> set[str]:
    """The element types of the ``*ELEMENT`` blocks of an Abaqus / CalculiX deck (suffixes such as
    R, H, M, I dropped for the solid types of ``ABAQUS_NODES``)."""
    return set().union(*(abaqus_types_of(line) for line in abaqus_lines(path) if line[:8].upper() == "*ELEMENT"))


def abaqus_types_of(line: str) -> set[str]:
    """{the element type} of one ``*ELEMENT`` keyword line (solid types without their R/H/M/I suffix)."""
    kind = dict(w.split("=", 1) for w in (x.strip().upper() for x in line.split(",")[1:]) if "=" in w).get("TYPE", "")
    return {kind.rstrip("RHIM") if kind.rstrip("RHIM") in ELEMENT_NODES else kind}


def element_model(m, path, node_ids=None, structural: bool = False) -> FEMesh:
    """The FEMesh of a meshio mesh of solid, shell and beam elements of any type (module docstring);
    ``node_ids``: the FE code's node numbers of ``m.points`` (None: read from the deck);
    ``structural``: its triangles, quadrilaterals and lines are shells and beams
    (:func:`has_structural_elements`), else only sets of nodes."""
    blocks = [b for b in m.cells if b.type in FAMILY]
    others = [b for b in m.cells if structural and b.type in STRUCTURAL]
    if not blocks and not any(STRUCTURAL[b.type] != "vertex" for b in others):
        raise InputError(f"{path}: no solid, shell or beam elements (tetrahedra, hexahedra, wedges, pyramids, "
                         "triangles, quadrilaterals, lines); give the deck with the model's elements")
    points = np.asarray(m.points, dtype=float)
    node_ids = _node_ids(m, path) if node_ids is None else node_ids
    used = np.zeros(len(points), bool)
    for b in blocks + others:
        used[b.data] = True
    keep = np.flatnonzero(used)
    renumber = np.cumsum(used) - 1
    tets, faces = [np.zeros((0, 4), np.int64)], []
    for b in blocks:
        family = FAMILY[b.type]
        corners = renumber[b.data[:, :CORNERS[family]]]                 # VTK: corner nodes first
        t = corners[:, np.array(TETS[family])]                          # (ne, k, 4)
        x = points[keep][t]
        vol = np.einsum("eki,eki->ek", np.cross(x[..., 1, :] - x[..., 0, :], x[..., 2, :] - x[..., 0, :]),
                        x[..., 3, :] - x[..., 0, :])
        sign = np.sign(vol.sum(axis=1))
        t[vol < 0] = t[vol < 0][:, [0, 2, 1, 3]]
        tets.append(t.reshape(-1, 4))
        for f in FACES[family]:
            face = corners[:, list(f)]
            faces.append(np.where(sign[:, None] < 0, face[:, ::-1], face))
    node_sets = {name: np.unique(renumber[idx][used[idx]]) for name, idx in m.point_sets.items()}
    for name, per_block in m.cell_sets.items():          # sets of surface elements: their nodes
        nodes = [m.cells[k].data[np.asarray(idx, np.int64)].ravel() for k, idx in enumerate(per_block)
                 if idx is not None and len(idx) and m.cells[k].type not in FAMILY]
        if nodes and name not in node_sets:
            nodes = np.concatenate(nodes)
            node_sets[name] = np.unique(renumber[nodes[used[nodes]]])
    shells = [renumber[b.data[:, :CORNERS[STRUCTURAL[b.type]]]] for b in others
              if STRUCTURAL[b.type] in ("triangle", "quad")]
    surface = np.concatenate([outer_surface(faces), both_sides(shells)]).astype(np.int64)
    return FEMesh(points=points[keep], cells=np.concatenate(tets), node_ids=node_ids[keep], node_sets=node_sets,
                  source=str(path), sha256=file_sha256(path), surface=surface,
                  notes=(f"{path}: {', '.join(sorted({b.type for b in blocks + others}))} elements: K and M from "
                         "the FE code" + ("; paths interpolate linearly between corner nodes" if blocks else ""),))


def both_sides(shells) -> np.ndarray:
    """(nt, 3) triangles of shell faces, each face once in each orientation (quadrilaterals split in
    two; faces shared by two shells once); ``shells``: list of (ne, 3) and (ne, 4) corner rows."""
    tri = [s if s.shape[1] == 3 else np.concatenate([s[:, [0, 1, 2]], s[:, [0, 2, 3]]]) for s in shells]
    if not tri:
        return np.zeros((0, 3), np.int64)
    t = np.concatenate(tri)
    t = t[np.unique(np.sort(t, axis=1), axis=0, return_index=True)[1]]
    return np.concatenate([t, t[:, ::-1]])


def outer_surface(faces) -> np.ndarray:
    """(nt, 3) triangles of the faces that belong to one element only (quadrilaterals split in two);
    ``faces``: list of (ne, 3) and (ne, 4) corner-node arrays."""
    out = [np.zeros((0, 3), np.int64)]
    for k in (3, 4):
        group = [f for f in faces if f.shape[1] == k]
        if not group:
            continue
        f = np.concatenate(group)
        _, inverse, counts = np.unique(np.sort(f, axis=1), axis=0, return_inverse=True, return_counts=True)
        f = f[counts[inverse.ravel()] == 1]
        out.append(f if k == 3 else np.concatenate([f[:, [0, 1, 2]], f[:, [0, 2, 3]]]))
    return np.concatenate(out).astype(np.int64)


def _node_ids(m, path) -> np.ndarray:
    """The deck's node numbers (Nastran through meshio, Abaqus/CalculiX from the *NODE lines)."""
    if hasattr(m, "points_id"):
        return np.asarray(m.points_id, np.int64)
    if path.suffix.lower() == ".inp":
        ids, _ = abaqus_ids(abaqus_lines(path))
        if len(ids) == len(m.points):
            return ids
    return np.arange(1, len(m.points) + 1, dtype=np.int64)


#: nodes per element of the Abaqus / CalculiX solid element types (C3D20R = C3D20, ...)
ABAQUS_NODES = {"C3D4": 4, "C3D10": 10, "C3D8": 8, "C3D20": 20, "C3D6": 6, "C3D15": 15, "C3D5": 5, "C3D13": 13}
#: the same of shells, beams and trusses (S4R = S4, B31H = B31, ...)
STRUCTURAL_NODES = {"S3": 3, "STRI3": 3, "S4": 4, "S6": 6, "STRI65": 6, "S8": 8, "S9R5": 9, "B31": 2, "B32": 3,
                    "B33": 3, "T3D2": 2, "T3D3": 3}
ELEMENT_NODES = ABAQUS_NODES | STRUCTURAL_NODES


def deck_elements(path) -> list[np.ndarray]:
    """The solid, shell and beam elements of a deck as (ne, k) arrays of the deck's node numbers, one
    per element type: Abaqus / CalculiX ``*ELEMENT`` blocks read directly (their numbers only,
    ``*INCLUDE`` followed), Nastran decks by sidprep.fe.matrices.nastran_deck, other formats through
    meshio."""
    path = Path(path)
    if path.suffix.lower() != ".inp":
        m, ids = nastran_mesh(path) if is_nastran(path) else (meshio_read(path), None)
        ids = _node_ids(m, path) if ids is None else ids
        lines = is_nastran(path)                           # other formats: no shells or beams
        return [ids[b.data] for b in m.cells if b.type in FAMILY or lines and STRUCTURAL.get(b.type, "vertex") != "vertex"]
    blocks, numbers, per = [], [], 0
    for line in abaqus_lines(path) + ["*END\n"]:
        if line.startswith("**"):
            continue
        if line.startswith("*"):
            if per and numbers:
                blocks.append(_element_table(numbers, per, path))
            per = ELEMENT_NODES.get(next(iter(abaqus_types_of(line))), 0) if line[:8].upper() == "*ELEMENT" else 0
            numbers = []
        elif per:
            numbers.append(line)
    return blocks


def deck_lines(path) -> np.ndarray:
    """(ne, 2) node numbers of the two-node line elements (beams, rods: CBAR, B31, ...) of a deck, for
    their tubes in the surface (sidprep.fe.matrices.tubes); none for other formats."""
    path = Path(path)
    if is_nastran(path):
        m, ids = nastran_mesh(path)
    elif path.suffix.lower() == ".inp" and any(t.startswith(("B", "T3D")) for t in abaqus_types(path)):
        m = meshio_read(path, abaqus_lines(path))
        ids = _node_ids(m, path)
    else:
        return np.zeros((0, 2), np.int64)
    return np.concatenate([np.zeros((0, 2), np.int64)] + [ids[b.data] for b in m.cells if b.type == "line"])


def _element_table(lines: list[str], per: int, path) -> np.ndarray:
    """(ne, per) node numbers of the data lines of one *ELEMENT block (element number first)."""
    values = np.array([v for v in ",".join(lines).replace("\n", ",").split(",") if v.strip()], dtype=np.int64)
    if values.size % (per + 1):
        raise InputError(f"{path}: an *ELEMENT block does not hold {per} nodes per element; fix the deck")
    return values.reshape(-1, per + 1)[:, 1:]
