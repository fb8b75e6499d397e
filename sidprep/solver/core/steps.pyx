"""What every integrator's step shares, compiled: the output sample buffers, the multipliers of
all rows from the kept ones, the Lie-group pose update, the LU factors and solve (LAPACK dgetrf),
the system restricted to the integrated coordinates and kept rows, its KKT solve, the
constraint convection gamma and the index-1 accelerations with their multipliers.

All kernels write into output arguments (the run's workspaces: SampleBuffers, Index1Workspace,
the Evaluation of records.evaluation_arrays) and allocate nothing; ``state_equations`` is the
entry for callers in Python (a fresh workspace per call).
"""

from collections import namedtuple

import numpy as np

from libc.math cimport NAN, fabs
from libc.stdint cimport int64_t
from scipy.linalg.cython_lapack cimport dgetrf

from sidprep.solver.core.assemble cimport evaluate_into
from sidprep.solver.core.forces cimport FE_FRICTION, FE_INT_KIND
from sidprep.solver.core.records cimport Evaluation, Layout
from sidprep.solver.core.rotations cimport exp_so3, se3_jacobian

from sidprep.solver.core.records import evaluation_arrays

#: s, time step of the central difference giving gamma = d/dt (B u + b_t)
GAMMA_STEP = 1e-6
#: friction reads the multipliers: the index-1 solve is repeated until they change by less than
#: this, relative to the largest (a fixed count left an error of the order of the previous call's
#: change, and RK4 fell to order 1.2-1.4 on the seed slider crank; docs/accuracy-cost.md)
MULTIPLIER_RTOL = 1e-10
#: contacts: a step from an open bump stop that is closing reaches at most this multiple of the
#: time to close its gap (genalpha, explicit; the kink itself is then located)
APPROACH_REACH = 2.0

#: the output samples of one call of a compiled loop as numpy arrays: t (k,), R (k, nb, 3),
#: A (k, nb, 3, 3), Q (k, nq), u, ud (k, n), lam (k, m), refs (k, nj), work (k, 3)
SampleArrays = namedtuple("SampleArrays", ["t", "R", "A", "Q", "u", "ud", "lam", "refs", "work"])


cdef class SampleBuffers:
    """The output samples of one call of a compiled loop (steps.pxd; made by sample_buffers)."""


cdef class Index1Workspace:
    """Scratch of the index-1 solve (steps.pxd; made by index1_workspace)."""


cpdef SampleBuffers sample_buffers(Py_ssize_t capacity, const double[:, ::1] R, const double[::1] Q,
                                   const double[::1] u, const double[::1] lam, const double[::1] refs):
    """Empty SampleBuffers of ``capacity`` rows for states shaped like R, Q, u, lam, refs."""
    cdef Py_ssize_t n = u.shape[0], nb = R.shape[0]
    cdef SampleBuffers buf = SampleBuffers.__new__(SampleBuffers)
    arrays = SampleArrays(np.empty(capacity), np.empty((capacity, nb, 3)), np.empty((capacity, nb, 3, 3)),
                          np.empty((capacity, Q.shape[0])), np.empty((capacity, n)), np.empty((capacity, n)),
                          np.empty((capacity, lam.shape[0])), np.empty((capacity, refs.shape[0])),
                          np.empty((capacity, 3)))
    buf.t, buf.R, buf.A, buf.Q, buf.u, buf.ud, buf.lam, buf.refs, buf.work = arrays
    buf.arrays = arrays
    return buf


cpdef object first_samples(SampleBuffers buf, Py_ssize_t count):
    """The first ``count`` rows of the SampleBuffers buf: a SampleArrays of numpy views."""
    return SampleArrays(*[a[:count] for a in buf.arrays])


cdef inline void put_row(double[::1] dst, const double[::1] src) noexcept nogil:
    """dst[:] = src (same length)."""
    cdef Py_ssize_t i
    for i in range(src.shape[0]):
        dst[i] = src[i]


