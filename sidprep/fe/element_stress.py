"""Nodal stresses of an FE deck's own solid elements, recovered the way CalculiX recovers them.

For each element the strain of a displacement field is evaluated at the element's integration
points from its own isoparametric shape functions (H = sum_b u_b (x) grad N_b, eps = (H + H^T) / 2),
the stress by isotropic Hooke with the element's material, sigma = lambda tr(eps) I + 2 mu eps,
and the integration-point values are extrapolated to the element's nodes; the values of all
elements sharing a node are averaged without weights (whatever their material).  This is
CalculiX's nodal stress (``*NODE FILE``/``*EL FILE``, S; src/extrapolate.f):

* C3D8 and C3D20R: 2 x 2 x 2 Gauss points, trilinear extrapolation to the corners (the C3D8
  functions through the Gauss points), mid-edge nodes the mean of their edge's corners;
* C3D20: 3 x 3 x 3 Gauss points, least-squares fit of the 20-node functions to the 27 values
  (CalculiX's matrix a27 is that pseudo-inverse to its 5 printed digits);
* C3D10: Keast's 4-point rule, linear extrapolation to the corners, mid-edge nodes averaged;
* C3D8R and C3D4: one point at the centre, the same stress at every node.

In all cases the extrapolation is E = C pinv(N_f(xi_g)): N_f the functions of the fitted
(corner or full) node set at the Gauss points xi_g, C the map of the fitted nodes to all nodes.
Shape functions in the Abaqus / CalculiX node order: the trilinear and serendipity hexahedra of
Zienkiewicz, Taylor & Zhu (2013, chapter 6), as in Dhondt's CalculiX CrunchiX User's Manual
(section 6.2, element types) and src/shape8h.f, shape20h.f; the tetrahedra of sidprep.fe.assemble
(C3D10 order = sidprep's tet10 order).
Components in sidprep.sid.stress.STRESS_ORDER (xx yy zz xy yz zx), Pa.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from sidprep.errors import InputError
from sidprep.fe.assemble import quadrature_rule, shape_functions, shape_gradients
from sidprep.fe.topology import TET10_EDGES

#: reference coordinates of the 8 corners of a hexahedron, Abaqus / CalculiX order
HEX_CORNERS = np.array([(-1, -1, -1), (1, -1, -1), (1, 1, -1), (-1, 1, -1),
                        (-1, -1, 1), (1, -1, 1), (1, 1, 1), (-1, 1, 1)], dtype=float)
#: corner pairs of the mid-edge nodes 9-20 of a C3D20 (0-based)
HEX20_EDGES = ((0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4), (0, 4), (1, 5), (2, 6), (3, 7))
#: the 20 nodes of a C3D20 in reference coordinates
HEX20_NODES = np.vstack([HEX_CORNERS, [(HEX_CORNERS[a] + HEX_CORNERS[b]) / 2 for a, b in HEX20_EDGES]])
#: corner nodes of the faces of a hexahedron and of a tetrahedron (Abaqus / CalculiX order)
HEX_FACES = ((0, 1, 2, 3), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7))
TET_FACES = ((0, 1, 2), (0, 1, 3), (1, 2, 3), (0, 2, 3))
#: elements per batch (temporaries ~ CHUNK * 27 * 20 * 3 * nc * 8 bytes)
CHUNK = 256
#: element types evaluated here (CalculiX names); the others are refused by name
SUPPORTED = ("C3D4", "C3D10", "C3D8", "C3D8R", "C3D20", "C3D20R")
METHOD = ("the deck's elements and materials: stress at the integration points, extrapolated to the "
          "nodes and averaged over the elements sharing a node (CalculiX's nodal stress)")


def hex_shape(nodes: np.ndarray, xi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Values and reference gradients of the 8-node trilinear or 20-node serendipity hexahedron.

    nodes : (8, 3) or (20, 3) reference coordinates of the nodes (HEX_CORNERS, HEX20_NODES);
    xi : (nq, 3) points.  Returns N (nq, nn) and dN (nq, nn, 3) = dN_a / dxi_k.
    Corner a: N = prod_k (1 + a_k xi_k) / 8 (8 nodes), times (sum_k a_k xi_k - 2) (20 nodes);
    mid-edge node with a_d = 0: N = (1 - xi_d^2) prod_{k != d} (1 + a_k xi_k) / 4.
    """
    a = nodes[None]                                            # (1, nn, 3)
    x = xi[:, None, :]                                         # (nq, 1, 3)
    mid = a == 0
    f = np.where(mid, 1 - x ** 2, 1 + a * x)                   # (nq, nn, 3) one factor per direction
    df = np.where(mid, -2 * x, a)
    prod = f.prod(axis=2)
    dprod = np.stack([df[..., 0] * f[..., 1] * f[..., 2], f[..., 0] * df[..., 1] * f[..., 2],
                      f[..., 0] * f[..., 1] * df[..., 2]], axis=2)
    if len(nodes) == 8:
        return prod / 8, dprod / 8
    corner = ~mid.any(axis=2)                                  # (1, nn)
    s = (a * x).sum(axis=2) - 2
    N = np.where(corner, prod * s / 8, prod / 4)
    dN = np.where(corner[..., None], (dprod * s[..., None] + prod[..., None] * a) / 8, dprod / 4)
    return N, dN


