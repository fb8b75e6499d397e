"""Tetrahedral FE meshes: the container ``FEMesh`` and ``read_mesh``, the one entry point that picks
a reader (``sidprep.fe.readers``: gmsh, meshio, Abaqus), checks and repairs what it read
(``sidprep.fe.validation``) and notes the mesh's parts (``sidprep.fe.topology``).

Node order of a cell (the canonical order used everywhere in sidprep, = VTK / meshio; the
constants ``TET10_EDGES`` and ``TET_FACES`` are in ``sidprep.fe.topology``):
tet4: vertices 0..3; tet10: vertices 0..3, then mid-edge nodes of the edges
(0,1), (1,2), (0,2), (0,3), (1,3), (2,3).
DOFs are node-interleaved: DOF 3*i + c is component c (x, y, z) of node i.
"""

from __future__ import annotations

import hashlib
import os
import re
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Mapping

import numpy as np

from sidprep.errors import InputError
from sidprep.fe.readers.gmsh import GEOMETRY_SUFFIXES, UNIT_CARRYING_SUFFIXES, read_gmsh
from sidprep.fe.topology import connected_parts
from sidprep.fe.validation import validated


@dataclass(frozen=True)
class FEMesh:
    """A validated tetrahedral mesh.

    Attributes
    ----------
    points : (n_nodes, 3) float64
        Node coordinates, in the length unit of ``length_unit``.
    cells : (n_cells, 4) or (n_cells, 10) int64
        Connectivity in the canonical node order (module docstring), positive volume.
    node_ids : (n_nodes,) int64
        The node numbers of the source file (used as SID node names).
    node_sets : mapping name -> (k,) int64
        Physical groups / node sets, as sorted unique node indices (0-based rows of ``points``).
    cell_sets : mapping name -> (k,) int64
        Volume physical groups / element sets, as cell indices.
    source : str
        The file the mesh was read from.
    sha256 : str
        Hash of that file's bytes (provenance).
    notes : tuple of str
        One-line notes about repairs made while reading (merged duplicates, dropped nodes, ...).
    length_unit : str
        "m" unless scaled otherwise.
    surface : (nt, 3) int64 or None
        Outer-surface triangles given by the model (imported decks of other elements,
        sidprep.fe.matrices.deck); None: the boundary faces of ``cells``.
    ties : sidprep.fe.ties.Ties or None
        Multipoint constraints of tied surfaces (assemblies, sidprep.jobs.assembly): nodes whose
        displacement is interpolated from other nodes; None: no constraint.
    rotational : (n_nodes,) bool or None
        The rows that hold a 6-DOF node's rotations rx, ry, rz, not a point's displacement (imported
        shells and beams, sidprep.fe.matrices.model_dofs); None: none.
    """

    points: np.ndarray
    cells: np.ndarray
    node_ids: np.ndarray
    node_sets: Mapping[str, np.ndarray] = field(default_factory=dict)
    cell_sets: Mapping[str, np.ndarray] = field(default_factory=dict)
    source: str = ""
    sha256: str = ""
    notes: tuple[str, ...] = ()
    length_unit: str = "m"
    surface: np.ndarray | None = None
    ties: object = None
    rotational: np.ndarray | None = None

    @property
    def order(self) -> int:
        """1 for tet4, 2 for tet10."""
        return 1 if self.cells.shape[1] == 4 else 2

    @property
    def n_nodes(self) -> int:
        return self.points.shape[0]

    @property
    def n_dof(self) -> int:
        return 3 * self.points.shape[0]

    def scaled(self, factor: float, length_unit: str = "m") -> "FEMesh":
        """The same mesh with coordinates multiplied by ``factor`` (e.g. 1e-3 for mm -> m)."""
        return replace(self, points=self.points * factor, length_unit=length_unit)

    def in_metres(self, length_to_m: float, unit_system: str) -> "FEMesh":
        """Coordinates in metres, from a file whose lengths are in ``unit_system`` units
        (``length_to_m`` m each).  STEP/IGES files carry their own unit and were read in metres
        already: they are left as they are, with a note."""
        if length_to_m == 1.0:
            return self
        if self.source.lower().endswith(UNIT_CARRYING_SUFFIXES):
            note = (f"{self.source}: coordinates taken in the file's own unit (converted to m); "
                    f"--units {unit_system} applies to the material values only")
            return replace(self, notes=self.notes + (note,))
        return self.scaled(length_to_m)


