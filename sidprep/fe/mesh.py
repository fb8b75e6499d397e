"""Tetrahedral FE meshes: the data model (readers and checks follow below it).

Node order of a cell (the canonical order used everywhere in sidprep, = VTK / meshio):
tet4: vertices 0..3; tet10: vertices 0..3, then mid-edge nodes of the edges
(0,1), (1,2), (0,2), (0,3), (1,3), (2,3).
DOFs are node-interleaved: DOF 3*i + c is component c (x, y, z) of node i.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import itertools
import re
import signal
import struct
import tempfile
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Mapping

import meshio
import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from sidprep.errors import InputError


#: mid-edge node k (k = 4..9 of a tet10) lies on the edge between these two vertices
TET10_EDGES = ((0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3))


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


# ---------------------------------------------------------------------------------------------
# Reading
# ---------------------------------------------------------------------------------------------
#: nodes closer than this fraction of the bounding-box diagonal are merged as duplicates
DUPLICATE_NODE_RTOL = 1e-9
#: largest |coordinate| of a node (any length unit): 1e12 m is beyond any body, and keeps squared
#: distances and volumes (x^3) far from floating-point overflow
MAX_COORDINATE = 1e12
#: an element with |V| / l_rms**3 below this is flat (a regular tetrahedron has 0.118)
FLAT_ELEMENT_TOL = 1e-8
#: allowed relative gap between the sum of element volumes and the volume enclosed by the
#: boundary; a larger gap means overlapping (tangled) elements
ENCLOSED_VOLUME_RTOL = 1e-6

#: files meshed through the gmsh API (geometry); ``.msh`` is read through the gmsh API too
GEOMETRY_SUFFIXES = (".geo", ".step", ".stp", ".brep", ".brp", ".iges", ".igs")
#: geometry formats that carry their length unit: read_mesh returns them in metres
UNIT_CARRYING_SUFFIXES = (".step", ".stp", ".iges", ".igs")
#: gmsh element type numbers of the linear and quadratic tetrahedron
_GMSH_TET = (4, 11)
#: gmsh tet10 node k -> canonical node: gmsh numbers the last two edges (2,3), (1,3)
_GMSH_TET10_TO_CANONICAL = np.array([0, 1, 2, 3, 4, 5, 6, 7, 9, 8])
#: re-ordering that reverses a cell's orientation (swap vertices 1 and 2 with their edges)
_FLIP = {4: np.array([0, 2, 1, 3]), 10: np.array([0, 2, 1, 3, 6, 5, 4, 7, 9, 8])}
#: corner-node faces of a positively oriented tetrahedron, numbered so the normals point out
TET_FACES = np.array([(0, 2, 1), (0, 1, 3), (1, 2, 3), (0, 3, 2)])


@dataclass(frozen=True)
class _RawMesh:
    """Tetrahedra as read, before the checks: canonical node order, any orientation."""

    points: np.ndarray
    node_ids: np.ndarray
    cells: np.ndarray
    cell_ids: np.ndarray
    node_sets: dict
    cell_sets: dict


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
    no gain.  What cannot be repaired is rejected: flat elements (|V| / l_rms^3 below
    ``FLAT_ELEMENT_TOL``) and overlapping ones (element volumes that do not add up to the volume
    the boundary encloses, ``ENCLOSED_VOLUME_RTOL``).  Node and element numbers in messages and
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
    if suffix == ".msh" or suffix in GEOMETRY_SUFFIXES:
        raw = _read_gmsh(path, size=size, order=order)
    else:
        raw = _read_meshio(path)
    return _validated(raw, path)


def _file_sha256(path) -> str:

    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _index_of(tags: np.ndarray, wanted: np.ndarray, path) -> np.ndarray:
    """Row indices of the ``wanted`` node / element numbers in the (unique) array ``tags``."""
    sorter = np.argsort(tags, kind="stable")
    index = sorter[np.clip(np.searchsorted(tags, wanted, sorter=sorter), 0, max(len(tags) - 1, 0))]
    missing = tags[index] != wanted if len(tags) else np.ones(len(wanted), bool)
    if missing.any():
        raise InputError(
            f"{path}: refers to node/element {wanted[missing][0]}, which it does not define; "
            "fix the file"
        )
    return index


@contextlib.contextmanager
def _gmsh_session(options: dict):
    """A quiet gmsh session with ``options`` set and an empty model of its own.

    Reuses a session the caller already started (its models and options are restored
    afterwards), else starts one and finalizes it.
    """
    import gmsh  # deferred: 0.6 s import, geometry files only

    own = not gmsh.isInitialized()
    if own:
        gmsh.initialize(readConfigFiles=False, interruptible=False)
        _python_sigpipe()
    options = {"General.Terminal": 0, "General.Verbosity": 0, **options}
    get = {str: gmsh.option.getString, float: gmsh.option.getNumber}
    put = {str: gmsh.option.setString, float: gmsh.option.setNumber}
    kinds = {name: str if isinstance(value, str) else float for name, value in options.items()}
    saved = {name: get[kinds[name]](name) for name in options}
    previous = None if own else gmsh.model.getCurrent()
    for name, value in options.items():
        put[kinds[name]](name, value)
    gmsh.model.add("sidprep_read_mesh")
    try:
        yield gmsh
    finally:
        if own:
            gmsh.finalize()
        else:
            gmsh.model.setCurrent("sidprep_read_mesh")
            gmsh.model.remove()
            if previous:
                gmsh.model.setCurrent(previous)
            for name, value in saved.items():
                put[kinds[name]](name, value)


def _python_sigpipe() -> None:
    """Give SIGPIPE back the disposition Python gave it (ignored: writes to a closed pipe raise
    BrokenPipeError): gmsh.initialize resets it to "terminate" in C, and a later write to a pipe whose
    reader died (a killed pool worker, sidprep.jobs.parts) ended the process silently with exit 141."""
    handler = signal.getsignal(signal.SIGPIPE)
    with contextlib.suppress(ValueError, TypeError):      # not the main thread / a handler set in C
        signal.signal(signal.SIGPIPE, handler)


def _read_gmsh(path, *, size, order) -> _RawMesh:
    """Open a .msh file or mesh a geometry file with the gmsh API."""
    suffix = path.suffix.lower()
    options = {"Mesh.ElementOrder": float(order)}
    if suffix in UNIT_CARRYING_SUFFIXES:
        options["Geometry.OCCTargetUnit"] = "M"  # these files carry their unit
    if size is not None:  # replaces the sizes the file gives its points
        options.update({"Mesh.MeshSizeFromPoints": 0.0, "Mesh.MeshSizeMax": float(size)})
    with _gmsh_session(options) as gmsh:
        try:
            if suffix == ".msh":
                _refuse_native_crashes(gmsh, path)
            gmsh.merge(str(path))
            if suffix != ".msh" and not _gmsh_volume_types(gmsh):
                gmsh.model.mesh.generate(3)
                gmsh.model.mesh.setOrder(order)
            return _gmsh_arrays(gmsh, path)
        except InputError:
            raise
        except Exception as exc:  # gmsh raises a bare Exception with its last error message
            what = "mesh" if suffix != ".msh" else "read"
            raise InputError(
                f"{path}: gmsh could not {what} it ({str(exc).strip() or 'unknown error'}); "
                "check that the file is complete and valid"
            ) from None


def _refuse_native_crashes(gmsh, path) -> None:
    """Refuse, before gmsh reads it, a .msh file that crashes gmsh's reader (the process, not
    with an error): two kinds of volume element in one entity, and (MSH 2.2 ASCII) an element
    on a node the file does not define (a segmentation fault in ``gmsh.merge``).

    gmsh keeps all tetrahedra of a volume entity in one list and sizes its output arrays by the
    type of the first (``getElementsByType``): a tet10 after a tet4 writes past the array and
    aborts the process in malloc.  So the element types per entity are counted from the file's
    ``$Elements`` section first (``msh_volume_types``).
    """
    node = msh2_undefined_node(path)
    if node is not None:
        raise InputError(f"{path}: an element refers to node {node}, which the file does not define; fix the file")
    for entity, types in msh_volume_types(path, gmsh.model.mesh.getElementProperties).items():
        if len(types) > 1:
            names = ", ".join(sorted(gmsh.model.mesh.getElementProperties(t)[0] for t in types))
            raise InputError(f"{path}: volume {entity} mixes element types ({names}); re-mesh it with one "
                             "element order (all tet4 or all tet10)")


def msh2_undefined_node(path) -> int | None:
    """The first node number an element of an MSH 2.2 ASCII file uses but $Nodes does not define
    (None: all defined, or another layout; gmsh reports those itself)."""
    data = path.read_bytes()
    if not re.search(rb"\$MeshFormat\s+2\.\d+\s+0\s", data):
        return None
    try:
        nodes = data[data.index(b"$Nodes"):].split(b"\n")
        defined = {int(line.split(None, 1)[0]) for line in nodes[2:2 + int(nodes[1])]}
        elements = data[data.index(b"$Elements"):].split(b"\n")
        for line in elements[2:2 + int(elements[1])]:
            f = [int(v) for v in line.split()]
            missing = [n for n in f[3 + f[2]:] if n not in defined]
            if missing:
                return missing[0]
    except (ValueError, IndexError):
        return None
    return None


def msh_volume_types(path, properties) -> dict[int, set[int]]:
    """{volume entity tag: gmsh element types of dimension 3 in it}, from a .msh file (2.2 / 4.x,
    ASCII or binary).  ``properties(type)`` is gmsh's ``getElementProperties`` (name, dim, order,
    number of nodes, ...).  Unknown layouts return {} (gmsh then reads and judges the file)."""
    data = path.read_bytes()
    head = re.search(rb"\$MeshFormat\s+(\S+)\s+(\d)\s+(\d)", data)
    start = data.find(b"$Elements")
    if head is None or start < 0:
        return {}
    version, binary = float(head.group(1)), head.group(2) == b"1"
    body = data[data.index(b"\n", start) + 1:]
    census: dict[int, set[int]] = {}
    try:
        for entity, etype in _msh_element_blocks(body, version, binary, properties):
            if properties(etype)[1] == 3:
                census.setdefault(entity, set()).add(etype)
    except Exception:  # noqa: BLE001  struct / index / gmsh errors: a broken section, which
        return {}      # gmsh's own reader then reports
    return census


def _msh_element_blocks(body: bytes, version: float, binary: bool, properties):
    """(entity tag, element type) pairs of an $Elements section (after its header line)."""
    if version < 3:                                   # 2.2: per element, entity = second tag
        count, _, rest = body.partition(b"\n")
        if not binary:
            for line in rest.split(b"\n", int(count))[:int(count)]:
                f = line.split()
                yield (int(f[4]) if int(f[2]) >= 2 else 0), int(f[1])
            return
        pos, seen = 0, 0
        while seen < int(count):
            etype, n, ntags = struct.unpack_from("<3i", rest, pos)
            width = 1 + ntags + properties(etype)[3]
            rows = np.frombuffer(rest, "<i4", n * width, pos + 12).reshape(n, width)
            for entity in np.unique(rows[:, 2]) if ntags >= 2 else (0,):
                yield int(entity), etype
            pos, seen = pos + 12 + 4 * n * width, seen + n
        return
    if not binary:                                    # 4.x: per block of one entity
        lines = body.split(b"\n")
        k = 1
        for _ in range(int(lines[0].split()[0])):
            f = [int(v) for v in lines[k].split()]
            yield (f[1] if version >= 4.1 else f[0]), f[2]
            k += 1 + f[3]
        return
    pos = 32
    for _ in range(struct.unpack_from("<Q", body, 0)[0]):
        first, second, etype = struct.unpack_from("<3i", body, pos)
        n = struct.unpack_from("<Q", body, pos + 12)[0]
        yield (second if version >= 4.1 else first), etype
        pos += 20 + 8 * n * (1 + properties(etype)[3])


def _gmsh_volume_types(gmsh) -> list[int]:
    return list(gmsh.model.mesh.getElementTypes(dim=3))


def _gmsh_arrays(gmsh, path) -> _RawMesh:
    """Tetrahedra, nodes and physical groups of the current gmsh model."""
    types = _gmsh_volume_types(gmsh)
    other = [gmsh.model.mesh.getElementProperties(t)[0] for t in types if t not in _GMSH_TET]
    if other:
        raise InputError(
            f"{path}: contains volume elements other than tetrahedra ({', '.join(other)}); "
            "re-mesh the volume with tetrahedra only"
        )
    tet_types = [t for t in types if t in _GMSH_TET]
    if not tet_types:
        raise InputError(f"{path}: contains no tetrahedra; mesh the volume (3D) with tet4 or tet10")
    if len(tet_types) > 1:
        raise InputError(f"{path}: mixes tet4 and tet10 elements; re-mesh with one element order")
    etype = tet_types[0]
    cell_ids, cell_tags = gmsh.model.mesh.getElementsByType(etype)
    n_per = 4 if etype == 4 else 10
    node_tags, coords, _ = gmsh.model.mesh.getNodes()
    node_tags = np.asarray(node_tags, dtype=np.int64)
    points = np.asarray(coords, dtype=float).reshape(-1, 3)
    cells = _index_of(node_tags, np.asarray(cell_tags, dtype=np.int64), path).reshape(-1, n_per)
    if n_per == 10:
        cells = cells[:, _GMSH_TET10_TO_CANONICAL]
    cell_ids = np.asarray(cell_ids, dtype=np.int64)
    node_sets, cell_sets = {}, {}
    for dim, tag in gmsh.model.getPhysicalGroups():
        name = gmsh.model.getPhysicalName(dim, tag) or f"group_{tag}"
        if dim < 3:
            tags, _ = gmsh.model.mesh.getNodesForPhysicalGroup(dim, tag)
            node_sets[name] = np.unique(_index_of(node_tags, np.asarray(tags, np.int64), path))
        else:
            ids = [np.zeros(0, np.int64)]
            for entity in gmsh.model.getEntitiesForPhysicalGroup(dim, tag):
                types, tags, _ = gmsh.model.mesh.getElements(3, entity)
                ids += [np.asarray(t, np.int64) for k, t in zip(types, tags) if k == etype]
            cell_sets[name] = np.unique(_index_of(cell_ids, np.concatenate(ids), path))
    return _RawMesh(points, node_tags, cells, cell_ids, node_sets, cell_sets)


def _read_meshio(path) -> _RawMesh:
    """Any volume format meshio reads; its tet10 node order is VTK's for every format."""


    suffix = path.suffix.lower()
    if suffix not in meshio.extension_to_filetypes:
        known = ".msh, " + ", ".join(GEOMETRY_SUFFIXES) + ", " + ", ".join(
            sorted(meshio.extension_to_filetypes)
        )
        raise InputError(f"{path}: unknown mesh file extension '{suffix}'; use one of {known}")
    abaqus_lines = _abaqus_lines(path) if suffix == ".inp" else None
    try:  # meshio prints warnings and errors itself, and exits on some broken files
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            if abaqus_lines is None:
                m = meshio.read(path)
            else:  # meshio does not resolve *INCLUDE: give it the included text inline
                with tempfile.TemporaryDirectory() as tmp:
                    flat = Path(tmp) / path.name
                    flat.write_text("".join(abaqus_lines))
                    m = meshio.read(flat, file_format="abaqus")
    except (Exception, SystemExit) as exc:  # ReadError, ValueError, KeyError, SystemExit, ...
        msg = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
        raise InputError(
            f"{path}: meshio could not read it ({type(exc).__name__}: {msg}); "
            "check that the file is complete and valid"
        ) from None
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
    node_ids, cell_ids = _meshio_ids(m, blocks, abaqus_lines)
    return _RawMesh(points, node_ids, cells, cell_ids, node_sets, cell_sets)