cpdef void store_sample(SampleBuffers buf, Py_ssize_t k, double t, const double[:, ::1] R,
                        const double[:, :, ::1] A, const double[::1] Q, const double[::1] u,
                        const double[::1] ud, const double[::1] lam, const double[::1] refs,
                        const double[::1] work) noexcept nogil:
    """Write one output sample into row k of the SampleBuffers buf."""
    cdef Py_ssize_t i, a, j
    buf.t[k] = t
    for i in range(R.shape[0]):
        for a in range(3):
            buf.R[k, i, a] = R[i, a]
            for j in range(3):
                buf.A[k, i, a, j] = A[i, a, j]
    put_row(buf.Q[k], Q)
    put_row(buf.u[k], u)
    put_row(buf.ud[k], ud)
    put_row(buf.lam[k], lam)
    put_row(buf.refs[k], refs)
    put_row(buf.work[k], work)


cpdef void expand(const double[::1] lam, const int64_t[::1] kept, double[::1] out) noexcept nogil:
    """Multipliers of all rows, written into out (m_all,; zero on the dropped rows), from those
    of the kept rows."""
    cdef Py_ssize_t k
    for k in range(out.shape[0]):
        out[k] = 0.0
    for k in range(kept.shape[0]):
        out[kept[k]] = lam[k]


cpdef void advance_pose(Layout L, const double[:, ::1] R, const double[:, :, ::1] A, const double[::1] Q,
                        const double[::1] dx, bint body_frame, double[:, ::1] R2, double[:, :, ::1] A2,
                        double[::1] Q2) noexcept nogil:
    """Positions R2, A2, Q2 = the pose moved by the increment dx (n,): r + dr, A exp(dtheta),
    q + dq (Lie group R^3 x SO(3)); ``body_frame``: dr in body components, moved along the SE(3)
    exponential, r + A V(dtheta) dr (rotations.se3_jacobian; se3.pyx).  R2, A2, Q2 may be R, A, Q."""
    cdef Py_ssize_t i, a, j, k, s, q0
    cdef double theta[3]
    cdef double y[3]
    cdef double V[9]
    cdef double E[9]
    cdef double Ai[9]
    cdef double acc
    for i in range(R.shape[0]):
        s = L.uoff[i]
        for a in range(3):
            theta[a] = dx[s + 3 + a]
            for j in range(3):
                Ai[3 * a + j] = A[i, a, j]
        if body_frame:
            se3_jacobian(theta, V)
            for a in range(3):  # V dr
                y[a] = V[3 * a] * dx[s] + V[3 * a + 1] * dx[s + 1] + V[3 * a + 2] * dx[s + 2]
            for a in range(3):
                R2[i, a] = R[i, a] + (Ai[3 * a] * y[0] + Ai[3 * a + 1] * y[1] + Ai[3 * a + 2] * y[2])
        else:
            for a in range(3):
                R2[i, a] = R[i, a] + dx[s + a]
        exp_so3(theta, E)
        for a in range(3):  # A exp(theta~)
            for k in range(3):
                acc = 0.0
                for j in range(3):
                    acc += Ai[3 * a + j] * E[3 * j + k]
                A2[i, a, k] = acc
        q0 = L.qoff[i]
        for k in range(L.qoff[i + 1] - q0):
            Q2[q0 + k] = Q[q0 + k] + dx[s + 6 + k]


cpdef int lu_factor(double[:, ::1] a, int[::1] piv) noexcept nogil:
    """LU factors of a (k, k) in place by LAPACK dgetrf, pivots piv (k,) (LAPACK's 1-based row
    interchanges); returns dgetrf's info (> 0: singular).  The row-major a is the column-major
    a^T, so a then holds a^T = P L U; lu_solve solves with it."""
    cdef int k = <int> a.shape[0]
    cdef int info = 0
    if k > 0:
        dgetrf(&k, &k, &a[0, 0], &k, &piv[0], &info)
    return info


