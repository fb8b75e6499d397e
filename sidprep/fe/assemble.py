"""Stiffness and mass matrices of tet4 (P1) / tet10 (P2) meshes, vectorised over elements.

Isoparametric elements: the geometry is interpolated with the element's own shape functions,
so curved tet10 edges (mid-edge nodes off the midpoints) are integrated on the true shape.
Element matrices are computed for all elements at once (numpy batched products), then summed
into a node-block sparsity pattern computed once from the connectivity (no per-element loop).

Shape functions (reference tet with vertices (0,0,0), (1,0,0), (0,1,0), (0,0,1), barycentric
L0 = 1-x-y-z, L1 = x, L2 = y, L3 = z): P1 N_a = L_a; P2 N_a = L_a (2 L_a - 1) at the vertices,
N = 4 L_i L_j at the mid-edge nodes of ``TET10_EDGES`` (canonical VTK order, sidprep.fe.mesh).

Quadrature: stiffness with the degree-2 (4-point) rule - exact for affine P2 (the integrand is
quadratic) and the standard C3D10 rule; consistent mass with the degree-4 rule (exact for affine
P2, whose integrand N_a N_b is quartic).  DOFs are node-interleaved: 3*i + c.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from sidprep.errors import InputError
from sidprep.fe.material import Material
from sidprep.fe.mesh import FEMesh
from sidprep.fe.topology import TET10_EDGES

#: quadrature degree of the stiffness (exact for affine P2) and of the consistent mass
STIFFNESS_QUAD_DEGREE = 2
MASS_QUAD_DEGREE = 4
#: elements per batch: bounds the temporaries to a few arrays of CHUNK * 30 * 30 * 8 bytes (30 MB)
CHUNK = 4096


def shape_functions(order: int, xi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Values and reference gradients of the P1/P2 shape functions at points ``xi``.

    Parameters
    ----------
    order : 1 or 2
    xi : (3, nq) reference coordinates

    Returns
    -------
    N : (nq, nn) values, nn = 4 or 10
    dN : (nq, nn, 3) derivatives d N_a / d xi_k
    """
    x, y, z = xi
    L = np.stack([1.0 - x - y - z, x, y, z], axis=1)  # (nq, 4)
    dL = np.array([[-1.0, -1.0, -1.0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])  # (4, 3)
    if order == 1:
        return L, np.broadcast_to(dL, (xi.shape[1], 4, 3)).copy()
    N = np.empty((xi.shape[1], 10))
    dN = np.empty((xi.shape[1], 10, 3))
    N[:, :4] = L * (2.0 * L - 1.0)
    dN[:, :4] = (4.0 * L - 1.0)[:, :, None] * dL[None]
    for k, (i, j) in enumerate(TET10_EDGES):
        N[:, 4 + k] = 4.0 * L[:, i] * L[:, j]
        dN[:, 4 + k] = 4.0 * (L[:, i, None] * dL[j] + L[:, j, None] * dL[i])
    return N, dN


def shape_gradients(X: np.ndarray, dN: np.ndarray, weights: np.ndarray, first: int) -> tuple[np.ndarray, np.ndarray]:
    """Physical shape-function gradients and integration weights.

    X : (ne, nn, 3) coordinates of elements first, first + 1, ...; dN : (nq, nn, 3); weights : (nq,).
    Returns G (ne, nq, nn, 3) = dN/dx, and wdet (ne, nq) = w_q det J (volume element).
    """
    J = np.einsum("eak,qal->eqkl", X, dN, optimize=True)  # dx_k / dxi_l
    det = np.linalg.det(J)
    if not (det > 0.0).all():
        bad = first + int(np.argmin(det.min(axis=1)))
        raise InputError(f"mesh: element {bad + 1} (1-based cell index) has a non-positive Jacobian "
                         f"({det.min():.3g}); fix the node order or the mid-edge node positions")
    Jinv = np.linalg.inv(J)  # (ne, nq, 3, 3): d xi_l / d x_k
    G = np.matmul(dN[None], Jinv)  # (ne, nq, nn, 3): sum_l dN_al dxi_l/dx_k
    return G, det * weights[None, :]


def _keast_points() -> dict:
    """Keast's symmetric rules on the reference tetrahedron (the ones scikit-fem uses for these
    degrees; written out here, so that assembly does not import scikit-fem):
    {degree: (points (3, nq), weights (nq,) summing to the volume 1/6)}."""
    a2, b2 = (5 + 3 * np.sqrt(5)) / 20, (5 - np.sqrt(5)) / 20
    a4, b4 = (1 + np.sqrt(5 / 14)) / 4, (1 - np.sqrt(5 / 14)) / 4
    c, d = 11 / 14, 1 / 14
    return {
        2: (np.array([[a2, b2, b2], [b2, b2, b2], [b2, b2, a2], [b2, a2, b2]]).T, np.full(4, 1 / 24)),
        4: (np.array([[0.25, 0.25, 0.25], [c, d, d], [d, d, d], [d, d, c], [d, c, d],
                      [b4, a4, a4], [a4, b4, a4], [a4, a4, b4], [a4, b4, b4], [b4, a4, b4], [b4, b4, a4]]).T,
            np.array([-74 / 5625] + [343 / 45000] * 4 + [56 / 2250] * 6)),
    }


def quadrature_rule(order: int, degree: int):
    """Shape functions N (nq, nn), reference gradients dN (nq, nn, 3) and weights w (nq,) of the
    tetrahedron rule exact to ``degree`` (2 or 4, :func:`_keast_points`), for tet4 (order 1) or tet10 (2)."""
    xi, w = _keast_points()[degree]
    N, dN = shape_functions(order, xi)
    return N, dN, w


@dataclass(frozen=True)
class BlockPattern:
    """Node-graph sparsity pattern of a mesh: CSR ``indptr``/``indices`` over nodes, and for every
    element-local node pair (a, b) the position of block (cells[e,a], cells[e,b]) in it."""

    indptr: np.ndarray
    indices: np.ndarray
    slot: np.ndarray  # (ne, nn, nn) int64

    @property
    def n_nodes(self) -> int:
        return self.indptr.size - 1

    def scalar(self, element_matrices: np.ndarray) -> sp.csr_matrix:
        """Sum (ne, nn, nn) element matrices into an (n, n) CSR matrix."""
        data = np.bincount(self.slot.ravel(), element_matrices.ravel(), minlength=self.indices.size)
        n = self.n_nodes
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(n, n))

    def from_blocks(self, data: np.ndarray) -> sp.csr_matrix:
        """The (3n, 3n) CSR matrix (DOF 3*i + c) with 3x3 node blocks ``data`` (nnz_nodes, 3, 3)."""
        n = self.n_nodes
        return sp.bsr_matrix((data, self.indices, self.indptr), shape=(3 * n, 3 * n)).tocsr()