def gauss_hex(n: int) -> np.ndarray:
    """(n^3, 3) Gauss-Legendre points of the cube [-1, 1]^3, n = 1, 2 or 3."""
    g = np.polynomial.legendre.leggauss(n)[0]
    return np.array([(x, y, z) for z in g for y in g for x in g])


def midedge_map(n_corners: int, edges) -> np.ndarray:
    """(n_corners + len(edges), n_corners): corners kept, each mid-edge node the mean of its corners."""
    C = np.vstack([np.eye(n_corners), np.zeros((len(edges), n_corners))])
    for k, (i, j) in enumerate(edges):
        C[n_corners + k, [i, j]] = 0.5
    return C


@dataclass(frozen=True)
class ElementRule:
    """Stress recovery of one element type: dN (ng, nn, 3) reference gradients at the ng
    integration points, E (nn, ng) the extrapolation of integration-point values to the nodes."""

    dN: np.ndarray
    E: np.ndarray


def element_rule(kind: str) -> ElementRule:
    """The ElementRule of a CalculiX element type (SUPPORTED; module docstring)."""
    if kind in ("C3D4", "C3D10"):
        # the linear functions at the rule's points are the points' barycentric coordinates
        corners = np.full((1, 4), 0.25) if kind == "C3D4" else quadrature_rule(1, 2)[0]    # (ng, 4)
        _, dN = shape_functions(1 if kind == "C3D4" else 2, corners[:, 1:].T)
        C = np.eye(4) if kind == "C3D4" else midedge_map(4, TET10_EDGES)
        return ElementRule(dN, C @ np.linalg.pinv(corners))
    points = gauss_hex({"C3D8R": 1, "C3D8": 2, "C3D20R": 2, "C3D20": 3}[kind])
    nodes = HEX20_NODES if kind.startswith("C3D20") else HEX_CORNERS
    _, dN = hex_shape(nodes, points)
    if kind == "C3D20":
        fitted, C = hex_shape(HEX20_NODES, points)[0], np.eye(20)
    else:
        fitted = hex_shape(HEX_CORNERS, points)[0]
        C = midedge_map(8, HEX20_EDGES) if kind == "C3D20R" else np.eye(8)
    return ElementRule(dN, C @ np.linalg.pinv(fitted))


def hooke(H: np.ndarray, lam, mu) -> np.ndarray:
    """Isotropic Hooke stress of displacement gradients: sigma = lambda tr(eps) I + 2 mu eps,
    eps = (H + H^T) / 2.  H : (..., 3, 3, nc) with H[..., i, j, :] = du_i/dx_j; lam, mu : Pa,
    scalars or arrays broadcasting against H[..., 0, 0, :].  Returns (..., 6, nc) in STRESS_ORDER."""
    trace = H[..., 0, 0, :] + H[..., 1, 1, :] + H[..., 2, 2, :]
    return np.stack([lam * trace + 2 * mu * H[..., 0, 0, :], lam * trace + 2 * mu * H[..., 1, 1, :],
                     lam * trace + 2 * mu * H[..., 2, 2, :], mu * (H[..., 0, 1, :] + H[..., 1, 0, :]),
                     mu * (H[..., 1, 2, :] + H[..., 2, 1, :]), mu * (H[..., 2, 0, :] + H[..., 0, 2, :])], axis=-2)


@dataclass(frozen=True)
class ElementBlock:
    """Elements of one type: kind (SUPPORTED), rows (ne, nn) model node rows in the deck's node
    order, lame (ne, 2) each element's (lambda, mu) in Pa, numbers (ne,) the deck's element numbers."""

    kind: str
    rows: np.ndarray
    lame: np.ndarray
    numbers: np.ndarray