def _meshio_ids(m, blocks, abaqus_lines) -> tuple[np.ndarray, np.ndarray]:
    """The file's node and tetrahedron numbers (Nastran, Abaqus); else 1, 2, ... in file order."""
    n_cells = sum(len(m.cells[k].data) for k in blocks)
    if hasattr(m, "points_id") and hasattr(m, "cells_id"):  # meshio's Nastran reader keeps them
        return np.asarray(m.points_id, np.int64), np.concatenate([m.cells_id[k] for k in blocks])
    if abaqus_lines is not None:
        node_ids, tet_ids = _abaqus_ids(abaqus_lines)
        if len(node_ids) == len(m.points) and len(tet_ids) == n_cells:
            return node_ids, tet_ids
    return np.arange(1, len(m.points) + 1, dtype=np.int64), np.arange(1, n_cells + 1, dtype=np.int64)


def _abaqus_lines(path) -> list[str]:
    """The lines of an Abaqus / CalculiX input file with every ``*INCLUDE`` replaced by its file."""
    lines = []
    with open(path, errors="replace") as f:
        for line in f:
            if line[:8].upper() == "*INCLUDE":
                included = Path(path).parent / line.split("=", 1)[1].strip().strip('"')
                if not included.is_file():
                    raise InputError(
                        f"{path}: *INCLUDE file {included} not found; "
                        "fix INPUT= (a path relative to the including file)"
                    )
                lines.extend(_abaqus_lines(included))
            else:
                lines.append(line if line.endswith("\n") else line + "\n")
    return lines