def block_pattern(cells: np.ndarray, n_nodes: int) -> BlockPattern:
    """The node-graph pattern of ``cells`` ((ne, nn) node indices) and the element slot map."""
    cells = np.asarray(cells, dtype=np.int64)
    nn = cells.shape[1]
    key = (cells[:, :, None] * n_nodes + cells[:, None, :]).ravel()
    uniq, inverse = np.unique(key, return_inverse=True)
    rows = uniq // n_nodes
    indptr = np.zeros(n_nodes + 1, dtype=np.int64)
    np.cumsum(np.bincount(rows, minlength=n_nodes), out=indptr[1:])
    idx_type = np.int32 if uniq.size < 2**31 and n_nodes < 2**31 else np.int64
    return BlockPattern(indptr=indptr.astype(idx_type), indices=(uniq % n_nodes).astype(idx_type),
                        slot=inverse.reshape(-1, nn, nn))


def _element_stiffness_blocks(X: np.ndarray, order: int, lam: float, mu: float, first: int) -> np.ndarray:
    """Element stiffness in node blocks (ne, nn, nn, 3, 3): K[a, b, i, j] couples u_a,i and u_b,j.

    K_ai,bj = int lam G_ai G_bj + mu G_aj G_bi + mu delta_ij G_a . G_b  (isotropic elasticity,
    a(u, v) = int lam div u div v + 2 mu eps(u) : eps(v)).
    """
    _, dN, w = quadrature_rule(order, STIFFNESS_QUAD_DEGREE)
    G, wdet = shape_gradients(X, dN, w, first)
    ne, nq, nn, _ = G.shape
    g = G.reshape(ne, nq, nn * 3)
    C = np.matmul((g * wdet[:, :, None]).transpose(0, 2, 1), g).reshape(ne, nn, 3, nn, 3)
    C = C.transpose(0, 1, 3, 2, 4)  # (ne, a, b, i, j) = int G_ai G_bj
    K = lam * C + mu * C.transpose(0, 1, 2, 4, 3)
    trace = np.einsum("eabii->eab", C)
    for i in range(3):
        K[:, :, :, i, i] += mu * trace
    return K


def _element_scalar_mass(X: np.ndarray, order: int, rho: float, first: int) -> np.ndarray:
    """Element scalar mass matrices (ne, nn, nn): int rho N_a N_b dV."""
    N, dN, w = quadrature_rule(order, MASS_QUAD_DEGREE)
    _, wdet = shape_gradients(X, dN, w, first)
    NN = np.einsum("qa,qb->qab", N, N).reshape(len(w), -1)
    nn = N.shape[1]
    return (rho * wdet @ NN).reshape(-1, nn, nn)


def _chunks(ne: int):
    for start in range(0, ne, CHUNK):
        yield slice(start, min(start + CHUNK, ne))


def _assemble_scalar(mesh: FEMesh, pattern: BlockPattern, element_fn) -> sp.csr_matrix:
    nn = mesh.cells.shape[1]
    out = np.empty((mesh.cells.shape[0], nn, nn))
    for s in _chunks(mesh.cells.shape[0]):
        out[s] = element_fn(mesh.points[mesh.cells[s]], s.start)
    return pattern.scalar(out)


