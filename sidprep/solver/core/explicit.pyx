"""Explicit Runge-Kutta methods on the index-1 form of the constrained equations:

    M ud + B_F^T lambda = f,   B ud = -gamma - 2 a g_dot - a^2 g    (Baumgarte, rate a in 1/s)

with the state y = [per body r_O (3), quaternion (4), q (nq); u (n); work (3)] (the work of
applied loads, the dissipated energy and the work of drivers are integrated with the motion, to
the method's order).  ``rk4_loop``: classic RK4 (Kutta 1901) at the fixed step h with its
samples' outputs; ``index1_rhs`` and ``sample`` also serve scipy's RK45 / DOP853
(integrators/adaptive.py).
"""

import numpy as np

from libc.math cimport fabs, isfinite
from libc.stdint cimport int64_t

from sidprep.solver.core.assemble cimport constraint_power, evaluate_into, moving_masses
from sidprep.solver.core.outputs cimport sample_outputs
from sidprep.solver.core.records cimport Evaluation, Layout
from sidprep.solver.core.rotations cimport quaternion_rate, quaternion_to_matrix
from sidprep.solver.core.runge_kutta cimport hermite, rk4_combine, rk4_stage
from sidprep.solver.core.steps cimport (SampleBuffers, expand, first_samples, has_friction, index1_accelerations,
                                        index1_workspace, sample_buffers, store_sample)

from sidprep.solver.core.records import evaluation_arrays


cdef class RhsParams:
    """What the right-hand side of a run needs, and its scratch (explicit.pxd; made by rhs_params)."""


cpdef RhsParams rhs_params(Layout L, const int64_t[::1] free, const int64_t[::1] kept, double[::1] refs,
                           double baumgarte, const double[::1] lam_guess):
    """The RhsParams of a run (made once per run): refs is the run's own array (sample updates it),
    lam_guess is copied."""
    cdef RhsParams p = RhsParams()
    cdef Py_ssize_t nb = L.qoff.shape[0] - 1, n = L.uoff[nb]
    p.L, p.free, p.kept, p.refs, p.baumgarte = L, free, kept, refs, baumgarte
    p.lam_guess = np.array(lam_guess, dtype=float)
    p.e = evaluation_arrays(L)
    p.ws = index1_workspace(L, free.shape[0], kept.shape[0])
    p.R, p.A, p.Q = np.zeros((nb, 3)), np.zeros((nb, 3, 3)), np.zeros(L.qoff[nb])
    p.u, p.ud = np.zeros(n), np.zeros(n)
    p.lam, p.lam_all = np.zeros(kept.shape[0]), np.zeros(p.e.g.shape[0])
    return p


cpdef void unpack(Layout L, const double[::1] y, double[:, ::1] R, double[:, :, ::1] A, double[::1] Q,
                  double[::1] u) noexcept nogil:
    """R (nb, 3), A (nb, 3, 3), Q, u of the explicit state y, written into R, A, Q, u."""
    cdef Py_ssize_t nb = L.qoff.shape[0] - 1, i, j, nq, o = 0
    for i in range(nb):
        nq = L.qoff[i + 1] - L.qoff[i]
        for j in range(3):
            R[i, j] = y[o + j]
        quaternion_to_matrix(&y[o + 3], &A[i, 0, 0])
        for j in range(nq):
            Q[L.qoff[i] + j] = y[o + 7 + j]
        o += 7 + nq
    for j in range(L.uoff[nb]):
        u[j] = y[o + j]


cpdef void index1_rhs(double t, const double[::1] y, RhsParams p, double[::1] ydot) noexcept nogil:
    """dy/dt (written into ydot) of the explicit state y at t: the index-1 accelerations
    (steps.index1_accelerations from the last solve's multipliers, which become the next guess),
    the quaternion rates and the power flows into the work integrals."""
    cdef Py_ssize_t nb = p.L.qoff.shape[0] - 1, n = p.u.shape[0], i, j, nq, s, o = 0
    cdef double power
    unpack(p.L, y, p.R, p.A, p.Q, p.u)
    index1_accelerations(p.L, p.e, p.ws, p.R, p.A, p.Q, p.u, t, p.refs, p.free, p.kept, p.baumgarte, p.lam_guess,
                         p.ud, p.lam)
    for j in range(p.lam.shape[0]):
        p.lam_guess[j] = p.lam[j]
    expand(p.lam, p.kept, p.lam_all)
    if has_friction(p.L):  # e holds the evaluation at the last guess: only friction reads lambda
        evaluate_into(p.L, p.e, p.R, p.A, p.Q, p.u, t, p.lam_all, p.refs)
    for i in range(nb):
        nq = p.L.qoff[i + 1] - p.L.qoff[i]
        s = p.L.uoff[i]
        for j in range(3):
            ydot[o + j] = p.u[s + j]
        quaternion_rate(&y[o + 3], &p.u[s + 3], &ydot[o + 3])
        for j in range(nq):
            ydot[o + 7 + j] = p.u[s + 6 + j]
        o += 7 + nq
    for j in range(n):
        ydot[o + j] = p.ud[j]
    ydot[o + n] = p.e.flows[0]
    ydot[o + n + 1] = p.e.flows[1]
    power = moving_masses(p.L, p.e.kin, p.R, p.A, p.Q, p.u, p.ud, t)[0]
    ydot[o + n + 2] = p.e.flows[3] + constraint_power(p.L, p.e.B, p.e.bt, p.u, p.lam_all) + power