cpdef void lu_solve(const double[:, ::1] lu, const int[::1] piv, const double[::1] b, double[::1] x) noexcept nogil:
    """x (k,) with a x = b from lu_factor(a): a = U^T L^T P^T, so U^T L^T w = b and x = P w (NaN
    where a is singular); x may be b."""
    cdef Py_ssize_t k = b.shape[0], i, c, p
    cdef double acc, pivot, swap
    for i in range(k):  # U^T (lower; U(j, i) is lu[i, j])
        acc = b[i]
        for c in range(i):
            acc -= lu[i, c] * x[c]
        pivot = lu[i, i]  # exactly 0 for a singular a: NaN, not an exception, so the callers'
        x[i] = acc / pivot if pivot != 0.0 else NAN  # non-finite checks name the cause
    for i in range(k - 1, -1, -1):  # L^T (unit upper; L(j, i) is lu[i, j])
        acc = x[i]
        for c in range(i + 1, k):
            acc -= lu[i, c] * x[c]
        x[i] = acc
    for i in range(k - 1, -1, -1):  # x = P w: the interchanges in reverse order
        p = piv[i] - 1
        swap = x[i]
        x[i] = x[p]
        x[p] = swap


cpdef void restrict(const double[:, ::1] M, const double[::1] f, const double[:, ::1] B, const double[:, ::1] BF,
                    const int64_t[::1] free, const int64_t[::1] kept, double[:, ::1] Mf, double[::1] ff,
                    double[:, ::1] Bk, double[:, ::1] BFk) noexcept nogil:
    """M, f, B, B_F restricted to the integrated coordinates ``free`` and the kept rows: Mf (nf, nf),
    ff (nf,), Bk, BFk (m, nf)."""
    cdef Py_ssize_t nf = free.shape[0], m = kept.shape[0], i, j, k
    for i in range(nf):
        ff[i] = f[free[i]]
        for j in range(nf):
            Mf[i, j] = M[free[i], free[j]]
        for k in range(m):
            Bk[k, i] = B[kept[k], free[i]]
            BFk[k, i] = BF[kept[k], free[i]]


cpdef void kkt_solve(const double[:, ::1] M, const double[::1] f, const double[:, ::1] B, const double[:, ::1] BF,
                     const double[::1] rhs, double[:, ::1] K, int[::1] piv, double[::1] z) noexcept nogil:
    """[M B_F^T; B 0] [x; lambda] = [f; rhs] -> z = [x; lambda] (n + m,), with the scratch K
    (n + m, n + m) (it holds the LU factors afterwards) and piv (n + m,)."""
    cdef Py_ssize_t n = M.shape[0], m = B.shape[0], i, j
    for i in range(n + m):
        for j in range(n + m):
            K[i, j] = 0.0
    for i in range(n):
        z[i] = f[i]
        for j in range(n):
            K[i, j] = M[i, j]
    for i in range(m):
        z[n + i] = rhs[i]
        for j in range(n):
            K[j, n + i] = BF[i, j]
            K[n + i, j] = B[i, j]
    lu_factor(K, piv)
    lu_solve(K, piv, z, z)


cpdef Index1Workspace index1_workspace(Layout L, Py_ssize_t nfree, Py_ssize_t nkept):
    """The scratch of index1_accelerations for layout L, nfree integrated coordinates and nkept
    kept rows (once per run)."""
    cdef Py_ssize_t nb = L.uoff.shape[0] - 1
    cdef Py_ssize_t n = L.uoff[nb], m_all = L.joint_off[L.joint_off.shape[0] - 1] + L.drv_joint.shape[0]
    cdef Index1Workspace ws = Index1Workspace.__new__(Index1Workspace)
    ws.Mf, ws.ff = np.zeros((nfree, nfree)), np.zeros(nfree)
    ws.Bk, ws.BFk = np.zeros((nkept, nfree)), np.zeros((nkept, nfree))
    ws.K, ws.piv, ws.z = np.zeros((nfree + nkept, nfree + nkept)), np.zeros(nfree + nkept, np.intc), np.zeros(nfree + nkept)
    ws.rhs, ws.gam, ws.lam_prev = np.zeros(nkept), np.zeros(nkept), np.zeros(nkept)
    ws.lam_all, ws.zero_all, ws.plus = np.zeros(m_all), np.zeros(m_all), np.zeros(m_all)
    ws.Rp, ws.Ap, ws.Qp, ws.dx = np.zeros((nb, 3)), np.zeros((nb, 3, 3)), np.zeros(L.qoff[nb]), np.zeros(n)
    return ws