def stiffness_matrix(mesh: FEMesh, material: Material, pattern: BlockPattern | None = None) -> sp.csr_matrix:
    """Linear-elastic stiffness matrix K (3n, 3n) in N/m (coordinates in m, E in Pa).

    ``pattern`` (from :func:`block_pattern`) may be passed to share it with the mass matrix.
    """
    pattern = pattern or block_pattern(mesh.cells, mesh.n_nodes)
    lam, mu = material.lame
    nnz = pattern.indices.size
    data = np.zeros((nnz, 9))
    flat = data.reshape(-1)
    for s in _chunks(mesh.cells.shape[0]):
        Ke = _element_stiffness_blocks(mesh.points[mesh.cells[s]], mesh.order, lam, mu, s.start)
        # scattered into the touched entries only: a bincount of every entry per chunk made the
        # assembly quadratic (28.4 s at 1.02M DOF, 7.0 s so)
        np.add.at(flat, (pattern.slot[s].reshape(-1, 1) * 9 + np.arange(9)).ravel(), Ke.ravel())
    return pattern.from_blocks(data.reshape(nnz, 3, 3))


def scalar_mass_matrix(mesh: FEMesh, rho: float, pattern: BlockPattern | None = None) -> sp.csr_matrix:
    """Scalar consistent mass matrix Ms (n, n), Ms_ab = int rho N_a N_b dV (kg); M = Ms (x) I3."""
    pattern = pattern or block_pattern(mesh.cells, mesh.n_nodes)
    return _assemble_scalar(mesh, pattern, lambda X, first: _element_scalar_mass(X, mesh.order, rho, first))


def lumped_scalar_mass(mesh: FEMesh, rho: float) -> np.ndarray:
    """Diagonal (lumped) scalar mass (n,) in kg.

    P1: row sums of the consistent element mass.  P2: HRZ lumping (Hinton, Rock & Zienkiewicz
    1976): the consistent diagonal scaled per element to the element mass, because P2 row sums
    give negative vertex masses.
    """
    m = np.zeros(mesh.n_nodes)
    for s in _chunks(mesh.cells.shape[0]):
        Me = _element_scalar_mass(mesh.points[mesh.cells[s]], mesh.order, rho, s.start)
        if mesh.order == 1:
            lumped = Me.sum(axis=2)
        else:
            diag = np.einsum("eaa->ea", Me)
            lumped = diag * (Me.sum(axis=(1, 2)) / diag.sum(axis=1))[:, None]
        m += np.bincount(mesh.cells[s].ravel(), lumped.ravel(), minlength=mesh.n_nodes)
    return m


def mass_matrix(mesh: FEMesh, material: Material, lumped: bool = False,
                pattern: BlockPattern | None = None) -> sp.csr_matrix:
    """Mass matrix M (3n, 3n) in kg: consistent (Ms (x) I3) or lumped (diagonal, see
    :func:`lumped_scalar_mass`)."""
    if lumped:
        return sp.diags(np.repeat(lumped_scalar_mass(mesh, material.rho), 3)).tocsr()
    return vector_mass(scalar_mass_matrix(mesh, material.rho, pattern))


def vector_mass(Ms: sp.spmatrix) -> sp.csr_matrix:
    """M = Ms (x) I3 (3n, 3n) from the scalar mass matrix Ms (n, n), without explicit zeros, written as
    CSR directly: row 3i + c holds row i of Ms at columns 3j + c (sp.kron's COO copies: a 206k-DOF
    bar's peak 172 -> 111 MiB, for a 62 MiB result)."""
    Ms = sp.csr_matrix(Ms)
    Ms.sort_indices()
    n, counts = Ms.shape[0], np.diff(Ms.indptr)
    index = np.int32 if 3 * max(n, Ms.nnz) < 2**31 else np.int64
    indptr = np.zeros(3 * n + 1, dtype=index)
    np.cumsum(np.repeat(counts, 3), out=indptr[1:])
    data, indices = np.empty(3 * Ms.nnz), np.empty(3 * Ms.nnz, dtype=index)
    row = np.repeat(np.arange(n), counts)                  # each entry's row i of Ms
    first = np.arange(Ms.nnz) + 2 * Ms.indptr[row]         # its place in row 3i: 3 indptr[i] + (k - indptr[i])
    step = counts[row]                                     # rows 3i + 1, 3i + 2 follow, each counts[i] long
    del row
    for c in range(3):
        data[first + c * step] = Ms.data
        indices[first + c * step] = 3 * Ms.indices + c
    return sp.csr_matrix((data, indices, indptr), shape=(3 * n, 3 * n))


def stiffness_and_mass(mesh: FEMesh, material: Material) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """K and consistent M (both (3n, 3n) CSR) sharing one sparsity pattern computation."""
    pattern = block_pattern(mesh.cells, mesh.n_nodes)
    return stiffness_matrix(mesh, material, pattern), mass_matrix(mesh, material, pattern=pattern)