@dataclass(frozen=True)
class DeckStress:
    """The stress recovery of a deck: its solid element blocks (module docstring)."""

    blocks: tuple[ElementBlock, ...]
    source: str = ""
    method: str = METHOD

    def surface_nodes(self) -> np.ndarray:
        """Sorted rows of the nodes on the outer faces of the elements (mid-edge nodes included)."""
        return outer_face_rows(self.blocks)

    def nodal_stress(self, points: np.ndarray, U: np.ndarray, nodes: np.ndarray) -> np.ndarray:
        """Averaged nodal stress of displacement fields at chosen nodes.

        points : (n, 3) node coordinates, m; U : (3 n', nc) fields, DOF 3 i + c (n' >= n: rotation
        nodes after the solid ones carry no element), m; nodes : (ns,) node rows.
        Returns (ns, 6, nc), Pa; only the elements that touch a chosen node are evaluated.
        """
        nodes = np.asarray(nodes, dtype=np.int64)
        nc = U.shape[1]
        U3 = np.asarray(U).reshape(-1, 3, nc)
        row = np.full(len(U3), -1, dtype=np.int64)
        row[nodes] = np.arange(len(nodes))
        total = np.zeros((len(nodes), 6 * nc))
        count = np.zeros(len(nodes))
        for block in self.blocks:
            rule = element_rule(block.kind)
            chosen = np.flatnonzero((row[block.rows] >= 0).any(axis=1))
            for start in range(0, len(chosen), CHUNK):
                e = chosen[start:start + CHUNK]
                cells = block.rows[e]
                try:
                    s = block_nodal_stress(rule, points[cells], U3[cells], block.lame[e])
                except InputError:
                    raise InputError(f"{self.source}: a {block.kind} element among numbers {block.numbers[e].min()}-"
                                     f"{block.numbers[e].max()} has a non-positive Jacobian at an integration point; "
                                     "fix its node order or mid-edge node positions") from None
                add_to_nodes(total, count, row[cells], s)
        return (total / np.maximum(count, 1)[:, None]).reshape(len(nodes), 6, nc)


def face_nodes(kind: str) -> tuple[int, list[np.ndarray]]:
    """(corners per face k, [node positions of each face of an element type: its k corners, then
    for quadratic types the mid-edge nodes of its edges])."""
    tet = kind in ("C3D4", "C3D10")
    faces, edges, corners = (TET_FACES, TET10_EDGES, 4) if tet else (HEX_FACES, HEX20_EDGES, 8)
    mid = {frozenset(e): corners + n for n, e in enumerate(edges)}
    quadratic = kind in ("C3D10", "C3D20", "C3D20R")
    return len(faces[0]), [np.array(list(f) + ([mid[frozenset((f[i], f[i - 1]))] for i in range(len(f))]
                                               if quadratic else [])) for f in faces]


def outer_face_rows(blocks) -> np.ndarray:
    """Sorted node rows of the faces that belong to one element only (the outer surface, with the
    mid-edge nodes of quadratic elements); faces are matched by their corner nodes."""
    keys, nodes = {}, {}
    for block in blocks:
        k, faces = face_nodes(block.kind)
        for f in faces:
            keys.setdefault(k, []).append(np.sort(block.rows[:, f[:k]], axis=1))
            nodes.setdefault(k, []).append(block.rows[:, f])
    out = [np.zeros(0, np.int64)]
    for k, corners in keys.items():
        _, inverse, counts = np.unique(np.concatenate(corners), axis=0, return_inverse=True, return_counts=True)
        outer = np.split(counts[inverse.ravel()] == 1, np.cumsum([len(a) for a in nodes[k]])[:-1])
        out += [a[once].ravel() for a, once in zip(nodes[k], outer)]
    return np.unique(np.concatenate(out))


def add_to_nodes(total: np.ndarray, count: np.ndarray, rows: np.ndarray, values: np.ndarray) -> None:
    """Sum element-node values into node rows (in place), for the unweighted nodal average.

    total : (ns, m) sums; count : (ns,) contributions per node; rows : (ne, nn) the row of each
    element node in ``total`` (-1: not kept); values : (ne, nn, ...) with m entries per element node.
    """
    r = rows.ravel()
    keep = r >= 0
    scatter = sp.csr_matrix((np.ones(keep.sum()), (r[keep], np.flatnonzero(keep))), shape=(len(total), r.size))
    total += scatter @ values.reshape(r.size, -1)
    count += np.bincount(r[keep], minlength=len(total))


def block_nodal_stress(rule: ElementRule, X: np.ndarray, Ue: np.ndarray, lame: np.ndarray) -> np.ndarray:
    """Extrapolated nodal stress of elements of one type.

    X : (ne, nn, 3) node coordinates, m; Ue : (ne, nn, 3, nc) nodal displacements, m;
    lame : (ne, 2) Pa.  InputError on a non-positive Jacobian.
    Returns (ne, nn, 6, nc), Pa.
    """
    G, _ = shape_gradients(X, rule.dN, np.ones(rule.dN.shape[0]), 0)   # (ne, ng, nn, 3)
    H = np.einsum("ebik,egbj->egijk", Ue, G, optimize=True)                    # du_i/dx_j at point g
    sigma = hooke(H, lame[:, None, 0, None], lame[:, None, 1, None])           # (ne, ng, 6, nc)
    return np.einsum("ag,egck->eack", rule.E, sigma, optimize=True)
