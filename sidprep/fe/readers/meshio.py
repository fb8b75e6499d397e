"""The meshio reader: every volume format meshio reads other than ``.msh`` (``.inp``, ``.bdf`` /
``.nas``, ``.vtu``, ``.vtk``, ``.med``, ...); its tet10 node order is VTK's for every format.
Abaqus / CalculiX decks are given to meshio with their ``*INCLUDE`` files inline, and keep their
node and element numbers (``sidprep.fe.readers.abaqus``).
"""

from __future__ import annotations

import contextlib
import io
import tempfile
from pathlib import Path

import meshio
import numpy as np

from sidprep.errors import InputError
from sidprep.fe.readers import RawMesh
from sidprep.fe.readers.abaqus import abaqus_ids, abaqus_lines
from sidprep.fe.readers.gmsh import GEOMETRY_SUFFIXES


def meshio_read(path: Path, deck_lines: list[str] | None = None):
    """meshio's mesh of ``path``, quietly (meshio prints warnings and errors itself and exits on some
    broken files); an Abaqus / CalculiX deck is read from ``deck_lines``, its lines with every
    ``*INCLUDE`` resolved (meshio does not resolve them).  InputError when meshio fails."""
    try:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            if deck_lines is None:
                return meshio.read(path)
            with tempfile.TemporaryDirectory() as tmp:
                flat = Path(tmp) / path.name
                flat.write_text("".join(deck_lines))
                return meshio.read(flat, file_format="abaqus")
    except (Exception, SystemExit) as exc:  # ReadError, ValueError, KeyError, SystemExit, ...
        msg = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
        raise InputError(
            f"{path}: meshio could not read it ({type(exc).__name__}: {msg}); "
            "check that the file is complete and valid"
        ) from None


def read_meshio(path) -> RawMesh:
    """Any volume format meshio reads (module docstring), as read: the checks follow in
    ``sidprep.fe.validation``."""
    suffix = path.suffix.lower()
    if suffix not in meshio.extension_to_filetypes:
        known = ".msh, " + ", ".join(GEOMETRY_SUFFIXES) + ", " + ", ".join(
            sorted(meshio.extension_to_filetypes)
        )
        raise InputError(f"{path}: unknown mesh file extension '{suffix}'; use one of {known}")
    deck_lines = abaqus_lines(path) if suffix == ".inp" else None
    m = meshio_read(path, deck_lines)
    volume = {"tetra", "tetra10", "hexahedron", "hexahedron20", "hexahedron27", "wedge",
              "wedge15", "pyramid", "pyramid13", "tetra20"}  # fmt: skip
    types = {b.type for b in m.cells}
    other = sorted(types & volume - {"tetra", "tetra10"})
    if other:
        raise InputError(
            f"{path}: contains volume elements other than tetrahedra ({', '.join(other)}); "
            "re-mesh the volume with tetrahedra only, or reduce it from its FE code's K and M "
            "with --matrices (docs/import.md)"
        )
    tet = types & {"tetra", "tetra10"}
    if not tet:
        raise InputError(f"{path}: contains no tetrahedra; mesh the volume (3D) with tet4 or tet10")
    if len(tet) > 1:
        raise InputError(f"{path}: mixes tet4 and tet10 elements; re-mesh with one element order")
    tet_type = tet.pop()
    blocks = [k for k, b in enumerate(m.cells) if b.type == tet_type]
    cells = np.concatenate([m.cells[k].data for k in blocks]).astype(np.int64)
    offsets = np.cumsum([0] + [len(m.cells[k].data) for k in blocks])
    node_sets = {name: np.unique(np.asarray(idx, np.int64)) for name, idx in m.point_sets.items()}
    cell_sets = {}
    for name, per_block in m.cell_sets.items():
        in_tets = [
            np.asarray(per_block[k], np.int64) + offsets[j]
            for j, k in enumerate(blocks)
            if per_block[k] is not None and len(per_block[k])
        ]
        if in_tets:
            cell_sets[name] = np.unique(np.concatenate(in_tets))
            continue
        set_nodes = [  # a set of surface / line / vertex elements: the nodes they use
            m.cells[k].data[np.asarray(idx, np.int64)].ravel()
            for k, idx in enumerate(per_block)
            if idx is not None and len(idx)
        ]
        if set_nodes and name not in node_sets:
            node_sets[name] = np.unique(np.concatenate(set_nodes)).astype(np.int64)
    points = np.asarray(m.points, dtype=float)
    if points.shape[1] == 2:
        raise InputError(f"{path}: has 2D coordinates; a tetrahedral mesh needs x, y, z")
    node_ids, cell_ids = _meshio_ids(m, blocks, deck_lines)
    return RawMesh(points, node_ids, cells, cell_ids, node_sets, cell_sets)


def _meshio_ids(m, blocks, deck_lines) -> tuple[np.ndarray, np.ndarray]:
    """The file's node and tetrahedron numbers (Nastran, Abaqus); else 1, 2, ... in file order."""
    n_cells = sum(len(m.cells[k].data) for k in blocks)
    if hasattr(m, "points_id") and hasattr(m, "cells_id"):  # meshio's Nastran reader keeps them
        return np.asarray(m.points_id, np.int64), np.concatenate([m.cells_id[k] for k in blocks])
    if deck_lines is not None:
        node_ids, tet_ids = abaqus_ids(deck_lines)
        if len(node_ids) == len(m.points) and len(tet_ids) == n_cells:
            return node_ids, tet_ids
    return np.arange(1, len(m.points) + 1, dtype=np.int64), np.arange(1, n_cells + 1, dtype=np.int64)