def _abaqus_ids(lines) -> tuple[np.ndarray, np.ndarray]:
    """Node numbers of the ``*NODE`` lines and element numbers of the C3D4* / C3D10* elements,
    in file order (the order meshio reads them in)."""
    node_ids, tet_ids = [], []
    block, tokens, per_element = None, [], 0

    def close():
        if block == "ELEMENT" and per_element:
            ids = np.array([int(t) for t in tokens if t.strip()], dtype=np.int64)
            tet_ids.append(ids.reshape(-1, per_element + 1)[:, 0])

    for line in lines:
        if line.startswith("**"):
            continue
        if line.startswith("*"):
            close()
            words = [w.strip().upper() for w in line[1:].split(",")]
            params = dict(w.split("=", 1) for w in words[1:] if "=" in w)
            block, tokens = words[0], []
            kind = params.get("TYPE", "")
            per_element = 10 if kind.startswith("C3D10") else 4 if kind.startswith("C3D4") else 0
        elif block == "NODE" and line.strip():
            node_ids.append(int(line.split(",", 1)[0]))
        elif block == "ELEMENT" and per_element:
            tokens.extend(line.split(","))
    close()
    tets = np.concatenate(tet_ids) if tet_ids else np.zeros(0, np.int64)
    return np.array(node_ids, dtype=np.int64), tets


