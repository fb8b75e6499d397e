"""The meshes of an assembly's components joined into one FE mesh (sidprep.jobs.assembly).

Components are stacked (their node numbers offset so that they stay unique) and joined:

* **shared** node sets (``nodes = ["A.joint", "B.joint"]``): every node of one set coincides with
  one node of the other within ``tol``; each pair becomes one node (the first component's), as
  Nastran superelements share their boundary grid points;
* **tied** surfaces (``tied = "B.joint"``, ``to = "A.joint"``): every node of the first set is
  constrained to the nearest face of the second component's surface whose nodes all lie in the
  second set (sidprep.fe.ties: interpolation with the face's shape functions, a multipoint
  constraint); the meshes need not match.

Node sets and cell sets keep their names behind the component's (``A.joint``); every component is
a cell set of its own name.  Every problem is a one-line InputError naming the job file and the join.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix, csr_matrix
from scipy.sparse.csgraph import connected_components

from sidprep.errors import InputError
from sidprep.fe.mesh import FEMesh
from sidprep.fe.topology import boundary_face_nodes
from sidprep.fe.ties import Ties, tie_to_faces


#: default tolerance of a shared join: nodes closer than this fraction of the assembly's
#: bounding-box diagonal are the same node (the meshes' coordinates as written, ~7 digits)
SHARED_NODE_RTOL = 1e-6
#: default tolerance of a tied join: largest gap between a tied node and its face, as a fraction of
#: the bounding-box diagonal (curved surfaces meshed independently differ by ~h^2 / radius)
TIED_GAP_RTOL = 1e-3
#: nodes per chunk of the nearest-node search (memory: chunk x nodes x 8 bytes x ~4)
NEAREST_CHUNK = 512


@dataclass(frozen=True)
class Join:
    """How two components are joined (module docstring): ``nodes`` two node sets "COMPONENT.SET"
    that share their nodes, or ``tied`` a node set tied ``to`` another component's node set;
    ``tol`` : largest distance of a pair (shared) or gap (tied), in the job's length units
    (default SHARED_NODE_RTOL / TIED_GAP_RTOL x the assembly's bounding-box diagonal)."""

    nodes: tuple[str, ...] | None = None
    tied: str | None = None
    to: str | None = None
    tol: float | None = None

    @property
    def sets(self) -> tuple[str, str]:
        """The two node sets: (first, second) of ``nodes``, or (``tied``, ``to``)."""
        return tuple(self.nodes) if self.nodes is not None else (self.tied, self.to)

    def __str__(self) -> str:
        return f"join nodes = {list(self.nodes)}" if self.nodes is not None else \
            f"join tied = {self.tied!r} to = {self.to!r}"


def check_join_form(join: Join, where: str) -> None:
    """One of the two forms, completely: ``nodes = [A, B]`` or ``tied = A`` with ``to = B``."""
    if (join.nodes is None) == (join.tied is None and join.to is None):
        raise InputError(f"{where}: give nodes = [\"A.SET\", \"B.SET\"] (shared nodes) or tied = \"A.SET\" with "
                         "to = \"B.SET\" (a tied surface), not both or neither")
    if join.nodes is not None and len(join.nodes) != 2:
        raise InputError(f"{where}: nodes = {list(join.nodes)}: name two node sets, one of each component")
    if join.nodes is None and (join.tied is None or join.to is None):
        raise InputError(f"{where}: a tied join needs both tied = \"A.SET\" (the tied nodes) and to = \"B.SET\" "
                         "(the faces they follow)")
    if join.tol is not None and not join.tol > 0:
        raise InputError(f"{where}: tol = {join.tol}: must be > 0 (a length in the job's units)")


def stacked(meshes: list[FEMesh], names: list[str]) -> tuple[FEMesh, np.ndarray]:
    """The components side by side in one FEMesh (node ids offset to stay unique, sets prefixed
    "NAME.") and (ne,) the component of every cell."""

    if len({m.cells.shape[1] for m in meshes}) > 1:
        raise InputError("assembly: the components mix tet4 and tet10 cells; mesh them with one order (order = 2)")
    start = np.cumsum([0] + [m.n_nodes for m in meshes])
    id_offset = np.cumsum([0] + [int(m.node_ids.max()) if m.n_nodes else 0 for m in meshes])
    node_sets, cell_sets, first_cell = {}, {}, 0
    for m, name, s in zip(meshes, names, start):
        node_sets.update({f"{name}.{k}": v + s for k, v in m.node_sets.items()})
        cell_sets.update({f"{name}.{k}": v + first_cell for k, v in m.cell_sets.items()})
        cell_sets[name] = first_cell + np.arange(len(m.cells))
        first_cell += len(m.cells)
    mesh = FEMesh(points=np.vstack([m.points for m in meshes]),
                  cells=np.vstack([m.cells + s for m, s in zip(meshes, start)]),
                  node_ids=np.concatenate([m.node_ids + o for m, o in zip(meshes, id_offset)]),
                  node_sets=node_sets, cell_sets=cell_sets,
                  sha256=hashlib.sha256("".join(m.sha256 for m in meshes).encode()).hexdigest(),
                  notes=tuple(f"{name}: {n}" for m, name in zip(meshes, names) for n in m.notes))
    return mesh, np.repeat(np.arange(len(meshes)), [len(m.cells) for m in meshes])


def node_set(mesh: FEMesh, names: list[str], ref: str, where: str) -> tuple[int, np.ndarray]:
    """(component index, node indices) of "COMPONENT.SET"."""
    component, dot, _ = ref.partition(".")
    if not dot or component not in names:
        raise InputError(f"{where}: {ref!r}: expected COMPONENT.NODE_SET with COMPONENT one of {', '.join(names)}")
    if ref not in mesh.node_sets:
        valid = [k for k in mesh.node_sets if k.startswith(component + ".")]
        raise InputError(f"{where}: {ref!r}: component {component} has no such node set; valid: "
                         f"{', '.join(valid) or '(none: name the joint faces in its mesh)'}")
    return names.index(component), np.asarray(mesh.node_sets[ref], dtype=np.int64)


def nearest_nodes(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For every node of ``b``: the nearest node of ``a`` and its distance ((len(b),) each)."""
    near, dist = np.empty(len(b), dtype=np.int64), np.empty(len(b))
    for s in range(0, len(b), NEAREST_CHUNK):
        d = np.linalg.norm(points[b[s:s + NEAREST_CHUNK], None, :] - points[None, a, :], axis=-1)
        near[s:s + NEAREST_CHUNK], dist[s:s + NEAREST_CHUNK] = a[np.argmin(d, axis=1)], d.min(axis=1)
    return near, dist


def shared_pairs(points: np.ndarray, a: np.ndarray, b: np.ndarray, tol: float, where: str) -> np.ndarray:
    """(len(b), 2) pairs (node of b, its node of a): every node of each set within ``tol`` (m) of
    exactly one node of the other."""

    near_a, gap_b = nearest_nodes(points, a, b)
    near_b, gap_a = nearest_nodes(points, b, a)
    if not (gap_b <= tol).any():
        raise InputError(f"{where}: matches no nodes: the nearest nodes of the two sets are {gap_b.min():.3g} m apart "
                         f"(tol {tol:.3g} m); check the node sets, the units, or use a tied join for a gap")
    for gap, count, other in ((gap_b, len(b), 0), (gap_a, len(a), 1)):
        off = gap > tol
        if off.any():
            raise InputError(f"{where}: {int(off.sum())} of the {count} nodes of the {('second', 'first')[other]} set "
                             f"have no node of the other within tol = {tol:.3g} m (largest gap {gap.max():.3g} m): the "
                             "meshes do not match at the joint; use a tied join (tied = ..., to = ...) or raise tol")
    if len(a) != len(b) or len(np.unique(near_a)) != len(b):
        raise InputError(f"{where}: the sets pair up {len(a)} with {len(b)} nodes, not one to one: nodes of one set "
                         f"lie within tol = {tol:.3g} m of each other; lower tol")
    return np.stack([b, near_a], axis=1)


def merged(mesh: FEMesh, pairs: np.ndarray) -> tuple[FEMesh, np.ndarray]:
    """Every pair of nodes (chains too) made one node: the lowest index of each group, nodes renumbered
    in their order; and (n,) the new node of every old one."""

    n = mesh.n_nodes
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, group = connected_components(graph, directed=False)
    first = np.full(group.max() + 1, n)
    np.minimum.at(first, group, np.arange(n))
    keep = np.zeros(n, bool)
    keep[first] = True
    new = np.cumsum(keep) - 1
    to = new[first[group]]                                # old node -> new node
    sets = {k: np.unique(to[v]) for k, v in mesh.node_sets.items()}
    return FEMesh(points=mesh.points[keep], cells=to[mesh.cells], node_ids=mesh.node_ids[keep], node_sets=sets,
                  cell_sets=mesh.cell_sets, source=mesh.source, sha256=mesh.sha256, notes=mesh.notes), to


def tied_nodes(mesh: FEMesh, labels: np.ndarray, master: int, slaves: np.ndarray, masters: np.ndarray,
               tol: float, where: str) -> Ties:
    """The constraints of a tied join: every node of ``slaves`` on the nearest boundary face of
    component ``master`` whose nodes all lie in ``masters``."""

    faces = boundary_face_nodes(mesh.cells[labels == master])
    faces = faces[np.isin(faces, masters).all(axis=1)]
    if not len(faces):
        raise InputError(f"{where}: the node set 'to' holds no complete face of its component's surface; name the "
                         "joint's surface nodes (all nodes of its faces) in that set")
    ties, gap = tie_to_faces(mesh.points, slaves, faces)
    off = gap > tol
    if off.all():
        raise InputError(f"{where}: matches no nodes: the tied nodes are {gap.min():.3g} m or more from the faces "
                         f"(tol {tol:.3g} m); check the node sets and the units")
    if off.any():
        raise InputError(f"{where}: {int(off.sum())} of the {len(slaves)} tied nodes are farther than tol = {tol:.3g} m "
                         f"from the faces (largest gap {gap.max():.3g} m); the surfaces do not touch there: shrink the "
                         "tied node set to the joint or raise tol")
    return ties


def embedded(A, nodes: np.ndarray, n_nodes: int, per_node: int = 3):
    """A component's matrix A (per_node n_c square) on the joined mesh's DOFs (per_node n_nodes square),
    its node i being joined node ``nodes[i]`` (merged nodes add up)."""
    rows = (per_node * np.asarray(nodes)[:, None] + np.arange(per_node)).ravel()
    P = csr_matrix((np.ones(len(rows)), (rows, np.arange(len(rows)))), shape=(per_node * n_nodes, len(rows)))
    return (P @ A @ P.T).tocsr()


def check_connected(names: list[str], edges: list[tuple[int, int]], source) -> None:
    """Every component joined to the first, directly or through others (a floating component would
    add rigid-body motions of its own to one body)."""
    n = len(names)
    graph = coo_matrix((np.ones(len(edges)), tuple(np.array(edges, dtype=np.int64).reshape(-1, 2).T)), shape=(n, n))
    _, group = connected_components(graph, directed=False)
    loose = [names[c] for c in range(n) if group[c] != group[0]]
    if loose:
        raise InputError(f"{source}: component(s) {', '.join(loose)} joined to nothing that reaches {names[0]}: a "
                         "floating component; add a [[join]] (nodes = [...] or tied = ..., to = ...) for each")


def joined_mesh(meshes: list[FEMesh], names: list[str], joins: list[Join], source,
                length_to_m: float = 1.0) -> tuple[FEMesh, np.ndarray, list[np.ndarray]]:
    """One FEMesh of the joined components (module docstring), (ne,) the component of every cell and
    per component (n_c,) the joined mesh's node of each of its nodes; join tolerances are in the
    job's length units (``length_to_m`` m each)."""

    mesh, labels = stacked(meshes, names)
    to = np.arange(mesh.n_nodes)
    diagonal = float(np.linalg.norm(np.ptp(mesh.points, axis=0)))
    resolved, edges = [], []
    for k, join in enumerate(joins):
        where = f"{source}: [[join]] {k + 1} ({join})"
        (ca, a), (cb, b) = (node_set(mesh, names, ref, where) for ref in join.sets)
        if ca == cb:
            raise InputError(f"{where}: both node sets belong to component {names[ca]}; a join joins two components")
        default = SHARED_NODE_RTOL if join.nodes is not None else TIED_GAP_RTOL
        tol = join.tol * length_to_m if join.tol is not None else default * diagonal
        resolved.append((join, where, a, b, cb, tol))
        edges.append((ca, cb))
    check_connected(names, edges, source)
    shared = [shared_pairs(mesh.points, a, b, tol, where) for join, where, a, b, _, tol in resolved if join.nodes]
    if shared:
        mesh, to = merged(mesh, np.vstack(shared))
    ties = [tied_nodes(mesh, labels, cb, mesh.node_sets[join.tied], mesh.node_sets[join.to], tol, where)
            for join, where, _, _, cb, tol in resolved if join.nodes is None]
    return FEMesh(points=mesh.points, cells=mesh.cells, node_ids=mesh.node_ids, node_sets=mesh.node_sets,
                  cell_sets=mesh.cell_sets, source=str(source), sha256=mesh.sha256, notes=mesh.notes,
                  ties=Ties.joined(ties)), labels, np.split(to, np.cumsum([m.n_nodes for m in meshes])[:-1])