cdef inline double constraint_rate(Evaluation e, const double[::1] u, Py_ssize_t r) noexcept nogil:
    """Row r of B u + b_t."""
    cdef Py_ssize_t j
    cdef double acc = 0.0
    for j in range(u.shape[0]):
        acc += e.B[r, j] * u[j]
    return acc + e.bt[r]


cpdef void constraint_convection(Layout L, Evaluation W, Index1Workspace ws, const double[:, ::1] R,
                                 const double[:, :, ::1] A, const double[::1] Q, const double[::1] u, double t,
                                 const double[::1] refs, const int64_t[::1] kept, double[::1] gam) noexcept nogil:
    """gam (kept,) = d/dt (B u + b_t) at constant u: the central difference of B u + b_t between
    the evaluations (into the workspace W) at the poses moved by +-GAMMA_STEP u (at
    t +- GAMMA_STEP), exact to O(1e-12) relative for the smooth constraint functions."""
    cdef Py_ssize_t i, k
    for i in range(u.shape[0]):
        ws.dx[i] = GAMMA_STEP * u[i]
    advance_pose(L, R, A, Q, ws.dx, False, ws.Rp, ws.Ap, ws.Qp)
    evaluate_into(L, W, ws.Rp, ws.Ap, ws.Qp, u, t + GAMMA_STEP, ws.zero_all, refs)
    for k in range(kept.shape[0]):
        ws.plus[k] = constraint_rate(W, u, kept[k])
    for i in range(u.shape[0]):
        ws.dx[i] = -GAMMA_STEP * u[i]
    advance_pose(L, R, A, Q, ws.dx, False, ws.Rp, ws.Ap, ws.Qp)
    evaluate_into(L, W, ws.Rp, ws.Ap, ws.Qp, u, t - GAMMA_STEP, ws.zero_all, refs)
    for k in range(kept.shape[0]):
        gam[k] = (ws.plus[k] - constraint_rate(W, u, kept[k])) / (2 * GAMMA_STEP)


cpdef bint has_friction(Layout L) noexcept nogil:
    """Whether a force element depends on the multipliers (friction): the index-1 solve then
    iterates on lambda."""
    cdef Py_ssize_t i
    for i in range(L.fe_int.shape[0]):
        if L.fe_int[i, FE_INT_KIND] == FE_FRICTION:
            return True
    return False


cpdef bint multipliers_settled(const double[::1] lam, const double[::1] lam_new) noexcept nogil:
    """|lam_new - lam| <= MULTIPLIER_RTOL max |lam_new| (or no multipliers); never with a NaN."""
    cdef Py_ssize_t k
    cdef double change = 0.0, largest = 0.0, d
    if lam.shape[0] == 0:
        return True
    for k in range(lam.shape[0]):
        d = fabs(lam_new[k] - lam[k])
        if d != d:
            return False
        change = max(change, d)
        largest = max(largest, fabs(lam_new[k]))
    return change <= MULTIPLIER_RTOL * largest