# ---------------------------------------------------------------------------------------------
# Checks and repairs
# ---------------------------------------------------------------------------------------------
def _validated(raw: _RawMesh, path) -> FEMesh:
    """Run the checks on a raw mesh; raise ``InputError`` or repair and note."""
    notes = []
    outside = (raw.cells < 0) | (raw.cells >= len(raw.points))
    if outside.any():
        row = int(np.argmax(outside.any(axis=1)))
        raise InputError(f"{path}: element {raw.cell_ids[row]} refers to node index {raw.cells[outside][0]}, which "
                         f"the file does not define ({len(raw.points)} nodes); fix the file")
    keep_nodes, cells = _drop_unreferenced(raw.points, raw.cells)
    n_dropped = len(raw.points) - len(keep_nodes)
    if n_dropped:
        notes.append(f"{n_dropped} nodes not used by any tetrahedron were dropped")
    points, node_ids = raw.points[keep_nodes], raw.node_ids[keep_nodes]
    node_map = np.full(len(raw.points), -1, dtype=np.int64)
    node_map[keep_nodes] = np.arange(len(keep_nodes))

    bad = ~(np.abs(points) <= MAX_COORDINATE).all(axis=1)
    if bad.any():
        raise InputError(
            f"{path}: {int(bad.sum())} nodes have NaN, infinite or larger than {MAX_COORDINATE:g} coordinates "
            f"(first: node {node_ids[bad][0]}); fix the coordinates in the mesh file"
        )

    merge = _duplicate_node_map(points)
    n_merged = len(points) - (merge.max() + 1 if len(merge) else 0)
    if n_merged:
        first = np.flatnonzero(np.bincount(merge) > 1)[0]
        notes.append(
            f"{n_merged} duplicate nodes (closer than {DUPLICATE_NODE_RTOL:g} x bounding-box "
            f"diagonal) were merged (first: node {node_ids[merge == first][0]})"
        )
        keep = np.unique(merge, return_index=True)[1]
        points, node_ids, cells = points[keep], node_ids[keep], merge[cells]
        node_map = np.where(node_map >= 0, merge[np.maximum(node_map, 0)], -1)

    cells = _positively_oriented(points, cells, raw.cell_ids, path, notes)
    if cells.shape[1] == 10:
        _check_midnode_order(points, cells, raw.cell_ids, path)
    _check_no_overlap(points, cells, path)

    node_sets = {}
    for name, idx in raw.node_sets.items():
        mapped = node_map[idx]
        node_sets[name] = np.unique(mapped[mapped >= 0])
        if (mapped < 0).any():
            notes.append(
                f"node set '{name}': {int((mapped < 0).sum())} of its {len(idx)} nodes are on no "
                "tetrahedron and were left out"
            )
    mesh = FEMesh(
        points=points,
        cells=cells,
        node_ids=node_ids,
        node_sets=node_sets,
        cell_sets=dict(raw.cell_sets),
        source=str(path),
        sha256=_file_sha256(path),
        notes=tuple(notes),
    )
    n_parts, _ = connected_parts(mesh)
    if n_parts > 1:
        mesh = replace(
            mesh,
            notes=mesh.notes
            + (f"mesh has {n_parts} disconnected parts; each adds 6 rigid-body modes",),
        )
    return mesh


