"""Topology of tetrahedral meshes: the edges and faces of one cell in the canonical node order, its
signed volume, the faces shared between cells, the outer surface and the connected parts.

Node order of a cell (the canonical order used everywhere in sidprep, = VTK / meshio):
tet4: vertices 0..3; tet10: vertices 0..3, then mid-edge nodes of the edges
(0,1), (1,2), (0,2), (0,3), (1,3), (2,3).
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

#: mid-edge node k (k = 4..9 of a tet10) lies on the edge between these two vertices
TET10_EDGES = ((0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3))
#: corner-node faces of a positively oriented tetrahedron, numbered so the normals point out
TET_FACES = np.array([(0, 2, 1), (0, 1, 3), (1, 2, 3), (0, 3, 2)])


def cell_volumes(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """(ne,) signed volumes of the straight tetrahedra spanned by the corner nodes (unit^3)."""
    x = points[cells[:, :4]]
    return np.einsum("ij,ij->i", np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), x[:, 3] - x[:, 0]) / 6


def face_table(cells: np.ndarray):
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
    _, counts, first = face_table(cells)
    return first[counts == 1]


def corner_faces(cells: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """(len(rows), 3) corner nodes of the faces ``4 c + f``, outward for positive cells."""
    return np.take_along_axis(cells[rows // 4], TET_FACES[rows % 4], axis=1)


def boundary_faces(mesh) -> np.ndarray:
    """(nf, 3) int64 corner-node triangles of the outer surface of an ``FEMesh``, normals pointing outward.

    Faces that belong to exactly one tetrahedron; the node order follows ``TET_FACES`` of the
    positively oriented cell, so ``(x1 - x0) x (x2 - x0)`` points out of the body.
    """
    return corner_faces(mesh.cells, _boundary_face_rows(mesh.cells))


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


def surface_node_indices(mesh) -> np.ndarray:
    """Sorted indices of all nodes on the outer surface of an ``FEMesh`` (corner and, for tet10,
    mid-edge nodes)."""
    return np.unique(boundary_face_nodes(mesh.cells))


def connected_parts(mesh) -> tuple[int, np.ndarray]:
    """Connected components of an ``FEMesh`` (through shared nodes of cells and the ties' constraints).

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