cpdef void index1_solve(Evaluation e, Index1Workspace ws, const double[::1] gam, const double[::1] u,
                        const int64_t[::1] free, const int64_t[::1] kept, double baumgarte, double[::1] ud,
                        double[::1] lam) noexcept nogil:
    """Accelerations ud (n,; zero outside ``free``) and kept multipliers lam of the index-1 form

        M ud + B_F^T lambda = f,   B ud = -gamma - 2 a g_dot - a^2 g   (a = baumgarte, 1/s)

    at the Evaluation e (u (n,) its velocities, gam (kept,) from constraint_convection)."""
    cdef Py_ssize_t nf = free.shape[0], m = kept.shape[0], i, k
    restrict(e.M, e.f, e.B, e.BF, free, kept, ws.Mf, ws.ff, ws.Bk, ws.BFk)
    for k in range(m):
        ws.rhs[k] = -gam[k]
    if baumgarte > 0.0 and m:
        for k in range(m):
            ws.rhs[k] = (ws.rhs[k] - 2.0 * baumgarte * constraint_rate(e, u, kept[k])
                         - baumgarte * baumgarte * e.g[kept[k]])
    kkt_solve(ws.Mf, ws.ff, ws.Bk, ws.BFk, ws.rhs, ws.K, ws.piv, ws.z)
    for i in range(ud.shape[0]):
        ud[i] = 0.0
    for i in range(nf):
        ud[free[i]] = ws.z[i]
    for k in range(m):
        lam[k] = ws.z[nf + k]


cpdef void index1_accelerations(Layout L, Evaluation W, Index1Workspace ws, const double[:, ::1] R,
                                const double[:, :, ::1] A, const double[::1] Q, const double[::1] u, double t,
                                const double[::1] refs, const int64_t[::1] free, const int64_t[::1] kept,
                                double baumgarte, const double[::1] lam_guess, double[::1] ud,
                                double[::1] lam) noexcept nogil:
    """Accelerations ud (n,) and kept multipliers lam of the index-1 form (index1_solve) at the
    state (R, A, Q, u, t), evaluated into the workspace W (records.evaluation_arrays; it holds
    the evaluation at the last guess of the multipliers afterwards), with the scratch ws
    (index1_workspace); iterated when forces depend on lambda (friction) until lambda changes by
    less than MULTIPLIER_RTOL of its largest entry, at most MULTIPLIER_ITERATIONS times
    (lam_guess (kept,) the first guess; lam may be lam_guess).  The start and the explicit loops
    call it."""
    cdef Py_ssize_t m = kept.shape[0], k, it
    cdef Py_ssize_t iterations = MULTIPLIER_ITERATIONS if has_friction(L) else 1
    cdef bint settled
    if m:
        constraint_convection(L, W, ws, R, A, Q, u, t, refs, kept, ws.gam)
    for k in range(m):
        ws.lam_prev[k] = lam_guess[k]
    for it in range(iterations):
        expand(ws.lam_prev, kept, ws.lam_all)
        evaluate_into(L, W, R, A, Q, u, t, ws.lam_all, refs)
        index1_solve(W, ws, ws.gam, u, free, kept, baumgarte, ud, lam)
        settled = multipliers_settled(ws.lam_prev, lam)
        for k in range(m):
            ws.lam_prev[k] = lam[k]
        if settled:
            break


cpdef tuple state_equations(Layout L, const double[:, ::1] R, const double[:, :, ::1] A, const double[::1] Q,
                            const double[::1] u, double t, const double[::1] lam, const double[::1] refs,
                            const int64_t[::1] free, const int64_t[::1] kept, bint solve):
    """The Evaluation at the state (R, A, Q, u, t) with the multipliers lam (m_all,), in a fresh
    workspace; when ``solve``, also the index-1 accelerations ud (n,) and the kept multipliers
    there (index1_accelerations without Baumgarte, lam[kept] the first guess; the Evaluation is
    then at the last guess), else two empty arrays.  The entry of the start and the other
    callers in Python."""
    cdef Evaluation W = evaluation_arrays(L)
    cdef Py_ssize_t k, m = kept.shape[0]
    if not solve:
        evaluate_into(L, W, R, A, Q, u, t, lam, refs)
        return W, np.zeros(0), np.zeros(0)
    guess = np.empty(m)
    cdef double[::1] g = guess
    for k in range(m):
        g[k] = lam[kept[k]]
    ud, lam_kept = np.zeros(u.shape[0]), np.empty(m)
    index1_accelerations(L, W, index1_workspace(L, free.shape[0], m), R, A, Q, u, t, refs, free, kept, 0.0, guess,
                         ud, lam_kept)
    return W, ud, lam_kept
