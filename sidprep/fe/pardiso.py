"""Symmetric indefinite LDL^T with inertia and Schur complement: MKL PARDISO through ctypes.

scipy has no sparse symmetric-indefinite factorisation that reports its inertia (CHOLMOD is Cholesky
only, SuperLU gives no pivot signs).  The PyPI wheel ``mkl`` (already a dependency: its BLAS runs
under CHOLMOD, sidprep.fe.linalg.fast_blas) ships PARDISO in libmkl_rt: for a real symmetric
indefinite matrix (mtype -2, Bunch-Kaufman pivoting) it returns the number of positive and negative
pivots (iparm[21], iparm[22]) and, on request (iparm[35] = 1 with ``perm`` marking the rows), the
dense Schur complement of a trailing block, A_BB - A_BI A_II^-1 A_IB, then with the inertia of A_II.

By Sylvester's law of inertia the pivot signs are the eigenvalue signs: the count of the
Wittrick-Williams algorithm (sidprep.reduction.coarse_space.count_below).  Intel oneMKL Developer Reference, "oneMKL
PARDISO - Parallel Direct Sparse Solver Interface" (pardiso, iparm).
"""

from __future__ import annotations

import ctypes
import functools
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from sidprep.fe.linalg import fast_blas, upper_triangle


#: PARDISO matrix type: real symmetric indefinite
MTYPE_REAL_SYMMETRIC_INDEFINITE = -2
#: phases: analysis + numerical factorisation, release of all memory
PHASE_FACTORIZE, PHASE_RELEASE = 12, -1
#: pivot perturbation 10^-PIVOT_PERTURBATION_EXP (PARDISO's default for mtype -2); a perturbed pivot
#: makes the inertia uncertain and is reported (``n_perturbed``)
PIVOT_PERTURBATION_EXP = 8
#: LP64 PARDISO takes 32-bit indices
MAX_INDEX = 2**31 - 1


@dataclass(frozen=True)
class Inertia:
    """Pivot signs of A (or of A_II when a Schur complement was asked) and the Schur complement.

    n_negative, n_positive : pivots below / above zero; n_perturbed : pivots PARDISO perturbed (then
    the signs are not certain); schur : (nb, nb) dense A_BB - A_BI A_II^-1 A_IB, or None.
    """

    n_negative: int
    n_positive: int
    n_perturbed: int
    schur: np.ndarray | None = None


@functools.cache
def _pardiso():
    """The ``pardiso`` entry of libmkl_rt (loaded by fast_blas), or None without MKL."""
    path = fast_blas()
    if path == "reference":
        return None
    fn = ctypes.CDLL(path, mode=ctypes.RTLD_GLOBAL).pardiso
    fn.restype = None
    fn.argtypes = [ctypes.c_void_p] * 16
    return fn


def pardiso_available() -> bool:
    return _pardiso() is not None


def with_diagonal(U: sp.csr_matrix) -> sp.csr_matrix:
    """U with every diagonal entry stored (explicit zeros where missing): PARDISO needs them."""
    n = U.shape[0]
    U = U.tocoo()
    return sp.csr_matrix((np.r_[U.data, np.zeros(n)], (np.r_[U.row, np.arange(n)], np.r_[U.col, np.arange(n)])),
                         shape=(n, n))


def _int(value: int) -> np.ndarray:
    return np.array([value], dtype=np.int32)


def ldlt_inertia(A: sp.spmatrix, schur_rows=None) -> Inertia:
    """Inertia of the symmetric sparse ``A`` (n, n) by LDL^T; with ``schur_rows`` (nb,) ascending
    row indices B, the inertia of A_II (I the other rows) and the dense Schur complement on B."""

    fn = _pardiso()
    if fn is None:
        raise RuntimeError("PARDISO needs the PyPI wheel 'mkl' (pip install mkl)")
    n = A.shape[0]
    U = upper_triangle(A)
    if np.any(np.diff(U.indptr) == 0) or np.any(U.indices[U.indptr[:-1]] != np.arange(n)):
        U = with_diagonal(U)
    if U.nnz > MAX_INDEX:
        raise MemoryError(f"PARDISO (LP64): {U.nnz} stored entries exceed 2^31 - 1")
    a = np.ascontiguousarray(U.data, dtype=np.float64)
    ia, ja = U.indptr.astype(np.int32, copy=False), U.indices.astype(np.int32, copy=False)
    rows = np.asarray([] if schur_rows is None else schur_rows, dtype=np.int64)
    perm = np.zeros(n, dtype=np.int32)
    perm[rows] = 1
    iparm = np.zeros(64, dtype=np.int32)
    iparm[0] = 1                                  # iparm given here, not PARDISO's defaults
    iparm[1] = 2                                  # nested-dissection ordering (METIS)
    iparm[9] = PIVOT_PERTURBATION_EXP
    iparm[34] = 1                                 # zero-based ia, ja
    iparm[35] = 1 if len(rows) else 0             # dense Schur complement of the rows marked in perm
    x = np.zeros(max(len(rows) ** 2, n))          # the dense Schur complement is returned in x
    b = np.zeros(n)                               # no solve: b only as PARDISO's argument
    pt, err = np.zeros(64, dtype=np.int64), np.zeros(1, dtype=np.int32)

    def call(phase: int) -> None:
        ptr = [v.ctypes.data_as(ctypes.c_void_p) for v in
               (pt, _int(1), _int(1), _int(MTYPE_REAL_SYMMETRIC_INDEFINITE), _int(phase), _int(n), a, ia, ja,
                perm, _int(1), iparm, _int(0), b, x, err)]
        fn(*ptr)

    try:
        call(PHASE_FACTORIZE)
        if err[0] != 0:
            raise np.linalg.LinAlgError(f"PARDISO: error {int(err[0])} in the factorisation")
        schur = x[:len(rows) ** 2].reshape(len(rows), len(rows)) if len(rows) else None   # a view: no copy
        return Inertia(int(iparm[22]), int(iparm[21]), int(iparm[13]), schur)
    finally:
        call(PHASE_RELEASE)
