"""Component-mode reduction of a sparse FE model onto boundary DOFs: Guyan and Craig-Bampton.

With the DOFs split into boundary b and interior i,

    u = Phi z,   Phi = [[Psi_ib, Phi_im], [E, 0]],   Psi_ib = -K_ii^-1 K_ib

(constraint modes Psi: static shapes for unit boundary displacements; fixed-interface normal
modes Phi_im: K_ii phi = lambda M_ii phi, M_ii-normalised).  Guyan keeps the constraint modes
only.  K_ii is factorised once (sidprep.fe.linalg.factorize) and that factor serves every
constraint-mode right-hand side and the shift-invert eigen solve.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from sidprep.errors import InputError
from sidprep.fe.linalg import (MEMORY_HEADROOM, available_memory_bytes, estimate_peak_memory, factorize,
    single_threaded_blas)


#: ceiling of fixed-interface modes requested when growing towards ``fmax``
MAX_FIXED_INTERFACE_MODES = 400
#: columns of an operator product at a time in a Gram matrix V^T A V (``block_gram``, ``project``):
#: its (n, GRAM_BLOCK) temporaries instead of an (n, k) one (the driver's peak of a reduction in parts)
GRAM_BLOCK = 16
#: boundary DOFs per multi-right-hand-side solve of the constraint modes (``add_constraint_modes``)
CONSTRAINT_BLOCK = 64
#: ARPACK relative tolerance of the fixed-interface eigen solve
EIGSH_TOL = 1e-10


@dataclass(frozen=True)
class ReducedModel:
    """A Guyan / Craig-Bampton reduced model.

    basis : (n, nb + nm) Phi in the unreduced DOFs; columns = boundary DOFs (in the order given),
    then fixed-interface modes.  K, M : (nb + nm, nb + nm) dense Phi^T K Phi, Phi^T M Phi.
    boundary_dofs : (nb,) unreduced DOF indices; fixed_interface_hz : (nm,) Hz;
    interior_factor : the factor of K_ii (reused by ``static_solve``).
    """

    basis: np.ndarray
    K: np.ndarray
    M: np.ndarray
    boundary_dofs: np.ndarray
    fixed_interface_hz: np.ndarray
    interior_factor: object = None

    @property
    def n_boundary(self) -> int:
        return len(self.boundary_dofs)

    def static_solve(self, P: np.ndarray, supports) -> np.ndarray:
        """EXACT full-model static solution K u = P, u = 0 at ``supports`` (a subset of the boundary).

        Static condensation with the stored K_ii factor: the boundary block of the reduced K is the
        Schur complement S = K_bb - K_bi K_ii^-1 K_ib, so S u_b = P_b + Psi^T P_i and
        u_i = Psi u_b + K_ii^-1 P_i.  P : (n, nc) -> u : (n, nc).
        """
        nb = self.n_boundary
        b = self.boundary_dofs
        interior = np.ones(self.basis.shape[0], bool)
        interior[b] = False
        P = np.asarray(P, dtype=float).reshape(self.basis.shape[0], -1)
        Psi = self.basis[interior, :nb]
        v_i = np.asarray(self.interior_factor.solve(P[interior])).reshape(-1, P.shape[1])
        free = ~np.isin(b, supports)
        if not np.isin(supports, b).all():
            raise ValueError("static_solve: the supports must be boundary DOFs")
        u_b = np.zeros((nb, P.shape[1]))
        u_b[free] = np.linalg.solve(self.K[:nb, :nb][np.ix_(free, free)], (P[b] + Psi.T @ P[interior])[free])
        u = np.empty_like(P)
        u[b] = u_b
        u[interior] = Psi @ u_b + v_i
        return u


def split_dofs(n: int, boundary_dofs) -> tuple[np.ndarray, np.ndarray]:
    """(boundary (nb,), interior (ni,)) DOF indices; boundary keeps the given order."""
    b = np.asarray(boundary_dofs, dtype=np.int64)
    if len(np.unique(b)) != len(b) or (len(b) and (b.min() < 0 or b.max() >= n)):
        raise ValueError("boundary_dofs must be distinct indices in [0, n)")
    interior = np.setdiff1d(np.arange(n), b)
    return b, interior


def add_constraint_modes(basis: np.ndarray, K: sp.csr_matrix, factor, b: np.ndarray, i: np.ndarray) -> None:
    """basis[i, :nb] = Psi_ib = -K_ii^-1 K_ib, CONSTRAINT_BLOCK boundary DOFs per multi-RHS solve (the
    solve's right-hand side and result scale with the block, not with nb: a part's hundreds of coarse
    coordinates).  K symmetric CSR: K_ib is read from the boundary rows (no CSC copy of K)."""
    for s in range(0, len(b), CONSTRAINT_BLOCK):
        rhs = -K[b[s:s + CONSTRAINT_BLOCK]][:, i].T.toarray()
        basis[i, s:s + len(rhs.T)] = np.asarray(factor.solve(rhs)).reshape(rhs.shape)


def interior_operator(A: sp.spmatrix, interior) -> spla.LinearOperator:
    """The block A_ii (``interior``: indices or a mask) as an operator, without copying the block:
    x -> (A x_padded)[interior], x (ni,) or (ni, k)."""
    n = A.shape[0]
    ni = int(np.count_nonzero(interior)) if np.asarray(interior).dtype == bool else len(interior)

    def matmat(X):
        full = np.zeros((n,) + X.shape[1:])
        full[interior] = X
        return (A @ full)[interior]

    return spla.LinearOperator((ni, ni), matvec=matmat, matmat=matmat, dtype=float)


def fixed_interface_modes(K_ii, M_ii, factor, n_modes=None, fmax=None):
    """Lowest eigenpairs of K_ii phi = lambda M_ii phi by shift-invert at 0 with the given factor
    (K_ii, M_ii sparse matrices or operators; ARPACK's shift-invert mode applies only M_ii and the factor).

    Returns (frequencies Hz (nm,), vectors (ni, nm) M_ii-normalised).  With ``fmax``, the count
    grows (doubling) until the highest computed frequency passes fmax, then is cut at fmax.
    """
    n = K_ii.shape[0]
    if n_modes is None and fmax is None:
        raise ValueError("give n_modes or fmax")
    if n_modes is not None and n_modes <= 0:
        return np.zeros(0), np.zeros((n, 0))
    op = spla.LinearOperator((n, n), matvec=factor.solve, dtype=float)
    k = n_modes if n_modes is not None else 12
    while True:
        k = min(k, n - 1)
        lam, vec = spla.eigsh(K_ii, k=k, M=M_ii, sigma=0.0, which="LM", OPinv=op, tol=EIGSH_TOL,
                              v0=np.ones(n))          # deterministic start: reproducible files
        order = np.argsort(lam)
        lam, vec = lam[order], vec[:, order]
        f = np.sqrt(np.abs(lam)) / (2 * np.pi)
        if n_modes is not None or f[-1] > fmax or k >= min(n - 1, MAX_FIXED_INTERFACE_MODES):
            break
        k *= 2
    if fmax is not None and n_modes is None:
        keep = f <= fmax
        f, vec = f[keep], vec[:, keep]
    vec /= np.sqrt(np.einsum("ij,ij->j", vec, M_ii @ vec))
    return f, vec


#: peak of a whole `sidprep reduce` run over the estimated peak of a direct eigen solve of the same
#: model (K_model and M_model, the K_ii factor with K_ii and M_ii, the dense constraint modes, the
#: Lanczos vectors of the fixed-interface modes, the basis): 1.38 / 1.36 on 93k / 211k-DOF tet10 bars
#: with two RBE2 interfaces and 30 modes (docs/performance.md, since the frequency check needs no
#: second factor; 2.1-2.2 before)
REDUCE_OVER_MODES_PEAK = 1.4


def reduction_peak_bytes(n_dof: int, nnz: int | None = None, extent=None) -> float:
    """Estimated peak memory (bytes) of a whole reduction of an n_dof model, before it runs;
    ``extent`` : the body's bounding-box edge lengths (default a cube, the densest fill)."""

    return REDUCE_OVER_MODES_PEAK * estimate_peak_memory(n_dof, nnz, extent).direct_peak_bytes


def check_reduction_memory(n_dof: int, nnz: int, memory_limit: float | None = None, extent=None) -> None:
    """Refuse (InputError, one line) a reduction whose estimated peak exceeds the memory this run may
    use, before the factorisation starts, instead of meeting the out-of-memory killer."""

    need = reduction_peak_bytes(n_dof, nnz, extent)
    avail = available_memory_bytes() if memory_limit is None else float(memory_limit)
    if need > MEMORY_HEADROOM * avail:
        raise InputError(f"model too large for this machine: the reduction of {n_dof} DOF needs ~{need / 1024 ** 3:.1f} GB, "
                         f"{avail / 1024 ** 3:.1f} GB available; use a coarser mesh, or force it by raising "
                         "SIDPREP_MEMORY_LIMIT (bytes, or with K/M/G)")


def craig_bampton(K, M, boundary_dofs, n_modes=None, fmax=None, memory_limit=None, extent=None) -> ReducedModel:
    """Craig-Bampton reduction (module docstring); n_modes fixed-interface modes or all below fmax Hz.

    Parameters
    ----------
    K, M : (n, n) sparse symmetric, N/m and kg
    boundary_dofs : (nb,) int; K_ii must be positive definite (the boundary holds the body).
    n_modes : int, optional; fmax : float, optional (Hz)
    memory_limit : bytes this run may use (default ``sidprep.fe.linalg.available_memory_bytes()``)
    extent : (3,) bounding-box edge lengths of the body for the memory estimate (default a cube)
    """

    check_reduction_memory(K.shape[0], K.nnz, memory_limit, extent)

    with single_threaded_blas():
        K, M = sp.csr_matrix(K), sp.csr_matrix(M)
        b, i = split_dofs(K.shape[0], boundary_dofs)
        try:
            factor = factorize(K[i][:, i])        # the copy K_ii lives only while it is factorised
        except (np.linalg.LinAlgError, RuntimeError) as exc:  # singular interior: the boundary does not hold it
            raise InputError(f"the interior stiffness is singular ({exc}); the interfaces do not hold the body "
                             "statically — add an interface or use the free frame") from exc
        if n_modes == 0 or (n_modes is None and fmax is None):
            f, Phi_m = np.zeros(0), np.zeros((len(i), 0))
        else:
            # K_ii only as an operator (shift-invert never applies it); M_ii copied after the factorisation
            # (ARPACK applies it ~4x per mode: 0.56 -> 0.2 ms per product through the copy, piston rod)
            f, Phi_m = fixed_interface_modes(interior_operator(K, i), M[i][:, i], factor, n_modes, fmax)
        basis = np.zeros((K.shape[0], len(b) + len(f)))
        basis[i, len(b):] = Phi_m
        del Phi_m
        basis[b, np.arange(len(b))] = 1.0
        add_constraint_modes(basis, K, factor, b, i)
    return ReducedModel(basis, project(K, basis), project(M, basis), b, f, factor)


def guyan(K, M, boundary_dofs) -> ReducedModel:
    """Guyan (static) condensation: Craig-Bampton without fixed-interface modes."""
    return craig_bampton(K, M, boundary_dofs, n_modes=0)


def project(A, basis: np.ndarray) -> np.ndarray:
    """Symmetrised basis^T A basis, dense (nr, nr); A @ basis is formed GRAM_BLOCK columns at a time
    (``block_gram``): no (n, nr) temporary beside the basis."""
    P = block_gram(A.__matmul__, (basis,))
    return 0.5 * (P + P.T)


def blockwise(op, X: np.ndarray) -> np.ndarray:
    """op(X) (n, k) for a square op (n, n) and X (n, k), op applied to GRAM_BLOCK columns at a time
    into the one (n, k) result: op's (n, k) temporaries (three for ``interior_operator``) are (n,
    GRAM_BLOCK) ones (the refinement's peak in a reduction in parts)."""
    out = np.empty(X.shape)
    for j in range(0, X.shape[1], GRAM_BLOCK):
        out[:, j:j + GRAM_BLOCK] = op(X[:, j:j + GRAM_BLOCK])
    return out


def block_gram(op, blocks) -> np.ndarray:
    """V^T op(V) (k, k) for V = [blocks] (n, k), the blocks side by side (V is never formed), op
    applied to GRAM_BLOCK columns at a time (peak memory)."""
    columns = (B[:, j:j + GRAM_BLOCK] for B in blocks for j in range(0, B.shape[1], GRAM_BLOCK))
    k = sum(B.shape[1] for B in blocks)
    return np.hstack([np.vstack([B.T @ product for B in blocks]) for product in map(op, columns)]) if k \
        else np.zeros((0, 0))