def _drop_unreferenced(points: np.ndarray, cells: np.ndarray):
    """(indices of the nodes used by ``cells``, cells renumbered onto them)."""
    used = np.zeros(len(points), dtype=bool)
    used[cells.ravel()] = True
    keep = np.flatnonzero(used)
    renumber = np.cumsum(used) - 1
    return keep, renumber[cells]


def close_pairs(points: np.ndarray, tol: float) -> np.ndarray:
    """(m, 2) index pairs i < j of the points at most ``tol`` apart, without a search tree (scipy.spatial
    costs 0.15 s to import): two points closer than h >= tol along every axis share a cell of width
    2 h in at least one of the 8 grids shifted by 0 or h along each axis; within a cell, all pairs
    are tested.  h is at least 2^-20 of the largest extent, so cell indices fit in 21 bits."""

    lo = points.min(axis=0)
    h = max(tol, float(np.ptp(points, axis=0).max()) * 2.0 ** -20, np.finfo(float).tiny)
    found = set()
    for shift in itertools.product((0.0, h), repeat=3):
        q = np.floor((points - lo + np.array(shift)) / (2 * h)).astype(np.int64)
        key = (q[:, 0] << 42) | (q[:, 1] << 21) | q[:, 2]
        order = np.argsort(key, kind="stable")
        bounds = np.flatnonzero(np.diff(np.concatenate([[-1], key[order], [-1]])) != 0)   # run starts + end
        shared = np.flatnonzero(np.diff(bounds) > 1)      # cells of several points: rare (duplicates)
        for start, stop in zip(bounds[shared], bounds[shared + 1]):
            for i, j in itertools.combinations(np.sort(order[start:stop]), 2):
                if np.linalg.norm(points[i] - points[j]) <= tol:
                    found.add((int(i), int(j)))
    return np.array(sorted(found), dtype=np.int64).reshape(-1, 2)