cpdef void sample(double t, const double[::1] y, RhsParams p) noexcept nogil:
    """The state at an accepted y: R, A, Q, u, ud, lam written into p's (the work integrals are
    y's last three entries), the angle references p.refs updated to its joint angles."""
    cdef Py_ssize_t j
    unpack(p.L, y, p.R, p.A, p.Q, p.u)
    index1_accelerations(p.L, p.e, p.ws, p.R, p.A, p.Q, p.u, t, p.refs, p.free, p.kept, p.baumgarte, p.lam_guess,
                         p.ud, p.lam)
    for j in range(p.refs.shape[0]):  # the joint coordinates are kinematic: e's at any multipliers
        p.refs[j] = p.e.coords[j, 0]


cdef void store_state(SampleBuffers buf, Py_ssize_t k, double t, RhsParams p, const double[::1] y) noexcept nogil:
    """Row k of buf: the state that sample left in p at t, the work integrals of y."""
    cdef Py_ssize_t ny = y.shape[0]
    store_sample(buf, k, t, p.R, p.A, p.Q, p.u, p.ud, p.lam, p.refs, y[ny - 3:])


cdef bint all_finite(const double[::1] y) noexcept nogil:
    """Whether every entry of y is finite."""
    cdef Py_ssize_t i
    for i in range(y.shape[0]):
        if not isfinite(y[i]):
            return False
    return True


def rk4_loop(double t, y_start, double t_end, double h, double out_dt, Py_ssize_t next_index, RhsParams p,
             Py_ssize_t capacity, int64_t[::1] steps, first, post):
    """Fixed-step RK4 (runge_kutta.rk4_stage / rk4_combine around index1_rhs) from t to t_end
    (the last step shortened to land on it) or until ``capacity`` samples besides those of
    ``first``; steps (2,) counts the steps (up to max_steps, steps[1]); p.refs follow the accepted
    steps.  Samples: the rows of the SampleBuffers-like ``first`` (the start on the first call,
    none after), then at next_index out_dt, (next_index + 1) out_dt, ... from the cubic Hermite
    interpolant of y with the slopes ydot at both ends (error O(h^4), RK4's order), or after every
    step (out_dt <= 0), and at t_end.  A step whose result is not finite (beyond the stability
    limit) is not taken: the loop returns that non-finite y with t and the samples before it.
    Returns t, y, the next output index, the samples and their SampledOutputs
    (outputs.sample_outputs with the PostSetup post)."""
    cdef Layout L = p.L
    cdef Py_ssize_t ny = len(y_start), ns0 = len(first.t), k, i
    cdef double[::1] y = np.array(y_start, dtype=float), y_old = np.zeros(ny), y_k = np.zeros(ny)
    cdef double[::1] k1 = np.zeros(ny), k2 = np.zeros(ny), k3 = np.zeros(ny), k4 = np.zeros(ny)
    cdef double[::1] slope_old = np.zeros(ny), stage = np.zeros(ny)
    cdef const double[::1] ft = first.t
    cdef const double[:, :, ::1] fR = first.R
    cdef const double[:, :, :, ::1] fA = first.A
    cdef const double[:, ::1] fQ = first.Q, fu = first.u, fud = first.ud, flam = first.lam, frefs = first.refs
    cdef const double[:, ::1] fwork = first.work
    cdef Py_ssize_t room = capacity + ns0, ns = ns0
    cdef double end_tol = 1e-12 * max(1.0, t_end), step, half, t_old, at, t_k, b00, b10, b01, b11
    cdef bint final, stored
    unpack(L, y, p.R, p.A, p.Q, p.u)
    cdef SampleBuffers buf = sample_buffers(room, p.R, p.Q, p.u, p.lam_guess, p.refs)
    for k in range(ns0):
        store_sample(buf, k, ft[k], fR[k], fA[k], fQ[k], fu[k], fud[k], flam[k], frefs[k], fwork[k])
    index1_rhs(t, y, p, k1)
    while t < t_end - end_tol and steps[0] < steps[1]:
        step = min(h, t_end - t)
        if out_dt > 0.0 and ns > ns0 and ns + <Py_ssize_t> (step / out_dt) + 2 > room:
            break  # the samples this step may give would not fit: the stepper resumes
        half = 0.5 * step
        rk4_stage(y, half, k1, stage)
        index1_rhs(t + half, stage, p, k2)
        rk4_stage(y, half, k2, stage)
        index1_rhs(t + half, stage, p, k3)
        rk4_stage(y, step, k3, stage)
        index1_rhs(t + step, stage, p, k4)
        y_old, y = y, y_old  # y_old, slope_old: the step's start and its slope (buffers swapped)
        slope_old, k1 = k1, slope_old
        t_old = t
        rk4_combine(y_old, step, slope_old, k2, k3, k4, y)
        if not all_finite(y):
            break  # blew up: the caller stops the run at t (the last finite state)
        t += step
        steps[0] += 1
        index1_rhs(t, y, p, k1)  # the next step's first stage: the interpolant's end slope
        final = t >= t_end - end_tol
        at = 1e-12 * max(1.0, fabs(t))
        stored = False
        while out_dt > 0.0 and next_index * out_dt <= t + at:
            t_k = next_index * out_dt
            b00, b10, b01, b11 = hermite(min(1.0, max(0.0, (t_k - t_old) / step)))
            for i in range(ny):
                y_k[i] = b00 * y_old[i] + b10 * step * slope_old[i] + b01 * y[i] + b11 * step * k1[i]
            sample(t_k, y_k, p)
            store_state(buf, ns, t_k, p, y_k)
            ns, next_index, stored = ns + 1, next_index + 1, t_k >= t - at
        sample(t, y, p)  # the state at t: a sample when stored below, else it keeps the angle references current
        if out_dt <= 0.0 or (final and not stored):
            store_state(buf, ns, t, p, y)
            ns += 1
        if ns == room:
            break
    samples = first_samples(buf, ns)
    return t, np.asarray(y), next_index, samples, sample_outputs(post.L, post.L0, samples, post.c)
