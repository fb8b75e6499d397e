"""The out-of-plane reactions of a planar run (integrators/planar.py): the reactions of the dropped
out-of-plane rows balance the out-of-plane equations of motion; their least-norm solution from the
independent equations, picked once per stretch of samples.
"""

from libc.math cimport NAN, fabs, sqrt
from libc.stdint cimport int64_t
from libc.stdlib cimport free, malloc

import numpy as np

from scipy.linalg.cython_lapack cimport dgelsd

from sidprep.solver.core.records cimport Evaluation

#: relative size (of the largest row norm, resp. the largest entry of a_I a_I^T) below which
#: the out-of-plane equations count as dependent (independent_equations, minimum_norm_solution)
RANK_TOL = 1e-12
#: relative residual of an out-of-plane equation above which the rows picked once per run no
#: longer span it (minimum_norm_solution falls back to lstsq)
RESIDUAL_TOL = 1e-10
cdef double C_RANK_TOL = RANK_TOL
cdef double C_RESIDUAL_TOL = RESIDUAL_TOL
#: double precision's machine epsilon (lstsq's rcond per unit of the larger size)
cdef double EPS = np.finfo(np.float64).eps


cdef class PlanarWork:
    """Scratch of the out-of-plane reactions of no equations in nd reactions (planar.pxd)."""

    def __init__(self, Py_ssize_t no, Py_ssize_t nd):
        self.a = np.zeros((no, nd))
        self.load = np.zeros(no)
        self.x = np.zeros(nd)
        self.rows = np.zeros(min(no, nd), np.int64)
        self.r = 0
        self.g = np.zeros((no, no))
        self.z = np.zeros(no)


cpdef PlanarWork planar_work(Py_ssize_t no, Py_ssize_t nd):
    """The scratch of the out-of-plane reactions of no equations in nd reactions (no independent
    rows picked yet)."""
    return PlanarWork(no, nd)


cpdef void out_of_plane_system(Evaluation e, const double[::1] ud, const double[::1] lam_full,
                               const int64_t[::1] planar_rows, const int64_t[::1] dropped, const int64_t[::1] fixed,
                               double[:, ::1] a, double[::1] load) noexcept nogil:
    """The out-of-plane equations of motion (the coordinates ``fixed``, no) in the reactions of
    the dropped rows (nd): a (no, nd) = B_F[dropped, fixed]^T and load (no,) = -(M ud - f +
    B_F^T lambda)[fixed] with lambda the planar run's multipliers lam_full (m_all,; zero on the
    dropped rows); e the Evaluation at the sample's state, ud (n,) its accelerations,
    planar_rows the rows the run kept.  Written into a and load."""
    cdef Py_ssize_t i, j, d, o, r
    cdef double acc
    for i in range(fixed.shape[0]):
        o = fixed[i]
        acc = -e.f[o]
        for j in range(ud.shape[0]):
            acc += e.M[o, j] * ud[j]
        for j in range(planar_rows.shape[0]):
            r = planar_rows[j]
            acc += e.BF[r, o] * lam_full[r]
        load[i] = -acc
        for d in range(dropped.shape[0]):
            a[i, d] = e.BF[dropped[d], o]


cpdef Py_ssize_t independent_equations(const double[:, ::1] a, int64_t[::1] rows) noexcept:
    """Rows of a (no, nd) that span its row space: Gram-Schmidt with pivoting on the largest
    remaining norm (QR with column pivoting of a^T), stopped at RANK_TOL times the largest row
    norm; written sorted into rows[:r] (rows: >= min(no, nd) entries), r the rank of a, returned."""
    cdef Py_ssize_t no = a.shape[0], nd = a.shape[1], i, d, best, r = 0, top = min(no, nd)
    cdef double size, proj, cutoff, largest = 0.0, acc
    cdef double *rest = <double *> malloc((no * nd + no + 1) * sizeof(double))
    cdef double *norms = rest + no * nd
    cdef char *chosen = <char *> malloc(no + 1)
    cdef int64_t swap
    for i in range(no):
        chosen[i] = 0
        acc = 0.0
        for d in range(nd):
            rest[i * nd + d] = a[i, d]
            acc += a[i, d] * a[i, d]
        norms[i] = sqrt(acc)
        largest = max(largest, norms[i])
    cutoff = C_RANK_TOL * max(no, nd) * max(largest, 1e-300)
    while r < top:
        best, size = -1, cutoff
        for i in range(no):
            if not chosen[i] and norms[i] > size:
                best, size = i, norms[i]
        if best < 0:
            break
        chosen[best] = 1
        rows[r] = best
        r += 1
        for i in range(no):  # each remaining row minus its projection on q = rest[best] / size
            if not chosen[i]:
                proj = 0.0
                for d in range(nd):
                    proj += rest[i * nd + d] * (rest[best * nd + d] / size)
                acc = 0.0
                for d in range(nd):
                    rest[i * nd + d] -= proj * (rest[best * nd + d] / size)
                    acc += rest[i * nd + d] * rest[i * nd + d]
                norms[i] = sqrt(acc)
    free(rest)
    free(chosen)
    for i in range(1, r):  # insertion sort of the picked rows
        swap = rows[i]
        d = i
        while d > 0 and rows[d - 1] > swap:
            rows[d] = rows[d - 1]
            d -= 1
        rows[d] = swap
    return r