def _duplicate_node_map(points: np.ndarray) -> np.ndarray:
    """(n,) index of each node's merged node: clusters of nodes closer than the tolerance."""

    n = len(points)
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    diag = float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))
    pairs = close_pairs(points, DUPLICATE_NODE_RTOL * diag)
    if len(pairs) == 0:
        return np.arange(n, dtype=np.int64)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, labels = connected_components(graph, directed=False)
    # renumber clusters in the order of their first node, so the mesh keeps its node order
    _, first, inverse = np.unique(labels, return_index=True, return_inverse=True)
    rank = np.empty(len(first), dtype=np.int64)
    rank[np.argsort(first)] = np.arange(len(first))
    return rank[inverse]


def cell_volumes(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """(ne,) signed volumes of the straight tetrahedra spanned by the corner nodes (unit^3)."""
    x = points[cells[:, :4]]
    return np.einsum("ij,ij->i", np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), x[:, 3] - x[:, 0]) / 6


def _positively_oriented(points, cells, cell_ids, path, notes) -> np.ndarray:
    """Reject flat cells; re-order negative ones (the other orientation convention)."""
    vol = cell_volumes(points, cells)
    x = points[cells[:, :4]]
    edges = [x[:, b] - x[:, a] for a, b in TET10_EDGES]
    l_rms = np.sqrt(sum(np.einsum("ij,ij->i", e, e) for e in edges) / 6)
    with np.errstate(divide="ignore", invalid="ignore"):
        shape = np.abs(vol) / l_rms**3
    flat = ~(shape >= FLAT_ELEMENT_TOL)
    if flat.any():
        worst = cell_ids[np.argmin(np.where(np.isnan(shape), -1, shape))]
        raise InputError(
            f"{path}: {int(flat.sum())} elements have zero or near-zero volume "
            f"(worst: element {worst}); re-mesh or remove the flat elements"
        )
    negative = vol < 0
    if negative.any():
        worst = cell_ids[np.argmin(vol / l_rms**3)]
        notes.append(
            f"{int(negative.sum())} of {len(cells)} elements had negative volume (worst: element "
            f"{worst}); their node order was reversed (the other orientation convention)"
        )
        cells = cells.copy()
        cells[negative] = cells[negative][:, _FLIP[cells.shape[1]]]
    return cells


