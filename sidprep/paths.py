"""Paths through a meshed body, along which loads move (issue: moving loads, seed 003).

A path is a straight segment from a to b in the body frame K (the mesh coordinates), sampled at
n points; at each point the full-resolution mode shapes are interpolated with the element's own
shape functions (P1 / P2 on straight-sided tetrahedra, barycentric coordinates L):

    phi(x) = sum_i N_i(L(x)) Phi_i,       psi(x) = 1/2 curl phi(x)

(corner nodes N = L_a (2 L_a - 1), mid-edge nodes N = 4 L_a L_b for tet10; N = L_a for tet4),
psi the small rotation of the material at x.  The result is a ``sidprep.sid.BodyPath`` stored in
the SID (``SID.paths``, HDF5 ``/paths``).
"""

from __future__ import annotations

import numpy as np

from sidprep.errors import InputError
from sidprep.mesh import TET10_EDGES
from sidprep.sid import BodyPath

#: samples of a path unless the spec gives their number
DEFAULT_PATH_POINTS = 201
#: a point belongs to an element when its barycentric coordinates are >= -this
INSIDE_TOL = 1e-9


def parse_path(spec: str) -> tuple[str, np.ndarray, np.ndarray, int]:
    """'NAME:x0,y0,z0:x1,y1,z1[:n]' -> (name, a (3,), b (3,), n); InputError otherwise."""
    parts = str(spec).split(":")
    try:
        if len(parts) not in (3, 4) or not parts[0]:
            raise ValueError("needs NAME:x0,y0,z0:x1,y1,z1[:n]")
        a, b = (np.array([float(v) for v in p.split(",")]) for p in parts[1:3])
        n = int(parts[3]) if len(parts) == 4 else DEFAULT_PATH_POINTS
        if a.shape != (3,) or b.shape != (3,) or n < 2 or np.linalg.norm(b - a) == 0.0:
            raise ValueError("needs two different points of 3 coordinates and n >= 2")
    except ValueError as exc:
        raise InputError(f"path {spec!r}: {exc}; write e.g. --path axis:0,0.025,0.04:1,0.025,0.04") from None
    return parts[0], a, b, n


def barycentric(mesh, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(element (n,), L (n, 4)) of the straight-sided tetrahedron holding each point x (n, 3);
    element -1 for points outside the mesh."""
    corners = mesh.points[mesh.cells[:, :4]]                           # (ne, 4, 3)
    T = (corners[:, 1:] - corners[:, :1]).transpose(0, 2, 1)          # (ne, 3, 3)
    Tinv = np.linalg.inv(T)
    element, L = np.full(len(x), -1), np.zeros((len(x), 4))
    for k, p in enumerate(x):
        l123 = np.einsum("eij,ej->ei", Tinv, p - corners[:, 0])
        lam = np.concatenate([1.0 - l123.sum(axis=1, keepdims=True), l123], axis=1)
        inside = np.flatnonzero(lam.min(axis=1) >= -INSIDE_TOL)
        if inside.size:
            best = inside[np.argmax(lam[inside].min(axis=1))]
            element[k], L[k] = best, lam[best]
    return element, L


def shape_functions(L: np.ndarray, order: int, gradL: np.ndarray):
    """Values N (nn,) and gradients dN (nn, 3) of the element's nodal shape functions at the
    barycentric coordinates L (4,), with gradL (4, 3) the gradients of L."""
    if order == 1:
        return L.copy(), gradL.copy()
    N, dN = np.zeros(10), np.zeros((10, 3))
    for a in range(4):
        N[a], dN[a] = L[a] * (2 * L[a] - 1), (4 * L[a] - 1) * gradL[a]
    for k, (a, b) in enumerate(TET10_EDGES):
        N[4 + k], dN[4 + k] = 4 * L[a] * L[b], 4 * (L[a] * gradL[b] + L[b] * gradL[a])
    return N, dN


def fe_path(mesh, Phi_fe: np.ndarray, a, b, n: int, name: str = "path") -> BodyPath:
    """The BodyPath of the segment a -> b (m, K) through ``mesh`` with the full mode shapes
    Phi_fe (3 n_nodes, nq) (module doc); InputError when a sample lies outside the mesh."""
    s = np.linspace(0.0, float(np.linalg.norm(np.asarray(b) - np.asarray(a))), n)
    x = np.asarray(a, float) + np.outer(s / s[-1], np.asarray(b, float) - np.asarray(a, float))
    element, L = barycentric(mesh, x)
    if (element < 0).any():
        bad = x[np.argmax(element < 0)]
        raise InputError(f"path {name!r}: the point ({bad[0]:.6g}, {bad[1]:.6g}, {bad[2]:.6g}) m lies outside the "
                         "mesh; give a segment inside the body")
    nq = Phi_fe.shape[1]
    shapes = Phi_fe.reshape(mesh.n_nodes, 3, nq)
    phi, psi = np.zeros((n, 3, nq)), np.zeros((n, 3, nq))
    for k in range(n):
        nodes = mesh.cells[element[k]]
        corners = mesh.points[nodes[:4]]
        T = (corners[1:] - corners[:1]).T
        g123 = np.linalg.inv(T)                                        # rows: grad L1..L3
        gradL = np.vstack([-g123.sum(axis=0), g123])
        N, dN = shape_functions(L[k], mesh.order, gradL)
        u = shapes[nodes]                                              # (nn, 3, nq)
        phi[k] = np.einsum("i,icq->cq", N, u)
        grad = np.einsum("icq,id->cdq", u, dN)                         # d u_c / d x_d
        psi[k] = 0.5 * np.stack([grad[2, 1] - grad[1, 2], grad[0, 2] - grad[2, 0], grad[1, 0] - grad[0, 1]])
    return BodyPath(s, x, phi, psi)