cpdef void minimum_norm_solution(const double[:, ::1] a, const double[::1] load, const int64_t[::1] rows,
                                 double[:, ::1] g, double[::1] z, double[::1] x) noexcept nogil:
    """x (nd,) of least norm with a x = load (a (no, nd) of rank r, load in its range), from the
    independent rows ``rows`` (r,; independent_equations): x = a_I^T z, (a_I a_I^T) z = load_I,
    a Cholesky factorisation of r x r (g (>= r, >= r), z (>= r,) scratch).  LAPACK's least-squares
    solution (lstsq, an SVD) instead when a_I a_I^T is not positive definite to RANK_TOL or, with
    r < no, x leaves a row of a unsolved (solves): the rank changed since the rows were picked."""
    cdef Py_ssize_t r = rows.shape[0], nd = a.shape[1], i, j, k, d
    cdef double acc, diag, scale = 1e-300  # the largest entry of a_I a_I^T, on its diagonal
    for i in range(r):  # a_I a_I^T, then its Cholesky factor (lower)
        for j in range(i + 1):
            acc = 0.0
            for d in range(nd):
                acc += a[rows[i], d] * a[rows[j], d]
            g[i, j] = acc
    for i in range(r):
        scale = max(scale, g[i, i])
    for j in range(r):
        diag = g[j, j]
        for k in range(j):
            diag -= g[j, k] * g[j, k]
        if diag <= C_RANK_TOL * scale:
            lstsq(a, load, x)
            return
        g[j, j] = sqrt(diag)
        for i in range(j + 1, r):
            acc = g[i, j]
            for k in range(j):
                acc -= g[i, k] * g[j, k]
            g[i, j] = acc / g[j, j]
    for i in range(r):  # forward, then backward substitution
        acc = load[rows[i]]
        for k in range(i):
            acc -= g[i, k] * z[k]
        z[i] = acc / g[i, i]
    for i in range(r - 1, -1, -1):
        acc = z[i]
        for k in range(i + 1, r):
            acc -= g[k, i] * z[k]
        z[i] = acc / g[i, i]
    for d in range(nd):
        x[d] = 0.0
    for i in range(r):
        for d in range(nd):
            x[d] += a[rows[i], d] * z[i]
    if r < a.shape[0] and not solves(a, x, load):
        lstsq(a, load, x)


cpdef bint solves(const double[:, ::1] a, const double[::1] x, const double[::1] load) noexcept nogil:
    """|a x - load| <= RESIDUAL_TOL (|a| |x| + |load|) in every row of a (no, nd)."""
    cdef Py_ssize_t i, d
    cdef double acc, size
    for i in range(a.shape[0]):
        acc, size = -load[i], fabs(load[i])
        for d in range(a.shape[1]):
            acc += a[i, d] * x[d]
            size += fabs(a[i, d] * x[d])
        if fabs(acc) > C_RESIDUAL_TOL * size:
            return False
    return True


cpdef void lstsq(const double[:, ::1] a, const double[::1] load, double[::1] x) noexcept nogil:
    """x (nd,) of least norm minimising |a x - load| (a (no, nd)): LAPACK dgelsd (an SVD) at rcond
    = machine epsilon times the larger size of a, as numpy's lstsq; NaN if it fails."""
    cdef int m = <int> a.shape[0], n = <int> a.shape[1], nrhs = 1, lda = max(m, 1), ldb = max(m, n, 1)
    cdef int rank = 0, lwork = -1, info = 0, liwork = 0, i, d
    cdef double rcond = EPS * max(m, n), query = 0.0
    cdef int iquery = 0
    cdef double *fa
    cdef double *fb
    cdef double *sv
    cdef double *work = NULL
    cdef int *iwork = NULL
    if n == 0:
        return
    fa = <double *> malloc((lda * n + ldb + min(m, n) + 1) * sizeof(double))
    fb = fa + lda * n
    sv = fb + ldb
    for i in range(m):  # column-major copy of a, and the right-hand side
        for d in range(n):
            fa[d * lda + i] = a[i, d]
    for i in range(ldb):
        fb[i] = load[i] if i < m else 0.0
    dgelsd(&m, &n, &nrhs, fa, &lda, fb, &ldb, sv, &rcond, &rank, &query, &lwork, &iquery, &info)
    lwork = max(<int> query, 1)
    liwork = max(iquery, 1)
    work = <double *> malloc(lwork * sizeof(double))
    iwork = <int *> malloc(liwork * sizeof(int))
    if m > 0:
        dgelsd(&m, &n, &nrhs, fa, &lda, fb, &ldb, sv, &rcond, &rank, work, &lwork, iwork, &info)
    for d in range(n):
        x[d] = (fb[d] if m > 0 else 0.0) if info == 0 else NAN
    free(work)
    free(iwork)
    free(fa)


cpdef void out_of_plane_reactions(Evaluation e, const double[::1] ud, double[::1] lam_full,
                                  const int64_t[::1] planar_rows, const int64_t[::1] dropped,
                                  const int64_t[::1] fixed, PlanarWork w) noexcept nogil:
    """The multipliers of all 3D rows from those of a planar run (lam_full (m_all,), zero on the
    dropped rows; the dropped rows' reactions written into it): the reactions of the dropped
    out-of-plane rows ``dropped`` balance the out-of-plane equations of motion (the coordinates
    ``fixed``; out_of_plane_system), the solution of least norm (the dropped rows may be
    redundant); w.rows[:w.r] the independent equations, picked once per stretch
    (independent_equations of the first sample's system).  The equations are consistent
    (planar_coordinates checked it), so this is the least-squares solution."""
    cdef Py_ssize_t d
    if dropped.shape[0] == 0:
        return
    out_of_plane_system(e, ud, lam_full, planar_rows, dropped, fixed, w.a, w.load)
    minimum_norm_solution(w.a, w.load, w.rows[:w.r], w.g, w.z, w.x)
    for d in range(dropped.shape[0]):
        lam_full[dropped[d]] = w.x[d]