def _check_midnode_order(points, cells, cell_ids, path) -> None:
    """Each mid-edge node must be nearer its own edge's midpoint than any other edge's."""
    x = points[cells]
    x -= x[:, :4].mean(axis=1, keepdims=True)  # cell-local coordinates: no cancellation below
    mid = np.stack([(x[:, a] + x[:, b]) / 2 for a, b in TET10_EDGES], 1)
    node = x[:, 4:]
    # squared distances (ne, node, edge) without an (ne, 6, 6, 3) temporary
    dist2 = (
        np.einsum("eid,eid->ei", node, node)[:, :, None]
        + np.einsum("ejd,ejd->ej", mid, mid)[:, None, :]
        - 2 * node @ mid.transpose(0, 2, 1)
    )
    wrong = (dist2.argmin(axis=2) != np.arange(6)).any(axis=1)
    if wrong.any():
        raise InputError(
            f"{path}: {int(wrong.sum())} tet10 elements have mid-edge nodes on the wrong edges "
            f"(first: element {cell_ids[np.argmax(wrong)]}); the file's tet10 node order is not "
            "the format's standard one — export with the standard order"
        )


def _check_no_overlap(points, cells, path) -> None:
    """Element volumes must add up to the volume enclosed by the boundary (no tangled cells)."""
    _, counts, first = _face_table(cells)
    if (counts > 2).any():
        raise InputError(
            f"{path}: {int((counts > 2).sum())} faces are shared by more than two elements "
            "(duplicate or overlapping elements); fix the mesh"
        )
    faces = _corner_faces(cells, first[counts == 1])
    centre = points.mean(axis=0)
    x = points[faces] - centre
    enclosed = np.einsum("ij,ij->i", x[:, 0], np.cross(x[:, 1], x[:, 2])).sum() / 6
    total = cell_volumes(points, cells).sum()
    if abs(enclosed - total) > ENCLOSED_VOLUME_RTOL * total:
        raise InputError(
            f"{path}: element volumes add up to {total:.6g} but the boundary encloses "
            f"{enclosed:.6g} (overlapping or inverted elements); fix the mesh"
        )


