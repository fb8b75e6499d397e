"""The gmsh reader: ``.msh`` files (2.2 / 4.x, ASCII or binary) and geometry files (``.geo``, STEP,
BREP, IGES) meshed with tetrahedra, both through the gmsh API, in a quiet session of their own.

Files that crash gmsh's own reader (the process, not with an error) are refused before gmsh reads
them: their ``$Elements`` section is counted here first (``msh_volume_types``,
``msh2_undefined_node``).
"""

from __future__ import annotations

import contextlib
import re
import signal
import struct

import numpy as np

from sidprep.errors import InputError
from sidprep.fe.readers import RawMesh

#: files meshed through the gmsh API (geometry); ``.msh`` is read through the gmsh API too
GEOMETRY_SUFFIXES = (".geo", ".step", ".stp", ".brep", ".brp", ".iges", ".igs")
#: geometry formats that carry their length unit: read_mesh returns them in metres
UNIT_CARRYING_SUFFIXES = (".step", ".stp", ".iges", ".igs")
#: gmsh element type numbers of the linear and quadratic tetrahedron
_GMSH_TET = (4, 11)
#: gmsh tet10 node k -> canonical node: gmsh numbers the last two edges (2,3), (1,3)
_GMSH_TET10_TO_CANONICAL = np.array([0, 1, 2, 3, 4, 5, 6, 7, 9, 8])


def read_gmsh(path, *, size, order) -> RawMesh:
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


def _gmsh_arrays(gmsh, path) -> RawMesh:
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
    return RawMesh(points, node_tags, cells, cell_ids, node_sets, cell_sets)


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
        _python_signals()
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


def _python_signals() -> None:
    """Give SIGPIPE, SIGINT and SIGTERM back the dispositions Python gave them: gmsh.initialize
    resets them in C.  SIGPIPE ignored (writes to a closed pipe raise BrokenPipeError): else a later
    write to a pipe whose reader died (a killed pool worker, sidprep.jobs.parts) ended the process
    silently with exit 141; SIGINT / SIGTERM to Python's handlers (KeyboardInterrupt,
    sidprep.errors.Terminated): else a signal while the outputs were written killed the process
    before it removed its temporary files."""
    for signum in (signal.SIGPIPE, signal.SIGINT, signal.SIGTERM):
        handler = signal.getsignal(signum)
        with contextlib.suppress(ValueError, TypeError):      # not the main thread / a handler set in C
            signal.signal(signum, handler)


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