def read_mesh(path, *, size: float | None = None, order: int = 2) -> FEMesh:
    """Read a tetrahedral mesh (or mesh a geometry file) and validate it.

    Parameters
    ----------
    path : str or Path
        ``.msh`` (gmsh 2.2 / 4.1, ASCII or binary; read through the gmsh API), any volume format
        meshio reads (``.inp``, ``.bdf``/``.nas``, ``.vtu``, ``.vtk``, ``.med``, ...), or a
        geometry file (``.geo``, ``.step``/``.stp``, ``.brep``, ``.iges``) meshed by gmsh.
    size : float, optional
        Target element size for geometry files (their unit; STEP/IGES are converted to metres);
        it replaces the sizes the file sets at its points.  ``None`` keeps the sizes the file
        or gmsh choose.  Ignored for mesh files.
    order : {1, 2}
        Element order for geometry files (tet4 / tet10).  Mesh files keep their own order.

    Returns
    -------
    FEMesh
        Tetrahedra in canonical VTK node order with positive volume.  Surface, line and point
        physical groups (gmsh) / node sets and surface element sets (meshio) become
        ``node_sets``; volume groups / element sets become ``cell_sets``.  Other elements are
        dropped.  Repairs (negative-volume cells re-ordered, duplicate nodes merged, unreferenced
        nodes dropped) and disconnected parts are listed in ``notes``.

    Notes
    -----
    Orientation: a tetrahedron whose corner nodes span a negative volume is a valid element
    written in the other orientation convention (MED / Salome and some exporters use it), so its
    node order is reversed (vertices 1 and 2 swapped with their edge nodes) and the count and
    worst element are noted; FE codes that reject such elements leave the user re-exporting for
    no gain.  What cannot be repaired is rejected (``sidprep.fe.validation``): flat elements
    (|V| / l_rms^3 below ``FLAT_ELEMENT_TOL``) and overlapping ones (element volumes that do not add
    up to the volume the boundary encloses, ``ENCLOSED_VOLUME_RTOL``).  Node and element numbers in messages and
    ``node_ids`` are the file's (gmsh, Abaqus, Nastran); other formats number from 1.

    Raises
    ------
    InputError
        Missing / unreadable / truncated file, unknown extension, no tetrahedra, non-tet volume
        elements, mixed tet4/tet10, NaN or inf coordinates, flat elements, overlapping elements.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: file not found; check the path")
    suffix = path.suffix.lower()
    if order not in (1, 2):
        raise InputError(f"--order {order}: element order must be 1 (tet4) or 2 (tet10)")
    if size is not None and not (np.isfinite(size) and size > 0):
        raise InputError(f"--size {size}: the element size must be a positive length")
    check_file_content(path)
    if suffix == ".msh" or suffix in GEOMETRY_SUFFIXES:
        raw = read_gmsh(path, size=size, order=order)
    else:
        from sidprep.fe.readers.meshio import read_meshio  # deferred: 0.09 s import (meshio, rich), not for .msh

        raw = read_meshio(path)
    raw, notes = validated(raw, path)
    mesh = FEMesh(points=raw.points, cells=raw.cells, node_ids=raw.node_ids, node_sets=raw.node_sets,
                  cell_sets=raw.cell_sets, source=str(path), sha256=file_sha256(path), notes=notes)
    n_parts, _ = connected_parts(mesh)
    if n_parts > 1:
        note = f"mesh has {n_parts} disconnected parts; each adds 6 rigid-body modes"
        mesh = replace(mesh, notes=mesh.notes + (note,))
    return mesh


#: a file this large whose holes (never-written regions, read as zeros) cover more than HOLE_SHARE of it
#: is not a mesh a mesher wrote: refused before a reader scans its zeros (minutes for 2 GB)
HOLE_CHECK_BYTES = 1 << 20
HOLE_SHARE = 0.5
#: endings of text mesh formats (and ASCII .msh): a NUL byte in their first or last SCAN_BYTES is damage
TEXT_SUFFIXES = (".inp", ".bdf", ".nas", ".dat", ".geo", ".mesh")
SCAN_BYTES = 1 << 20


def hole_bytes(path) -> int:
    """Bytes of ``path`` in holes (sparse regions: SEEK_DATA / SEEK_HOLE; 0 where the file system
    does not report them)."""
    size = os.path.getsize(path)
    holes, pos = 0, 0
    with open(path, "rb") as f:
        fd = f.fileno()
        try:
            while pos < size:
                try:
                    data = os.lseek(fd, pos, os.SEEK_DATA)
                except OSError:                  # ENXIO: no data after pos
                    return holes + size - pos
                holes += data - pos
                pos = os.lseek(fd, data, os.SEEK_HOLE)
        except (OSError, AttributeError):        # SEEK_DATA unsupported: no holes known
            return 0
    return holes


def check_file_content(path: Path) -> None:
    """Refuse, before a reader scans it, a file that cannot be a mesh however long it is: one mostly
    made of holes (a sparse file), or a text format (TEXT_SUFFIXES, ASCII .msh) with NUL bytes at its
    start or end; the readers' work is then bounded by what the file holds."""
    size = path.stat().st_size
    if size >= HOLE_CHECK_BYTES:
        holes = hole_bytes(path)
        if holes > HOLE_SHARE * size:
            raise InputError(f"{path}: {holes / 2**20:.0f} of its {size / 2**20:.0f} MiB were never written (a sparse "
                             "file: they read as zeros); not a mesh: write the file again")
    suffix = path.suffix.lower()
    with open(path, "rb") as f:
        head = f.read(SCAN_BYTES)
        f.seek(max(size - SCAN_BYTES, len(head)))
        tail = f.read(SCAN_BYTES)
    text = suffix in TEXT_SUFFIXES or (suffix == ".msh" and re.match(rb"\$MeshFormat\s+\S+\s+0\s", head))
    if text and (b"\0" in head or b"\0" in tail):
        where = head.find(b"\0") if b"\0" in head else size - len(tail) + tail.find(b"\0")
        raise InputError(f"{path}: a NUL byte at byte {where} of a text mesh format; the file is damaged or "
                         "not what its ending says: write it again")


def file_sha256(path) -> str:
    """Hex sha256 of a file's bytes, read in 1 MiB blocks (the provenance of a model)."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()