# ---------------------------------------------------------------------------------------------
# Topology
# ---------------------------------------------------------------------------------------------
def _face_table(cells: np.ndarray):
    """Corner faces of all cells grouped by their node set.

    Returns
    -------
    group : (4 ne,) int64
        Group number of face ``4 c + f`` (face f of cell c, ``TET_FACES`` order).
    counts : (n_groups,) int64
        How many cells share each group's face (1 = boundary, 2 = interior).
    first : (n_groups,)
        Index ``4 c + f`` of one face of each group.
    """
    faces = np.sort(cells[:, TET_FACES].reshape(-1, 3), axis=1)
    order = np.lexsort(faces.T[::-1])
    sorted_faces = faces[order]
    new = np.ones(len(order), dtype=bool)
    new[1:] = (sorted_faces[1:] != sorted_faces[:-1]).any(axis=1)
    group_sorted = np.cumsum(new) - 1
    group = np.empty_like(group_sorted)
    group[order] = group_sorted
    counts = np.bincount(group_sorted)
    return group, counts, order[new]


def _boundary_face_rows(cells: np.ndarray) -> np.ndarray:
    """(nf,) indices ``4 c + f`` of the faces that belong to one cell only."""
    _, counts, first = _face_table(cells)
    return first[counts == 1]


def _corner_faces(cells: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """(len(rows), 3) corner nodes of the faces ``4 c + f``, outward for positive cells."""
    return np.take_along_axis(cells[rows // 4], TET_FACES[rows % 4], axis=1)


def boundary_faces(mesh: FEMesh) -> np.ndarray:
    """(nf, 3) int64 corner-node triangles of the outer surface, normals pointing outward.

    Faces that belong to exactly one tetrahedron; the node order follows ``TET_FACES`` of the
    positively oriented cell, so ``(x1 - x0) x (x2 - x0)`` points out of the body.
    """
    return _corner_faces(mesh.cells, _boundary_face_rows(mesh.cells))


def boundary_face_nodes(cells: np.ndarray) -> np.ndarray:
    """(nf, 3) or (nf, 6) nodes of the faces that belong to one cell only: the corners (outward
    order, ``TET_FACES``), then for tet10 the mid-edge nodes of the edges (0,1), (1,2), (2,0)."""
    rows = _boundary_face_rows(cells)
    local = TET_FACES[rows % 4]
    if cells.shape[1] == 10:
        edge_node = {frozenset(e): 4 + k for k, e in enumerate(TET10_EDGES)}
        face_mids = np.array(
            [[edge_node[frozenset((f[i], f[(i + 1) % 3]))] for i in range(3)] for f in TET_FACES]
        )
        local = np.hstack([local, face_mids[rows % 4]])
    return np.take_along_axis(cells[rows // 4], local, axis=1)


def surface_node_indices(mesh: FEMesh) -> np.ndarray:
    """Sorted indices of all nodes on the outer surface (corner and, for tet10, mid-edge nodes)."""
    return np.unique(boundary_face_nodes(mesh.cells))


def connected_parts(mesh: FEMesh) -> tuple[int, np.ndarray]:
    """Connected components of the mesh (through shared nodes of cells and the ties' constraints).

    Returns
    -------
    n_parts : int
    labels : (n_nodes,) int64
        Part number of each node (nodes used by no cell form parts of their own).
    """

    c = mesh.cells
    rows = np.repeat(c[:, 0], c.shape[1] - 1)
    cols = c[:, 1:].ravel()
    if mesh.ties is not None:                            # a tied node hangs on its master face's nodes
        rows = np.r_[rows, np.repeat(mesh.ties.slaves, mesh.ties.masters.shape[1])]
        cols = np.r_[cols, mesh.ties.masters.ravel()]
    n = mesh.n_nodes
    graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n))
    n_parts, labels = connected_components(graph, directed=False)
    return int(n_parts), labels.astype(np.int64)
