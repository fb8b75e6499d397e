"""Tied surfaces: multipoint constraints that glue the nodes of one surface to the faces of another.

A tied node s (a "slave", as Abaqus *TIE and Nastran's glued contact call it) follows the face of
the other surface nearest to it, interpolated with that face's own shape functions at the closest
point on the face (barycentric coordinates l of the corner triangle):

    u_s = sum_k N_k(l) u_k,    tri3: N_k = l_k;    tri6: N_k = l_k (2 l_k - 1) (corners),
                                                         4 l_i l_j (mid-edge node of edge i-j)

so a tied node on a master node follows it exactly, and a tie of coincident meshes is the shared
node.  The constraints are one sparse map of FE DOFs (``tie_map``) that the interface model
(sidprep.reduction.interfaces.tied_interface_model) composes with its own.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp


#: slave nodes per chunk of the nearest-face search (memory: chunk x faces x 3 x 8 bytes x ~10)
TIE_CHUNK = 256


@dataclass(frozen=True)
class Ties:
    """Multipoint constraints u_s = sum_k w_sk u_(m_sk).

    slaves : (k,) int64 node indices; masters : (k, m) int64 the nodes of each slave's face
    (m = 3 for tet4 faces, 6 for tet10 faces); weights : (k, m) their shape-function values.
    """

    slaves: np.ndarray
    masters: np.ndarray
    weights: np.ndarray

    def dependent_dofs(self) -> np.ndarray:
        """(3k,) the tied nodes' DOFs 3 s + c."""
        return (3 * self.slaves[:, None] + np.arange(3)).ravel()

    def dof_map(self, n_nodes: int) -> sp.csr_matrix:
        """The (3n, 3n) map of FE DOFs u = S u (:func:`tie_map`)."""
        return tie_map(self, n_nodes)

    @staticmethod
    def joined(ties: list["Ties"]) -> "Ties | None":
        """All constraints of ``ties`` in one (None for none)."""
        if not ties:
            return None
        return Ties(*(np.concatenate([getattr(t, f) for t in ties]) for f in ("slaves", "masters", "weights")))


def closest_points_on_triangles(x: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray):
    """Closest point of every triangle (a, b, c) to every point x: barycentric coordinates
    (k, f, 3) and distances (k, f); x (k, 3), a, b, c (f, 3).  The plane projection when it lies
    inside the triangle, else the closest point of its three edges."""

    corners = (a, b, c)
    e1, e2 = b - a, c - a
    n = np.cross(e1, e2)
    d = x[:, None, :] - a[None]
    # barycentric coordinates of the plane projection: solve [e1 e2] (l1, l2) = d_projected
    g11, g12, g22 = (e1 * e1).sum(-1), (e1 * e2).sum(-1), (e2 * e2).sum(-1)
    det = g11 * g22 - g12 ** 2
    r1, r2 = (d * e1[None]).sum(-1), (d * e2[None]).sum(-1)
    l1, l2 = (g22 * r1 - g12 * r2) / det, (g11 * r2 - g12 * r1) / det
    best_l = np.stack([1 - l1 - l2, l1, l2], axis=-1)
    inside = (best_l >= 0).all(-1)
    unit_n = n / np.linalg.norm(n, axis=-1, keepdims=True)
    best_d = np.where(inside, np.abs((d * unit_n[None]).sum(-1)), np.inf)
    for i, j in ((0, 1), (1, 2), (2, 0)):
        p, q = corners[i], corners[j]
        t = np.clip(((x[:, None, :] - p[None]) * (q - p)[None]).sum(-1) / ((q - p) ** 2).sum(-1), 0.0, 1.0)
        dist = np.linalg.norm(x[:, None, :] - (p[None] + t[..., None] * (q - p)[None]), axis=-1)
        better = dist < best_d
        edge_l = np.zeros(best_l.shape)
        edge_l[..., i], edge_l[..., j] = 1 - t, t
        best_l = np.where(better[..., None], edge_l, best_l)
        best_d = np.where(better, dist, best_d)
    return best_l, best_d


def face_shape_functions(l: np.ndarray, n_face_nodes: int) -> np.ndarray:
    """(k, 3) barycentric coordinates -> (k, n_face_nodes) shape functions of the 3- or 6-node
    triangle (corners, then the mid-edge nodes of edges 0-1, 1-2, 2-0; module docstring)."""
    if n_face_nodes == 3:
        return l
    mids = np.stack([4 * l[:, 0] * l[:, 1], 4 * l[:, 1] * l[:, 2], 4 * l[:, 2] * l[:, 0]], axis=1)
    return np.hstack([l * (2 * l - 1), mids])


def tie_to_faces(points: np.ndarray, slaves: np.ndarray, faces: np.ndarray) -> tuple[Ties, np.ndarray]:
    """Each slave node tied to its nearest face: (Ties, (k,) gap from node to face, m).

    points (n, 3) m; slaves (k,) node indices; faces (f, 3 | 6) face nodes (corners first)."""

    a, b, c = (points[faces[:, i]] for i in range(3))
    masters = np.empty((len(slaves), faces.shape[1]), dtype=np.int64)
    weights = np.empty(masters.shape)
    gap = np.empty(len(slaves))
    for start in range(0, len(slaves), TIE_CHUNK):
        s = slaves[start:start + TIE_CHUNK]
        l, d = closest_points_on_triangles(points[s], a, b, c)
        best = np.argmin(d, axis=1)
        rows = np.arange(len(s))
        masters[start:start + len(s)] = faces[best]
        weights[start:start + len(s)] = face_shape_functions(l[rows, best], faces.shape[1])
        gap[start:start + len(s)] = d[rows, best]
    return Ties(np.asarray(slaves, dtype=np.int64), masters, weights), gap


def tie_map(ties: Ties, n_nodes: int) -> sp.csr_matrix:
    """(3n, 3n) map S of FE DOFs: identity, except the rows of the tied nodes' DOFs, which hold the
    constraint weights on their masters' DOFs (u = S u reproduces u on free nodes and imposes the
    constraints on tied ones)."""

    n_dof = 3 * n_nodes
    free = np.ones(n_dof, bool)
    tied = (3 * ties.slaves[:, None] + np.arange(3)).ravel()
    free[tied] = False
    keep = np.flatnonzero(free)
    m = ties.masters.shape[1]
    rows = np.repeat(tied, m)                                         # (k, 3, m) order
    cols = (3 * np.repeat(ties.masters[:, None, :], 3, axis=1) + np.arange(3)[None, :, None]).ravel()
    vals = np.repeat(ties.weights[:, None, :], 3, axis=1).ravel()
    return sp.csr_matrix((np.r_[np.ones(len(keep)), vals], (np.r_[keep, rows], np.r_[keep, cols])),
                         shape=(n_dof, n_dof))


def untied_triangles(triangles: np.ndarray, ties: Ties) -> np.ndarray:
    """The surface ``triangles`` (nt, 3) without those of the tied joints, now inside the body: the
    triangles whose nodes are all tied nodes, or all nodes of the faces the tied nodes follow."""
    tied = np.zeros(int(max(triangles.max(initial=0), ties.masters.max(initial=0), ties.slaves.max(initial=0))) + 1, bool)
    under = tied.copy()
    tied[ties.slaves] = True
    under[ties.masters.ravel()] = True
    return triangles[~(tied[triangles].all(axis=1) | under[triangles].all(axis=1))]
