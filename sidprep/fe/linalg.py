"""Sparse factorisations and the generalized eigenproblem K phi = lambda M phi.

One interface, interchangeable backends:

* ``factorize(A, backend)``: "cholmod" (supernodal Cholesky of the ``sksparse_minimal`` wheel,
  SPD matrices, fill-reducing ordering), "superlu" (scipy, any nonsingular matrix), "auto"
  (CHOLMOD when importable, else SuperLU).  The wheel bundles the netlib reference BLAS; when the
  PyPI wheel ``mkl`` is installed, its BLAS/LAPACK is loaded with global symbol visibility before
  CHOLMOD, so CHOLMOD's dgemm_/dsyrk_/dpotrf_/dtrsm_ calls bind to it (ELF symbol interposition;
  factorisation 3-4x faster at 101k DOF).  SIDPREP_FAST_BLAS=0 turns this off.
* ``eigen_modes(K, M, ...)``: shift-invert Lanczos (ARPACK through ``scipy.sparse.linalg.eigsh``)
  with the factorisation of K - sigma M as OPinv, or ``backend="lobpcg"``: LOBPCG preconditioned
  with smoothed-aggregation AMG (pyamg) on K - sigma M, for models beyond direct-solver memory.

Shift: sigma is negative (K - sigma M is then SPD even for free-floating bodies, so Cholesky
applies) and scaled to the problem: sigma = -SHIFT_REL * s with s = median(diag K / diag M),
an element-level eigenvalue scale ~ (c/h)^2.  sigma = -1 (rad/s)^2 made K - sigma M nearly
singular and lost up to 2e-4 relative accuracy on a 262k-DOF free bar
(../shared/validation/README.md section 3.2); a shift of this size does not.
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import os
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.csgraph as csgraph
import scipy.sparse.linalg as spla
from threadpoolctl import threadpool_limits

from sidprep.errors import InputError


#: sigma = -SHIFT_REL * median(diag K / diag M)
SHIFT_REL = 1e-6
#: rigid-body modes are the leading modes before the largest gap of the spectrum; that gap must be at
#: least RIGID_GAP (ratio of eigenvalues; a free steel part: ~1e8 and more, two neighbouring elastic
#: modes: < 1e2) ...
RIGID_GAP = 1e4
#: ... and the rigid eigenvalues below RIGID_LOOSE_REL * median(diag K / diag M), a loose bound (the
#: round-off of a zero eigenvalue is ~ eps x that scale).  An absolute bound alone (1e-10 x scale) took
#: the 0.605 Hz mode of a soft 10 m beam (lambda = 14.45, scale 3.3e11) for rigid.
RIGID_LOOSE_REL = 1e-6
#: below this many DOFs (backend "auto"), or when half the modes or more are wanted (any backend), the
#: eigenproblem is solved densely (LAPACK): ARPACK cannot give k >= n - 1 modes, and ARPACK with
#: CHOLMOD aborted the process (malloc / segfault) on a one-tet mesh
DENSE_MAX_DOF = 600
EIGEN_BACKENDS = ("auto", "cholmod", "superlu", "lobpcg", "dense")
#: nearly all modes of a larger problem are refused above this size (dense K, M, vectors: ~0.6 GB)
DENSE_ALL_MAX_DOF = 5000
#: ARPACK convergence tolerance (relative accuracy of the Ritz values); 0 = machine precision
ARPACK_TOL = 0.0
#: seed of the deterministic Lanczos start vector (bit-identical repeat runs)
START_SEED = 20261121
#: LOBPCG stop: residual ||A x - mu M x|| below LOBPCG_RTOL * |sigma| * ||M x|| (x M-normalised,
#: ||M x|| ~ sqrt(mean diag M)); eigenvalue errors are ~ the square of it.  Tighter settings only
#: stall at round-off (1e-7 took 30x longer and ended with larger residuals on the 17k-DOF bar).
LOBPCG_RTOL = 1e-6
LOBPCG_MAXITER = 400
#: first block size of the fmax search, and its growth factor
FMAX_FIRST_COUNT = 20
FMAX_GROWTH = 2


#: optimised BLAS/LAPACK libraries interposed under CHOLMOD, searched in <prefix>/lib (wheel "mkl")
FAST_BLAS_LIBRARIES = ("libmkl_rt.so.3", "libmkl_rt.so.2", "libmkl_rt.so")
#: MKL threading layer unless MKL_THREADING_LAYER is set: OpenMP threads made the Lanczos phase
#: (many small triangular solves) 16x slower on the shared 2-core machine (0.56 s -> 9 s, 17k DOF)
MKL_DEFAULT_THREADING = "SEQUENTIAL"


@functools.cache
def fast_blas() -> str:
    """Load an optimised BLAS for CHOLMOD (see the module docstring); returns its path or
    "reference" (the wheel's own netlib BLAS).  Must run before CHOLMOD's first BLAS call."""
    if os.environ.get("SIDPREP_FAST_BLAS", "1") == "0" or "sksparse_minimal._cholespy_core" in sys.modules:
        return "reference"  # switched off, or CHOLMOD was loaded (and bound) before this call
    os.environ.setdefault("MKL_THREADING_LAYER", MKL_DEFAULT_THREADING)  # read when MKL loads
    for prefix in dict.fromkeys((sys.prefix, sys.base_prefix)):
        for name in FAST_BLAS_LIBRARIES:
            path = Path(prefix) / "lib" / name
            if path.exists():
                try:
                    ctypes.CDLL(str(path), mode=ctypes.RTLD_GLOBAL)
                except OSError:
                    continue
                return str(path)
    return "reference"


class Factorization:
    """A factorised square matrix; ``solve(b)`` for b of shape (n,) or (n, k)."""

    backend = ""

    def solve(self, b: np.ndarray) -> np.ndarray:  # pragma: no cover - interface
        raise NotImplementedError


class CholmodFactorization(Factorization):
    """Supernodal Cholesky L L^T of an SPD matrix (CHOLMOD via sksparse_minimal)."""

    backend = "cholmod"

    def __init__(self, A: sp.spmatrix, upper: bool = False):
        """``upper``: A already holds only its upper triangle as CSR with sorted indices."""
        self.blas = fast_blas()
        from sksparse_minimal import SparseCholesky  # deferred: optional CHOLMOD wheel; after fast_blas: extensions bind at load

        # CHOLMOD reads the lower triangle of a CSC matrix; the CSR arrays of triu(A) are exactly
        # the CSC arrays of tril(A) (A symmetric), so no transpose copy is made.
        U = A if upper else upper_triangle(A)
        if not U.has_sorted_indices:
            U.sort_indices()
        L = sp.csc_matrix((U.data, U.indices, U.indptr), shape=A.shape)
        self.n = A.shape[0]
        del U
        try:
            self._chol = SparseCholesky(L)
        except Exception as exc:  # CHOLMOD raises a plain exception for non-SPD input
            raise np.linalg.LinAlgError(f"CHOLMOD: {exc}") from None

    def solve(self, b):
        b = np.ascontiguousarray(b, dtype=np.float64)         # CHOLMOD needs C order
        if b.ndim not in (1, 2) or b.shape[0] != self.n:      # CHOLMOD reads past a short b (heap corruption)
            raise ValueError(f"CHOLMOD solve: right-hand side of shape {b.shape} for a matrix of order {self.n}")
        return self._chol.solve_A(b)


def upper_triangle(A: sp.spmatrix) -> sp.csr_matrix:
    """triu(A) as CSR with sorted indices, without the COO copies of scipy.sparse.triu."""
    A = sp.csr_matrix(A)
    A.sort_indices()
    rows = np.repeat(np.arange(A.shape[0], dtype=A.indices.dtype), np.diff(A.indptr))
    keep = A.indices >= rows
    indptr = np.zeros_like(A.indptr)
    np.cumsum(np.bincount(rows[keep], minlength=A.shape[0]), out=indptr[1:])
    del rows
    return sp.csr_matrix((A.data[keep], A.indices[keep], indptr), shape=A.shape)


class SuperLUFactorization(Factorization):
    """LU factorisation (scipy SuperLU, COLAMD ordering) of any nonsingular sparse matrix."""

    backend = "superlu"

    def __init__(self, A: sp.spmatrix):
        self._lu = spla.splu(sp.csc_matrix(A))

    def solve(self, b):
        return self._lu.solve(np.asarray(b, dtype=np.float64))


def cholmod_available() -> bool:
    fast_blas()  # Python loads extension modules with RTLD_NOW: the BLAS must come first
    try:
        import sksparse_minimal  # deferred: optional CHOLMOD wheel  # noqa: F401
    except ImportError:
        return False
    return True


def _direct_backend(backend: str) -> str:
    if backend == "auto":
        return "cholmod" if cholmod_available() else "superlu"
    if backend not in ("cholmod", "superlu"):
        raise InputError(f"--backend {backend}: unknown factorisation backend; use auto, cholmod or superlu")
    return backend


def factorize(A: sp.spmatrix, backend: str = "auto") -> Factorization:
    """Factorise the square sparse matrix ``A`` (symmetric positive definite for "cholmod").

    backend: "auto" (CHOLMOD if installed, else SuperLU), "cholmod" or "superlu".
    """
    if _direct_backend(backend) == "cholmod":
        return CholmodFactorization(A)
    return SuperLUFactorization(A)


def factorize_shifted(K: sp.spmatrix, M: sp.spmatrix, sigma: float, backend: str = "auto") -> Factorization:
    """Factorisation of K - sigma M (K, M symmetric).  For CHOLMOD only the upper triangle is ever
    formed: no full copy of K - sigma M is alive while the factor is built (peak memory)."""
    if _direct_backend(backend) == "cholmod":
        return CholmodFactorization(upper_triangle(K) - sigma * upper_triangle(M), upper=True)
    return SuperLUFactorization(K - sigma * M)


#: memory model of a direct (shift-invert Lanczos) run, calibrated on tet10 boxes of three shapes
#: (bar 1 x 0.05 x 0.08, cube, plate 0.5 x 0.5 x 0.04 m; 21k-110k DOF; benchmarks/scale.py):
#: Python + numpy/scipy/gmsh + mesh, bytes
MEMORY_BASE = 110e6
#: K and M (CSR, both triangles) with the assembly's transient arrays, bytes per stored entry of K
MEMORY_PER_NNZ = 32.0
#: CHOLMOD factor (supernodal padding, indices, its copy of the input) over 8 bytes x the geometric
#: nested-dissection fill estimate (nested_dissection_fill) of the same mesh: measured 3.5-4.7
FACTOR_OVER_FILL = 4.3
#: smoothed-aggregation AMG hierarchy, bytes per stored entry of K (operators, prolongators, smoothers)
AMG_PER_NNZ = 40.0
#: entries of K per DOF of a tet10 mesh when the caller does not know nnz (measured 71-75)
TET10_NNZ_PER_DOF = 75.0
#: fraction of the available memory a run may plan to use (page cache, other processes, error)
MEMORY_HEADROOM = 0.8
#: a leaf of the nested dissection holds at most this many nodes (eliminated densely)
ND_LEAF_NODES = 64


def nested_dissection_fill(layers) -> float:
    """Entries (3 x 3 node blocks) of the Cholesky factor of a box-shaped mesh with ``layers``
    (3,) node layers along its axes, under geometric nested dissection (George 1973): the middle
    plane across the longest axis is a separator (dense triangle, plus its coupling to the
    enclosing separators), the two halves recurse."""
    d = sorted((max(float(x), 1.0) for x in layers), reverse=True)
    n = d[0] * d[1] * d[2]
    if n <= ND_LEAF_NODES or d[0] < 3:
        return n * n / 2
    s = d[1] * d[2]
    return s * s / 2 + 2 * s * (d[1] + d[2]) + 2 * nested_dissection_fill(((d[0] - 1) / 2, d[1], d[2]))


@dataclass(frozen=True)
class MemoryEstimate:
    """Predicted memory of a modes / reduce run, bytes (``estimate_peak_memory``)."""

    n_dof: int
    nnz: int
    factor_bytes: float
    direct_peak_bytes: float
    iterative_peak_bytes: float

    def describe(self) -> str:
        gb = 1024.0 ** 3
        return (f"memory estimate: {self.n_dof} DOF, factor {self.factor_bytes / gb:.2f} GB, peak "
                f"{self.direct_peak_bytes / gb:.2f} GB direct / {self.iterative_peak_bytes / gb:.2f} GB AMG-LOBPCG")


def estimate_peak_memory(n_dof: int, nnz: int | None = None, extent=None, n_modes: int = 30) -> MemoryEstimate:
    """Peak memory of an eigen solve / reduction before it runs, from the size and the sparsity.

    Parameters
    ----------
    n_dof : free DOFs (3 per node)
    nnz : stored entries of K (both triangles); default TET10_NNZ_PER_DOF x n_dof
    extent : (3,) bounding-box edge lengths of the body, m; default a cube (the densest fill)
    n_modes : modes wanted (Lanczos / LOBPCG blocks)
    """
    n_dof = int(n_dof)
    nnz = int(TET10_NNZ_PER_DOF * n_dof if nnz is None else nnz)
    n_nodes = max(n_dof / 3.0, 1.0)
    ext = np.ones(3) if extent is None else np.maximum(np.asarray(extent, dtype=float), 1e-12)
    ext = np.maximum(ext, ext.max() * 1e-3)                      # a flat box is at least one layer thick
    layers = ext * (n_nodes / ext.prod()) ** (1.0 / 3.0)
    factor = FACTOR_OVER_FILL * 8.0 * 9.0 * nested_dissection_fill(layers)
    matrices = MEMORY_PER_NNZ * nnz
    lanczos = 8.0 * n_dof * 2 * max(2 * n_modes + 1, 20)        # Lanczos basis + Ritz vectors
    lobpcg = 8.0 * n_dof * 3 * n_modes * 6                      # X, R, P blocks and their images
    return MemoryEstimate(n_dof, nnz, factor, MEMORY_BASE + matrices + factor + lanczos,
                          MEMORY_BASE + matrices + AMG_PER_NNZ * nnz + lobpcg)


def available_memory_bytes() -> float:
    """Memory this process may use: SIDPREP_MEMORY_LIMIT (bytes, or with a K/M/G suffix) if set,
    else the kernel's MemAvailable (/proc/meminfo), the smaller of it and a cgroup limit."""
    limit = os.environ.get("SIDPREP_MEMORY_LIMIT")
    if limit:
        try:
            return float(limit[:-1]) * 1024.0 ** "KMG".index(limit[-1].upper()) * 1024 if limit[-1].isalpha() \
                else float(limit)
        except ValueError:
            raise InputError(f"SIDPREP_MEMORY_LIMIT={limit}: give bytes or a number with K, M or G") from None
    avail = np.inf
    with contextlib.suppress(OSError, ValueError, StopIteration):
        with open("/proc/meminfo") as fh:
            avail = 1024.0 * float(next(line for line in fh if line.startswith("MemAvailable")).split()[1])
    with contextlib.suppress(OSError, ValueError):
        avail = min(avail, float(Path("/sys/fs/cgroup/memory.max").read_text().strip()))
    return avail


def choose_backend(estimate: MemoryEstimate, available: float | None = None) -> str:
    """"cholmod" (direct) when its peak fits in MEMORY_HEADROOM x the available memory, else
    "lobpcg" (AMG-preconditioned, no factor); InputError when neither fits."""
    avail = available_memory_bytes() if available is None else float(available)
    if estimate.direct_peak_bytes <= MEMORY_HEADROOM * avail:
        return "cholmod" if cholmod_available() else "superlu"
    if estimate.iterative_peak_bytes <= MEMORY_HEADROOM * avail:
        return "lobpcg"
    gb = 1024.0 ** 3
    raise InputError(f"model too large for this machine: {estimate.n_dof} DOF need ~{estimate.iterative_peak_bytes / gb:.1f} GB "
                     f"even with the iterative solver (direct {estimate.direct_peak_bytes / gb:.1f} GB), "
                     f"{avail / gb:.1f} GB available; use a coarser mesh, or force it with --backend lobpcg")


@dataclass(frozen=True)
class EigenResult:
    """Solution of K phi = lambda M phi, rigid-body modes first.

    Attributes
    ----------
    eigenvalues : (k,) lambda = omega^2 in (rad/s)^2, ascending (rigid ones ~ 0)
    vectors : (n, k) M-normalised modes (phi^T M phi = 1)
    residuals : (k,) ||K phi - lambda M phi|| / ||K phi|| (elastic), / (s ||M phi||) (rigid,
        s = median(diag K / diag M))
    n_rigid : number of leading rigid-body (zero-frequency) modes
    sigma : the shift used, (rad/s)^2
    backend : "cholmod", "superlu", "lobpcg" or "dense" (small problems, LAPACK)
    """

    eigenvalues: np.ndarray
    vectors: np.ndarray
    residuals: np.ndarray
    n_rigid: int
    sigma: float
    backend: str

    @property
    def frequencies_hz(self) -> np.ndarray:
        """f = sqrt(lambda) / 2 pi, Hz (signed: a slightly negative rigid lambda gives -f)."""
        lam = self.eigenvalues
        return np.sign(lam) * np.sqrt(np.abs(lam)) / (2.0 * np.pi)


def spectral_scale(K: sp.spmatrix, M: sp.spmatrix) -> float:
    """median(diag K / diag M): an element-level eigenvalue scale (rad/s)^2 ~ (c/h)^2."""
    dk, dm = K.diagonal(), M.diagonal()
    ok = dm > 0
    if not ok.any():
        raise InputError("mass matrix has no positive diagonal entry; check the density")
    return float(np.median(dk[ok] / dm[ok]))


def rigid_body_modes(points: np.ndarray) -> np.ndarray:
    """The 6 rigid-body displacement fields (3 translations, 3 small rotations about the
    centroid) of nodes ``points`` (n, 3), as a (3n, 6) array in node-interleaved DOF order."""
    x = points - points.mean(axis=0)
    n = len(points)
    R = np.zeros((n, 3, 6))
    R[:, 0, 0] = R[:, 1, 1] = R[:, 2, 2] = 1.0
    # rotation about axis e_k: u = e_k x r
    R[:, 1, 3], R[:, 2, 3] = -x[:, 2], x[:, 1]
    R[:, 0, 4], R[:, 2, 4] = x[:, 2], -x[:, 0]
    R[:, 0, 5], R[:, 1, 5] = -x[:, 1], x[:, 0]
    return R.reshape(3 * n, 6)


def n_components(K: sp.spmatrix) -> int:
    """Number of connected parts of the sparsity graph of K."""
    return int(csgraph.connected_components(K, directed=False)[0])


@dataclass(frozen=True)
class Restriction:
    """Selects free DOFs: ``restrict(A)`` -> A[free][:, free], ``expand(v)`` puts zeros back."""

    free: np.ndarray
    n: int

    def restrict(self, A: sp.spmatrix) -> sp.csr_matrix:
        A = sp.csr_matrix(A)
        return A[self.free][:, self.free].tocsr()

    def expand(self, v: np.ndarray) -> np.ndarray:
        out = np.zeros((self.n,) + v.shape[1:], dtype=v.dtype)
        out[self.free] = v
        return out


def clamp_dofs(n_dof: int, fixed: np.ndarray) -> Restriction:
    """The restriction to all DOFs except ``fixed`` (DOF indices)."""
    mask = np.ones(n_dof, dtype=bool)
    mask[np.asarray(fixed, dtype=np.int64)] = False
    return Restriction(free=np.flatnonzero(mask), n=n_dof)


def node_dofs(nodes: np.ndarray) -> np.ndarray:
    """All three DOFs 3*i + c of the nodes ``nodes``."""
    nodes = np.asarray(nodes, dtype=np.int64)
    return (3 * nodes[:, None] + np.arange(3)[None]).ravel()


def _residuals(K, M, lam, phi, scale, rigid):
    Kphi = K @ phi
    Mphi = M @ phi
    r = np.linalg.norm(Kphi - Mphi * lam[None], axis=0)
    denom = np.where(rigid, scale * np.linalg.norm(Mphi, axis=0), np.linalg.norm(Kphi, axis=0))
    return r / denom


def rigid_mode_count(lam: np.ndarray, scale: float, n_rigid_max: int | None = None) -> int:
    """Number of rigid-body (zero-frequency) modes at the start of the ascending spectrum ``lam``.

    They are identified by what they are, not by one absolute bound: at most ``n_rigid_max`` (6 per
    free part), all at round-off level against the element scale ``scale`` (RIGID_LOOSE_REL, loose),
    and followed by the largest gap of the leading spectrum, a ratio of at least RIGID_GAP.  A
    clamped soft body (first elastic lambda far below any absolute bound) has no such gap.
    """
    lam = np.asarray(lam, dtype=float)
    cap = len(lam) - 1 if n_rigid_max is None else min(int(n_rigid_max), len(lam) - 1)  # a gap needs a mode after
    floor = np.finfo(float).eps * scale                  # round-off level of a zero eigenvalue
    best, best_gap = 0, RIGID_GAP
    for r in range(1, cap + 1):
        low = float(np.abs(lam[:r]).max())
        if low > RIGID_LOOSE_REL * scale:
            break
        gap = lam[r] / max(low, floor)
        if gap >= best_gap:
            best, best_gap = r, gap
    return best


def _finish(K, M, lam, phi, sigma, scale, backend, n_rigid_max=None) -> EigenResult:
    order = np.argsort(lam)
    lam, phi = lam[order], phi[:, order]
    phi = phi / np.sqrt(np.einsum("ij,ij->j", phi, M @ phi))[None]
    # deterministic sign: largest-magnitude entry positive
    idx = np.argmax(np.abs(phi), axis=0)
    phi = phi * np.sign(phi[idx, np.arange(phi.shape[1])])[None]
    rigid = np.arange(len(lam)) < rigid_mode_count(lam, scale, n_rigid_max)
    return EigenResult(eigenvalues=lam, vectors=phi, residuals=_residuals(K, M, lam, phi, scale, rigid),
                       n_rigid=int(rigid.sum()), sigma=sigma, backend=backend)


def single_threaded_blas():
    """Context: one thread in every BLAS loaded - numpy/scipy's OpenBLAS and the MKL that
    ``fast_blas`` interposes under CHOLMOD (loaded first so that the limit reaches it).  With two
    BLAS threads on the shared 2-core machine the Lanczos phase of a 17k-DOF bar took 9 s instead
    of 0.56 s and the piston rod's factorisation 20x longer (docs/performance.md)."""

    fast_blas()
    return threadpool_limits(limits=1, user_api="blas")


def all_cores_blas():
    """Context: one BLAS thread per core, for large dense work (LAPACK on blocks of thousands) while
    nothing else computes - a reduction in parts' driver between rounds of part tasks (its workers
    wait): the interface eigenproblems of a 2600-DOF cut 1.6x faster on 2 idle cores."""

    fast_blas()
    return threadpool_limits(limits=os.cpu_count() or 1, user_api="blas")


def _start_vector(n: int) -> np.ndarray:
    return np.random.default_rng(START_SEED).standard_normal(n)


def _lanczos(K, M, k, sigma, solver) -> tuple[np.ndarray, np.ndarray]:
    n = K.shape[0]
    OPinv = spla.LinearOperator((n, n), matvec=solver.solve, dtype=np.float64)
    if k >= n - 1:
        raise InputError(f"eigen solve: {k} modes of a {n}-DOF problem; Lanczos gives at most {n - 2}")
    lam, phi = spla.eigsh(K, k=k, M=M, sigma=sigma, which="LM", OPinv=OPinv, tol=ARPACK_TOL,
                          v0=_start_vector(n))
    return lam, phi


def _dense_modes(K, M) -> tuple[np.ndarray, np.ndarray]:
    """All eigenpairs of a small problem by LAPACK (generalized symmetric-definite eigh)."""

    try:
        return sla.eigh(K.toarray(), M.toarray())
    except np.linalg.LinAlgError as exc:
        raise InputError(f"the mass matrix is not positive definite ({exc}); check the density and the mesh") from None


def _lobpcg_solver(K, M, sigma, near_null):
    """k -> lowest (lambda, phi) by LOBPCG on K - sigma M with a smoothed-aggregation AMG
    V-cycle as preconditioner (near-null space: the rigid-body fields, if given)."""
    import pyamg  # deferred: 1 s import, AMG only

    A = (K - sigma * M).tocsr()
    ml = pyamg.smoothed_aggregation_solver(A, B=near_null, symmetry="symmetric", strength="symmetric",
                                           max_coarse=500)
    precond = ml.aspreconditioner(cycle="V")
    tol = LOBPCG_RTOL * abs(sigma) * np.sqrt(M.diagonal().mean())

    def solve(k):
        X = np.random.default_rng(START_SEED).standard_normal((K.shape[0], k))
        if near_null is not None:  # rigid-body fields span the lowest modes of a free body well
            X[:, : min(k, near_null.shape[1])] = near_null[:, :k]
        mu, phi = spla.lobpcg(A, X, B=M, M=precond, largest=False, tol=tol, maxiter=LOBPCG_MAXITER)
        return mu + sigma, phi

    return solve


def eigen_modes(K: sp.spmatrix, M: sp.spmatrix, *, count: int | None = None, fmax: float | None = None,
                backend: str = "auto", sigma: float | None = None, n_rigid_max: int | None = None,
                near_null: np.ndarray | None = None, phases=None, extent=None,
                memory_limit: float | None = None) -> EigenResult:
    """Lowest modes of K phi = lambda M phi (symmetric K >= 0, M > 0, both (n, n) sparse).

    Parameters
    ----------
    count : number of ELASTIC modes wanted; rigid-body modes (lambda ~ 0) are returned in
        addition, first.  Exactly one of ``count`` / ``fmax`` must be given.
    fmax : Hz; all modes with f <= fmax (the block grows until a mode above fmax is found).
    backend : "auto" | "cholmod" | "superlu" (shift-invert Lanczos) | "lobpcg" (AMG-LOBPCG) |
        "dense" (LAPACK, all modes; "auto" picks it below DENSE_MAX_DOF).
    sigma : shift (rad/s)^2, negative; default -SHIFT_REL * spectral_scale(K, M).
    n_rigid_max : upper bound of the rigid-mode count (6 per free part, 0 for a clamped part): sizes
        the block and caps ``rigid_mode_count``; default 6 x connected parts of K.
    near_null : (n, m) rigid-body fields for the AMG near-null space (lobpcg backend only).
    phases : sidprep.progress.Phases, optional; times "factorize" and "eigen" (progress on stderr),
        and notes the memory estimate and the backend "auto" chose.
    extent : (3,) bounding box of the body, m, for the memory estimate (default: a cube)
    memory_limit : bytes the run may use for "auto" (default ``available_memory_bytes()``)
    """
    if (count is None) == (fmax is None):
        raise InputError("modes: give exactly one of --count N or --fmax HZ")
    if count is not None and count < 1:
        raise InputError(f"--count {count}: must be >= 1")
    if fmax is not None and not fmax > 0:
        raise InputError(f"--fmax {fmax}: must be > 0 Hz")
    if backend not in EIGEN_BACKENDS:
        raise InputError(f"--backend {backend}: unknown eigen solver backend; use {', '.join(EIGEN_BACKENDS)}")
    K, M = sp.csr_matrix(K), sp.csr_matrix(M)
    n = K.shape[0]
    scale = spectral_scale(K, M)
    if sigma is None:
        sigma = -SHIFT_REL * scale
    if not sigma < 0:
        raise InputError(f"--sigma {sigma}: the shift must be negative (K - sigma M must be positive definite)")
    extra = 6 * n_components(K) if n_rigid_max is None else n_rigid_max
    phase = phases if phases is not None else (lambda name, detail="": contextlib.nullcontext())
    k = (count if count is not None else FMAX_FIRST_COUNT) + extra

    if backend == "dense" or (backend == "auto" and n <= DENSE_MAX_DOF) or 2 * k >= n:
        if n > DENSE_ALL_MAX_DOF:
            raise InputError(f"modes: {k} modes asked of a {n}-DOF model (nearly all of them); ask for fewer "
                             "(--count / --modes / --fmax)")
        with phase("eigen", f"all {n} modes, dense LAPACK"):
            lam, phi = _dense_modes(K, M)
        res = _finish(K, M, lam, phi, sigma, scale, "dense", extra)
    else:
        if backend == "auto":
            backend = _auto_backend(K, k, extent, memory_limit, phases)
        res = _iterative_modes(K, M, count, fmax, backend, sigma, scale, extra, near_null, phase)
    keep = res.n_rigid + (count if count is not None else int((res.frequencies_hz[res.n_rigid:] <= fmax).sum()))
    keep = min(keep, len(res.eigenvalues))
    return EigenResult(eigenvalues=res.eigenvalues[:keep], vectors=res.vectors[:, :keep],
                       residuals=res.residuals[:keep], n_rigid=res.n_rigid, sigma=sigma, backend=res.backend)


def _auto_backend(K, k, extent, memory_limit, phases) -> str:
    """Direct or AMG-LOBPCG by the memory estimate (InputError when neither fits); noted on stderr."""
    est = estimate_peak_memory(K.shape[0], K.nnz, extent, n_modes=k)
    backend = choose_backend(est, memory_limit)
    if phases is not None:
        phases.note(f"{est.describe()}; backend {backend}")
    return backend


def _iterative_modes(K, M, count, fmax, backend, sigma, scale, extra, near_null, phase) -> EigenResult:
    """Shift-invert Lanczos or AMG-LOBPCG with a block that grows until ``count`` elastic modes
    (or one above ``fmax``) are in."""
    n = K.shape[0]
    if backend == "lobpcg":
        with phase("preconditioner", "smoothed-aggregation AMG"):
            solve = _lobpcg_solver(K, M, sigma, near_null)
        used = "lobpcg"
    else:
        try:
            with phase("factorize", f"K - sigma M, {n} DOF"):
                solver = factorize_shifted(K, M, sigma, backend)
        except np.linalg.LinAlgError as exc:
            raise InputError(f"K - sigma M is not positive definite ({exc}); the stiffness or mass "
                             "matrix is not symmetric positive semi-definite - check the mesh") from None
        used = solver.backend

        def solve(k):
            return _lanczos(K, M, k, sigma, solver)

    k = (count if count is not None else FMAX_FIRST_COUNT) + extra
    while True:
        k = min(k, n - 2)
        with phase("eigen", f"{k} modes, {used}"), single_threaded_blas():
            lam, phi = solve(k)
        res = _finish(K, M, lam, phi, sigma, scale, used, extra)
        n_elastic = len(lam) - res.n_rigid
        if k >= n - 2:
            return res
        if count is not None and n_elastic >= count:
            return res
        if fmax is not None and res.frequencies_hz[-1] > fmax:
            return res
        k = k + (count - n_elastic if count is not None else k * (FMAX_GROWTH - 1))
