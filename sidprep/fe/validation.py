"""The checks and repairs of a mesh as read (``sidprep.fe.readers.RawMesh``): nodes on no
tetrahedron dropped, coordinates finite, duplicate nodes merged, cells re-oriented to positive
volume, tet10 mid-edge nodes on their own edges, no flat and no overlapping elements.

What cannot be repaired raises ``InputError`` naming the file's node or element numbers; each
repair adds a one-line note.
"""

from __future__ import annotations

import itertools
import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from sidprep.errors import InputError
from sidprep.fe.readers import RawMesh
from sidprep.fe.topology import TET10_EDGES, cell_volumes, corner_faces, face_table

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
#: re-ordering that reverses a cell's orientation (swap vertices 1 and 2 with their edges)
_FLIP = {4: np.array([0, 2, 1, 3]), 10: np.array([0, 2, 1, 3, 6, 5, 4, 7, 9, 8])}


def validated(raw: RawMesh, path) -> tuple[RawMesh, tuple[str, ...]]:
    """The mesh ``raw`` read from ``path`` checked and repaired (module docstring).

    Returns
    -------
    mesh : RawMesh
        Used nodes only, duplicates merged, every cell of positive volume; the sets mapped onto
        the kept nodes.
    notes : tuple of str
        One line per repair.
    """
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
    return RawMesh(points, node_ids, cells, raw.cell_ids, node_sets, dict(raw.cell_sets)), tuple(notes)


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
    _, counts, first = face_table(cells)
    if (counts > 2).any():
        raise InputError(
            f"{path}: {int((counts > 2).sum())} faces are shared by more than two elements "
            "(duplicate or overlapping elements); fix the mesh"
        )
    faces = corner_faces(cells, first[counts == 1])
    centre = points.mean(axis=0)
    x = points[faces] - centre
    enclosed = np.einsum("ij,ij->i", x[:, 0], np.cross(x[:, 1], x[:, 2])).sum() / 6
    total = cell_volumes(points, cells).sum()
    if abs(enclosed - total) > ENCLOSED_VOLUME_RTOL * total:
        raise InputError(
            f"{path}: element volumes add up to {total:.6g} but the boundary encloses "
            f"{enclosed:.6g} (overlapping or inverted elements); fix the mesh"
        )

