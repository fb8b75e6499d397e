"""Lie-group generalised-alpha for the index-3 DAE (Arnold & Bruls 2007; Bruls, Cardona &
Arnold 2012), compiled: the method's kernels and its stepping loop ``ga_loop``.  On SE(3) x R^nq
per body (se3.pyx: body-frame translational velocities, so that a
uniform rotation about any fixed axis is integrated exactly; on R^3 x SO(3) a body whirling
about a hinge away from its frame origin gained energy ~ h^2 Omega^3):

    x_{n+1} = x_n (+) h dx,  dx = u_n + h (1/2 - beta) a_n + h beta a_{n+1}
    u_{n+1} = u_n + h (1 - gamma) a_n + h gamma a_{n+1}
    (1 - alpha_m) a_{n+1} + alpha_m a_n = (1 - alpha_f) ud_{n+1} + alpha_f ud_n
    M ud_{n+1} - f + B_F^T lambda = 0,   g(x_{n+1}, t_{n+1}) / (h^2 beta') = 0

(Chung-Hulbert parameters from rho_inf; beta' = beta (1 - alpha_f) / (1 - alpha_m) scales the
constraint rows so that the iteration matrix is O(1)).  Unknowns ud_{n+1}, lambda; modified
Newton: the iteration matrix [M + D, B_F^T; B, 0] is factorised once per step at the
predictor (M, B exact there) and re-used over the step's iterations; D = h gamma' C_t +
h^2 beta' K_t (finite differences) is re-used over steps until convergence slows.  Converged
when the position correction is below newton_tol L and the constraint residual before it
below newton_tol L (the correction shrinks it further); the state is then not evaluated once
more: the power flows and joint angles of the step come from the last evaluation, within the
Newton tolerance.  Constraints hold at position level to the Newton tolerance (no drift).

Velocity projection (rho_inf > RHO_PROJECTED): index-3 generalised-alpha meets the constraints
at position level only; its velocities leave B u + b_t = 0 by a little each step, and only the
method's numerical damping keeps that error bounded.  With little damping it grows without
bound where a closed loop passes its dead centres, whatever the step: the trapezoidal rule,
rho_inf = 1, is unstable on index-3 systems (Cardona & Geradin 1989).  Above RHO_PROJECTED the
velocities of each accepted step are projected onto B u + b_t = 0 (post-stabilisation, Ascher,
Chin & Reich 1994) by an impulse of the constraint rows, solved with the step's factorised
iteration matrix (one back-substitution); the impulse's work through the rheonomic rows is
booked as the drives' work.

Contacts (bump stops, forces.pyx stop_states; docs/solver.md "Contacts"): a step whose end engages or
releases a stop that its start did not is repeated, shortened by the secant of the penetration,
until the kink lies in its last CROSSING_TAIL: the step goes to the contact, not across it; a
step from an open stop is bounded by APPROACH_REACH times the time to close the gap at the
current rate; while a stop is engaged, the normal rate may change by at most 2 V / CONTACT_STEPS
per step (V the largest normal speed of the contact, at least CONTACT_REST_SPEED L / h), so that
the impact takes at least CONTACT_STEPS steps whatever the nominal step.

Output (output_dt given): every sample sits at exactly k output_dt, interpolated inside the step
that contains it (``dense_state``): the pose is x_n (+) delta(theta) with the cubic Hermite
increment delta(0) = 0, delta'(0) = h u_n, delta(1) = h dx, delta'(1) = h u_{n+1} (exact for q;
for the rotations and the body-frame translations the end slope is u_{n+1}, right to O(h^2)), the
velocities the cubic Hermite of u with the slopes h ud, the accelerations, multipliers and work
integrals linear: within the method's second order, and the step is never cut to land on an
output time.

Error control (rtol given): the local error of the step against the third-order Taylor
expansion written with the true accelerations ud (not the alpha-lagged a),

    e_x = h^2 [(1/2 - beta) a_n + beta a_{n+1} - ud_n / 3 - ud_{n+1} / 6]
    e_u = h   [(1 - gamma) a_n + gamma a_{n+1} - (ud_n + ud_{n+1}) / 2]

measured in lengths (e_x and h e_u, weighted to metres), RMS against atol + rtol L.  For
Newmark (a = ud) e_x reduces to the classic h^2 (beta - 1/6) (ud_{n+1} - ud_n); with alpha
damping it also sees the lag of a behind ud, which the classic estimate misses.
"""

from libc.math cimport INFINITY, fabs, isfinite, sqrt
from libc.float cimport DBL_EPSILON
from libc.stdint cimport int64_t

import numpy as np

from sidprep.solver.core.assemble cimport (constraint_power, evaluate_into, has_moving_masses, markers_into,
                                           moving_masses)
from sidprep.solver.core.forces cimport has_stops, stop_states
from sidprep.solver.core.outputs cimport PostConstants, sample_outputs
from sidprep.solver.core.records cimport Evaluation, Layout
from sidprep.solver.core.runge_kutta cimport hermite
from sidprep.solver.core.se3 cimport (body_accelerations, body_increment, body_velocities, inertial_accelerations,
                                      inertial_velocities, to_body_frame)
from sidprep.solver.core.steps cimport (APPROACH_REACH, FINISHED, LARGE_DEFORMATION, MAX_STEPS, NEWTON_FAILED,
                                        RUNNING, SampleBuffers, advance_pose, expand, first_samples, lu_factor,
                                        lu_solve, sample_buffers, store_sample)
from sidprep.solver.core.records import evaluation_arrays

#: maximum Newton iterations with one iteration matrix
MAX_NEWTON = 6
#: contraction factor above which the iteration matrix is renewed
SLOW_CONTRACTION = 0.3
#: fixed-step mode: successful steps after a step cut before the step is doubled again
RECOVER_STEPS = 4
#: step-size factor limits and safety factor of the error control
H_GROW, H_SHRINK, SAFETY = 2.0, 0.2, 0.9
#: contacts: fewest steps over an impact (the normal rate reverses by 2 V over it;
#: tests/test_impacts.py: the Hertz rebound of a ball at h = 1 ms, rho_inf = 0.9)
CONTACT_STEPS = 100
#: rho_inf above which the velocities are projected after each step (module doc).  Up to it the
#: method's damping bounds the velocity error wherever the step resolves the motion (the undriven
#: slider crank of tests/test_stability.py at rho_inf = 0.95 diverges at h = 2 ms and holds at
#: 1 ms); above it a smaller step does not help (0.99 diverges at 1 and 0.5 ms).  Unprojected
#: runs are the more accurate where they hold: that crank's angle after 1 s is 2.7e-2 rad off at
#: h = 1 ms, projected 6.6e-2
RHO_PROJECTED = 0.95
#: a step engaging or releasing a stop is accepted when the kink lies in this last fraction of it
CROSSING_TAIL = 0.05
#: floor of the contact's speed scale, in system lengths per nominal step (a resting contact)
CONTACT_REST_SPEED = 1e-6

cdef int C_MAX_NEWTON = MAX_NEWTON
cdef double C_SLOW = SLOW_CONTRACTION, C_GROW = H_GROW, C_SHRINK = H_SHRINK, C_SAFETY = SAFETY
cdef int C_RECOVER = RECOVER_STEPS
cdef double C_CONTACT_STEPS = CONTACT_STEPS, C_TAIL = CROSSING_TAIL, C_REST = CONTACT_REST_SPEED


cdef class GaState:
    """The state of the method (genalpha.pxd); ``GaState(R, A, Q, u, ud, a, lam)`` takes the
    arrays themselves (C-contiguous float64), ``GaState.zeros(L, m)`` makes one of zeros."""

    def __init__(self, double[:, ::1] R, double[:, :, ::1] A, double[::1] Q, double[::1] u, double[::1] ud,
                 double[::1] a, double[::1] lam):
        self.R, self.A, self.Q, self.u, self.ud, self.a, self.lam = R, A, Q, u, ud, a, lam

    @staticmethod
    def zeros(Layout L, Py_ssize_t m):
        """A state of zeros for layout L with m kept multipliers."""
        nb, n = L.qoff.shape[0] - 1, L.uoff[L.uoff.shape[0] - 1]
        return GaState(np.zeros((nb, 3)), np.zeros((nb, 3, 3)), np.zeros(L.qoff[nb]), np.zeros(n), np.zeros(n),
                       np.zeros(n), np.zeros(m))

    def arrays(self):
        """(R, A, Q, u, ud, a, lam) as numpy arrays (views of this state's memory)."""
        return (np.asarray(self.R), np.asarray(self.A), np.asarray(self.Q), np.asarray(self.u), np.asarray(self.ud),
                np.asarray(self.a), np.asarray(self.lam))


cdef void copy_state(GaState x, GaState out) noexcept nogil:
    """out = x, element by element."""
    out.R[:, :] = x.R
    out.A[:, :, :] = x.A
    out.Q[:] = x.Q
    out.u[:] = x.u
    out.ud[:] = x.ud
    out.a[:] = x.a
    out.lam[:] = x.lam


cdef class GaConstants:
    """A run's constants (genalpha.pxd)."""

    def __init__(self, prm, free, kept, w, double length, limits, double tol, double rtol, double atol,
                 double h_nominal, double out_dt):
        self.alpha_m, self.alpha_f, self.gamma, self.beta, self.beta_p = [float(v) for v in prm]
        self.free = np.ascontiguousarray(free, dtype=np.int64)
        self.kept = np.ascontiguousarray(kept, dtype=np.int64)
        self.w = np.ascontiguousarray(w, dtype=float)
        self.limits = np.ascontiguousarray(limits, dtype=float)
        self.length, self.tol, self.rtol, self.atol = length, tol, rtol, atol
        self.h_nominal, self.out_dt = h_nominal, out_dt
        self.projected = self.alpha_f / (1.0 - self.alpha_f) > RHO_PROJECTED * (1.0 + 1e-9)  # rho_inf = af / (1 - af)


cdef class GaWorkspace:
    """A run's workspace (genalpha.pxd) for layout L and the GaConstants c."""

    def __init__(self, Layout L, GaConstants c):
        cdef Py_ssize_t nf = c.free.shape[0], m = c.kept.shape[0], n = L.uoff[L.uoff.shape[0] - 1]
        cdef Py_ssize_t m_all = L.joint_off[L.joint_off.shape[0] - 1] + L.drv_joint.shape[0]
        cdef Py_ssize_t nfe = L.fe_int.shape[0]
        self.e, self.e_col = evaluation_arrays(L), evaluation_arrays(L)
        self.lam_all = np.zeros(m_all)
        self.r, self.r_col, self.dz = np.zeros(nf + m), np.zeros(nf + m), np.zeros(nf + m)
        self.jac = np.zeros((nf + m, nf + m))
        self.piv = np.zeros(nf + m, dtype=np.intc)
        self.D = np.zeros((nf, nf))
        self.work, self.flows = np.zeros(3), np.full(4, np.nan)
        self.flows_new, self.work_old, self.work_k = np.zeros(4), np.zeros(3), np.zeros(3)
        self.pen, self.rate = np.full(nfe, -np.inf), np.zeros(nfe)
        self.pen_new, self.rate_new, self.speed = np.full(nfe, -np.inf), np.zeros(nfe), np.zeros(nfe)
        self.cur, self.trial, self.old = GaState.zeros(L, m), GaState.zeros(L, m), GaState.zeros(L, m)
        self.col, self.dense = GaState.zeros(L, m), GaState.zeros(L, m)
        self.dx, self.udt, self.u_o, self.ud_o = np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n)
        self.vec, self.conv = np.zeros(n), np.zeros(n)


cdef class LoopStatus:
    """The loop's status (genalpha.pxd), for a run of at most max_steps steps."""

    def __init__(self, long max_steps):
        self.steps = self.rejected = self.newton_iterations = self.jacobians = self.code = self.body = 0
        self.h_min, self.h_max, self.deflection = INFINITY, 0.0, 0.0
        self.max_steps = max_steps


cdef class GaRun:
    """What ga_loop works on over a run: the layout L, the GaConstants c, the GaWorkspace ws, the
    joints' angle references refs (nj,; updated after every step), the LoopStatus status, the
    outputs' layouts post_L, post_L0 and PostConstants post_c (outputs.sample_outputs), and the
    stepper's time t (s), step size h (s) and next output index (updated by each call)."""
    cdef readonly Layout L, post_L, post_L0
    cdef readonly GaConstants c
    cdef readonly GaWorkspace ws
    cdef readonly double[::1] refs
    cdef readonly LoopStatus status
    cdef readonly PostConstants post_c
    cdef public double t, h
    cdef public Py_ssize_t next_index

    def __init__(self, Layout L, GaConstants c, double[::1] refs, long max_steps, post, double h):
        self.L, self.c, self.refs = L, c, refs
        self.ws = GaWorkspace(L, c)
        self.status = LoopStatus(max_steps)
        self.post_L, self.post_L0, self.post_c = post.L, post.L0, post.c
        self.t, self.h, self.next_index = 0.0, h, 1


cdef void ga_state(Layout L, const double[::1] udn, GaState x, double h, GaConstants c, double[::1] dx,
                   GaState out) noexcept nogil:
    """The update of the GaState x for ud_{n+1} = udn (module doc): a_{n+1}, R, A, Q, u_{n+1}
    written into out (out.ud, out.lam untouched); dx (n,) scratch, the increment h dx."""
    cdef double am = c.alpha_m, af = c.alpha_f, gamma = c.gamma, beta = c.beta, an
    cdef Py_ssize_t i
    for i in range(udn.shape[0]):
        an = (af * x.ud[i] + (1 - af) * udn[i] - am * x.a[i]) / (1 - am)
        out.a[i] = an
        dx[i] = h * x.u[i] + h * h * ((0.5 - beta) * x.a[i] + beta * an)
        out.u[i] = x.u[i] + h * ((1 - gamma) * x.a[i] + gamma * an)
    advance_pose(L, x.R, x.A, x.Q, dx, True, out.R, out.A, out.Q)


cdef void newton_residual(Evaluation e, const double[::1] udn, const double[::1] lamn, double h, GaConstants c,
                          double[::1] r) noexcept nogil:
    """r (free + kept,) = [M ud - f + B_F^T lambda; g / (h^2 beta')] on the free coordinates and
    kept rows of the GaConstants c, from the Evaluation e at the state updated for (udn, lamn)."""
    cdef const int64_t[::1] free = c.free, kept = c.kept
    cdef Py_ssize_t nf = free.shape[0], m = kept.shape[0], i, j, k, row
    cdef double acc
    for i in range(nf):
        row = free[i]
        acc = 0.0  # (M ud)_row
        for j in range(udn.shape[0]):
            acc += e.M[row, j] * udn[j]
        acc = acc - e.f[row]
        for k in range(m):
            acc += e.BF[kept[k], free[i]] * lamn[k]
        r[i] = acc
    for k in range(m):
        r[nf + k] = e.g[kept[k]] / (h * h * c.beta_p)


cdef void dense_state(Layout L, GaState x0, GaState x1, double h, double theta, GaWorkspace ws,
                      GaState out) noexcept nogil:
    """The state at t_n + theta h inside the step from GaState x0 to x1 (module doc, Output),
    written into out: the increment delta(theta) on the Lie group, u by cubic Hermite, ud and lam
    linear; out.u, out.ud inertial (se3.py), out.a untouched.  ws.dx, ws.udt, ws.vec scratch."""
    cdef double b00, b10, b01, b11
    cdef Py_ssize_t i, k
    cdef double[::1] step = ws.dx, u = ws.udt, delta = ws.vec
    b00, b10, b01, b11 = hermite(theta)
    body_increment(L, x0.R, x0.A, x1.R, x1.A, x0.Q, x1.Q, step)  # h dx: what took x0 to x1 (ga_state)
    for i in range(step.shape[0]):
        delta[i] = b10 * h * x0.u[i] + b01 * step[i] + b11 * h * x1.u[i]
        u[i] = b00 * x0.u[i] + b10 * h * x0.ud[i] + b01 * x1.u[i] + b11 * h * x1.ud[i]
        out.a[i] = (1.0 - theta) * x0.ud[i] + theta * x1.ud[i]  # ud in body-frame coordinates
    for k in range(x0.lam.shape[0]):
        out.lam[k] = (1.0 - theta) * x0.lam[k] + theta * x1.lam[k]
    advance_pose(L, x0.R, x0.A, x0.Q, delta, True, out.R, out.A, out.Q)
    inertial_velocities(L, out.A, u, out.u)
    inertial_accelerations(L, out.A, u, out.a, out.ud)


cdef void state_flows(Layout L, Evaluation e, GaState x, const double[::1] lam_all, double mass_power,
                      double[::1] flows) noexcept nogil:
    """The power flows (4,) at the GaState x (SE(3) coordinates) from its Evaluation e (the same
    coordinates), written into flows: e.flows, to whose drives' power flows[3] the power through
    the rheonomic rows at the multipliers lam_all (m_all,) and that of the moving masses
    (mass_power, W; assemble.moving_masses) are added."""
    flows[:] = e.flows
    flows[3] += constraint_power(L, e.B, e.bt, x.u, lam_all) + mass_power


cdef void iteration_matrix(Evaluation e, const double[:, ::1] D, const int64_t[::1] free, const int64_t[::1] kept,
                           double[:, ::1] jac) noexcept nogil:
    """[M + D, B_F^T; B, 0] (free + kept, free + kept) written into jac, with M, B, B_F of the
    Evaluation e restricted to the free coordinates and the kept rows."""
    cdef Py_ssize_t nf = free.shape[0], m = kept.shape[0], i, j, k
    for i in range(nf):
        for j in range(nf):
            jac[i, j] = e.M[free[i], free[j]] + D[i, j]
        for k in range(m):
            jac[i, nf + k] = e.BF[kept[k], free[i]]
            jac[nf + k, i] = e.B[kept[k], free[i]]
    for k in range(m):
        for j in range(m):
            jac[nf + k, nf + j] = 0.0


cdef double project_velocities(Layout L, Evaluation e, GaConstants c, GaWorkspace ws, double[::1] u) noexcept nogil:
    """u (n,) moved onto B u + b_t = 0 (kept rows) by the impulse of the multipliers mu (module
    doc, Velocity projection): [M + D, B_F^T; B, 0] [du; mu] = [0; -(B u + b_t)] with the step's
    factorised iteration matrix (ws.jac, ws.piv) and B, b_t of the Evaluation e.  Returns the work
    (J) the impulse does through the rheonomic rows (drivers, joints on moving markers; as
    assemble.constraint_power): -mu_r B_r (u + du / 2), the drives' share.  ws.r, ws.dz scratch."""
    cdef const int64_t[::1] free = c.free, kept = c.kept
    cdef Py_ssize_t nf = free.shape[0], m = kept.shape[0], nrj = L.joint_off[L.joint_off.shape[0] - 1], i, j, k, r
    cdef double rate, work = 0.0
    for i in range(nf):
        ws.r[i] = 0.0
    for k in range(m):
        rate = e.bt[kept[k]]
        for j in range(u.shape[0]):
            rate += e.B[kept[k], j] * u[j]
        ws.r[nf + k] = -rate
    lu_solve(ws.jac, ws.piv, ws.r, ws.dz)
    for k in range(m):
        r = kept[k]
        if r >= nrj or e.bt[r] != 0.0:
            rate = 0.0
            for i in range(nf):
                rate += e.B[r, free[i]] * (u[free[i]] + 0.5 * ws.dz[i])
            work -= ws.dz[nf + k] * rate
    for i in range(nf):
        u[free[i]] += ws.dz[i]
    return work


cdef double local_error(const double[::1] udn, const double[::1] an, GaState x, double h,
                        GaConstants c) noexcept nogil:
    """RMS of the weighted local error estimate (module doc) of the step from GaState x to
    (udn, an) over the free coordinates, in units of atol + rtol L (<= 1: accept)."""
    cdef double gamma = c.gamma, beta = c.beta, acc = 0.0, ex, eu, e
    cdef Py_ssize_t k, i, nf = c.free.shape[0]
    for k in range(nf):
        i = c.free[k]
        ex = h * h * ((0.5 - beta) * x.a[i] + beta * an[i] - x.ud[i] / 3.0 - udn[i] / 6.0)
        eu = h * h * ((1 - gamma) * x.a[i] + gamma * an[i] - 0.5 * (x.ud[i] + udn[i]))
        e = max(fabs(ex), fabs(eu)) * c.w[i] / (c.atol + c.rtol * c.length)
        acc += e * e
    return sqrt(acc / max(nf, 1))


cdef double approach_bound(GaWorkspace ws, double h) noexcept nogil:
    """The step h (s) bounded so that no open stop closing at its current rate is reached
    beyond APPROACH_REACH times its gap (module doc, Contacts)."""
    cdef Py_ssize_t i
    for i in range(ws.pen.shape[0]):
        if -INFINITY < ws.pen[i] <= 0.0 and ws.rate[i] > 0.0:
            h = min(h, max(APPROACH_REACH * -ws.pen[i] / ws.rate[i], 1e-3 * h))
    return h


cdef (bint, double) contact_factor(GaWorkspace ws, double speed_floor) noexcept nogil:
    """(accept, factor) of a converged step from the stop states ws.pen, ws.rate to
    ws.pen_new, ws.rate_new (module doc, Contacts): a step that engages or releases a stop
    with the kink before its last CROSSING_TAIL, or changes an engaged stop's normal rate by
    more than 2 V / CONTACT_STEPS, is rejected and factor (< 1) shortens it; an accepted step's
    factor (>= 1 or inf) bounds the growth of the next.  speed_floor: the least V, m/s."""
    cdef bint accept = True
    cdef double factor = INFINITY, p0, p1, theta, v, change, bound
    cdef Py_ssize_t i
    for i in range(ws.pen.shape[0]):
        p0, p1 = ws.pen[i], ws.pen_new[i]
        if p0 == -INFINITY:
            continue
        if (p0 <= 0.0) != (p1 <= 0.0):  # a kink inside the step: at theta of it (secant)
            theta = p0 / (p0 - p1)
            if theta < 1.0 - C_TAIL:
                accept, factor = False, min(factor, max(theta, 1e-6) / (1.0 - 0.5 * C_TAIL))
                continue
        if p0 > 0.0 or p1 > 0.0:
            v = max(ws.speed[i], fabs(ws.rate[i]), fabs(ws.rate_new[i]), speed_floor)
            change = fabs(ws.rate_new[i] - ws.rate[i])
            bound = 2.0 * v / C_CONTACT_STEPS
            if change > bound:
                accept = False
                factor = min(factor, max(C_SHRINK, C_SAFETY * bound / change))
            elif accept and change > 0.0:
                factor = min(factor, C_SAFETY * bound / change)
    return accept, factor


cdef bint contact_accepted(GaWorkspace ws) noexcept nogil:
    """Take the trial stop states as the current ones; the speed scale of each engaged stop's
    contact grows to its largest normal speed, an open stop's is reset.  True when a stop is
    engaged."""
    cdef bint engaged = False
    cdef Py_ssize_t i
    for i in range(ws.pen.shape[0]):
        if ws.pen_new[i] > 0.0:
            engaged = True
            ws.speed[i] = max(ws.speed[i], fabs(ws.rate[i]), fabs(ws.rate_new[i]))
        else:
            ws.speed[i] = 0.0
        ws.pen[i], ws.rate[i] = ws.pen_new[i], ws.rate_new[i]
    return engaged


cdef bint deflection_check(Layout L, const double[::1] Q, GaConstants c, LoopStatus status) noexcept nogil:
    """False (and the body and its deflection, m, in status) when a body's elastic deflection
    |w Q| exceeds its limit (the floating frame's small-deformation range)."""
    cdef bint within = True
    cdef Py_ssize_t b, k
    cdef double d2, d
    for b in range(L.qoff.shape[0] - 1):
        d2 = 0.0
        for k in range(L.qoff[b + 1] - L.qoff[b]):
            d = Q[L.qoff[b] + k] * c.w[L.uoff[b] + 6 + k]
            d2 += d * d
        if not sqrt(d2) <= c.limits[b]:
            status.code, status.body, status.deflection = LARGE_DEFORMATION, b, sqrt(d2)
            within = False
    return within


cdef void to_body_state(Layout L, GaState x, GaState out) noexcept nogil:
    """out = the GaState x (u, ud inertial) in the coordinates of se3.py (x.a is kept in them)."""
    copy_state(x, out)
    body_velocities(L, x.A, x.u, out.u)
    body_accelerations(L, x.A, out.u, x.ud, out.ud)


cdef void to_inertial_state(Layout L, GaState x, GaState out) noexcept nogil:
    """out = the GaState x with u, ud inertial (x.a, in the coordinates of se3.py, kept)."""
    out.R[:, :] = x.R
    out.A[:, :, :] = x.A
    out.Q[:] = x.Q
    out.a[:] = x.a
    out.lam[:] = x.lam
    inertial_velocities(L, x.A, x.u, out.u)
    inertial_accelerations(L, x.A, x.u, x.ud, out.ud)



cdef void trial_residual(GaRun run, GaState start, GaState trial, double t, double h) noexcept:
    """The Newton residual run.ws.r of the iterate ``trial`` (its accelerations ud and multipliers
    lam) of the step of h s from ``start`` at t s: its pose and velocities (ga_state), the system
    evaluated there at t + h (run.ws.e) and turned into the body frame (se3.pyx to_body_frame)."""
    cdef Layout L = run.L
    cdef GaWorkspace ws = run.ws
    ga_state(L, trial.ud, start, h, run.c, ws.dx, trial)
    inertial_velocities(L, trial.A, trial.u, ws.u_o)
    expand(trial.lam, run.c.kept, ws.lam_all)
    evaluate_into(L, ws.e, trial.R, trial.A, trial.Q, ws.u_o, t + h, ws.lam_all, run.refs)
    to_body_frame(L, trial.A, trial.u, ws.e, ws.conv)
    newton_residual(ws.e, trial.ud, trial.lam, h, run.c, ws.r)


def ga_loop(GaRun run, GaState x, double t_end, Py_ssize_t capacity):
    """Generalised-alpha steps of the GaState x (written in place) from run.t until t_end or
    until ``capacity`` output samples besides the start's (so that the stretches end at the same
    steps whether or not it is recorded), with the run's GaConstants run.c and GaWorkspace run.ws;
    samples at run.next_index c.out_dt, (run.next_index + 1) c.out_dt, ... (dense_state; a sample
    at a step's end is that step's state), or after every step (c.out_dt <= 0), and at t_end; the
    first call records the start as the run's first sample.  Returns the samples (SampleBuffers)
    and their SampledOutputs (outputs.sample_outputs with the run's post_L, post_L0, post_c).

    c.rtol <= 0: fixed step run.h (cut in halves when Newton fails, then doubled back).
    ws.work (3,) the work integrals [applied loads, dissipated, drivers] and ws.flows (4,) the
    power flows at the current state (NaN before the first call: computed here, and x.a set to
    x.ud) are updated in place, as run.refs (angle references), run.status (LoopStatus) and
    run.t, run.h, run.next_index.  x.u, x.ud in and out and the samples are inertial (v_O); the
    steps are taken in the SE(3) coordinates of se3.py, in which x.a is kept.
    """
    cdef Layout L = run.L
    cdef GaConstants c = run.c
    cdef GaWorkspace ws = run.ws
    cdef LoopStatus status = run.status
    cdef Evaluation e = ws.e
    cdef GaState xc = ws.cur, trial = ws.trial, old = ws.old, swap
    cdef double[::1] refs = run.refs, work = ws.work, flows0 = ws.flows, lam_all = ws.lam_all, r = ws.r
    cdef double[::1] dz = ws.dz, u_o = ws.u_o, ud_o = ws.ud_o, udt = ws.udt
    cdef double[:, ::1] D = ws.D
    cdef const int64_t[::1] free = c.free, kept = c.kept
    cdef Py_ssize_t nf = free.shape[0], m = kept.shape[0], nj = refs.shape[0]
    cdef Py_ssize_t next_index = run.next_index, ns, ns0, room, it, i, j, k, col, row
    cdef double t = run.t, h = run.h, end_tol, D_h = 0.0, h_prev = -1.0, factor = 1.0, speed_floor, last, err
    cdef double drift, scale, eps_pos, delta, est, contact_growth, mass_power, t_old, at, t_k, theta
    cdef bint first_call = not isfinite(ws.flows[0]), masses, stops, in_contact = False, have_d = False
    cdef bint want_d, fresh_d, refactored, factor_now, converged, accept, final, stored
    ns0 = 1 if first_call else 0  # the start's row, before the loop's own samples
    room = capacity + ns0
    cdef SampleBuffers buf = sample_buffers(room, x.R, x.Q, x.u, x.lam, refs)
    ns = ns0
    if first_call:  # the start as given (inertial), before any conversion
        store_sample(buf, 0, t, x.R, x.A, x.Q, x.u, x.ud, x.lam, refs, work)
    to_body_state(L, x, xc)
    masses = has_moving_masses(L)
    if first_call:  # a = ud and the power flows at the start state
        xc.a[:] = xc.ud
        expand(xc.lam, kept, lam_all)
        inertial_velocities(L, xc.A, xc.u, u_o)
        inertial_accelerations(L, xc.A, xc.u, xc.ud, ud_o)
        evaluate_into(L, e, xc.R, xc.A, xc.Q, u_o, t, lam_all, refs)
        mass_power = moving_masses(L, e.kin, xc.R, xc.A, xc.Q, u_o, ud_o, t)[0] if masses else 0.0
        stop_states(L, e.kin, ws.pen, ws.rate)
        to_body_frame(L, xc.A, xc.u, e, ws.conv)
        state_flows(L, e, xc, lam_all, mass_power, flows0)
    end_tol = 1e-12 * max(1.0, t_end)
    D[:, :] = 0.0
    old.ud[:] = xc.ud  # the predictor's previous step (none yet: h_prev < 0)
    old.lam[:] = xc.lam
    stops = has_stops(L)
    speed_floor = C_REST * c.length / c.h_nominal
    status.code = RUNNING
    while t < t_end - end_tol:
        if status.steps >= status.max_steps:
            status.code = MAX_STEPS
            break
        if stops:
            h = approach_bound(ws, h)
        h = min(h, t_end - t)
        if c.out_dt > 0.0 and ns > ns0 and ns + <Py_ssize_t>(h / c.out_dt) + 2 > room:
            break  # the samples this step may give would not fit: the stepper resumes
        if h == h_prev:  # linear extrapolation predictor
            for i in range(xc.ud.shape[0]):
                trial.ud[i] = 2.0 * xc.ud[i] - old.ud[i]
            for k in range(m):
                trial.lam[k] = 2.0 * xc.lam[k] - old.lam[k]
        else:
            trial.ud[:] = xc.ud
            trial.lam[:] = xc.lam
        if have_d and D_h != h:  # the stiffness part scales with h^2; a poor fit is caught by the monitor
            scale = h / D_h
            scale = scale * scale  # (h / D_h)^2 as a product (pow may differ from it in the last bit)
            for i in range(nf):
                for j in range(nf):
                    D[i, j] = D[i, j] * scale
            D_h = h
        want_d, fresh_d, refactored, factor_now = not have_d, False, False, True
        last = INFINITY
        it = 0
        converged = False
        trial_residual(run, xc, trial, t, h)
        while True:
            if want_d:  # D = d r1 / d ud - M by forward differences at the current iterate
                eps_pos = sqrt(DBL_EPSILON) / (h * h * c.beta_p)
                for col in range(nf):
                    delta = max(1e-7 * fabs(trial.ud[free[col]]), eps_pos)
                    udt[:] = trial.ud
                    udt[free[col]] += delta
                    ga_state(L, udt, xc, h, c, ws.dx, ws.col)
                    inertial_velocities(L, ws.col.A, ws.col.u, u_o)
                    evaluate_into(L, ws.e_col, ws.col.R, ws.col.A, ws.col.Q, u_o, t + h, lam_all, refs)
                    to_body_frame(L, ws.col.A, ws.col.u, ws.e_col, ws.conv)
                    newton_residual(ws.e_col, udt, trial.lam, h, c, ws.r_col)
                    for row in range(nf):
                        D[row, col] = (ws.r_col[row] - r[row]) / delta - e.M[free[row], free[col]]
                D_h, have_d, fresh_d, want_d, factor_now = h, True, True, False, True
                status.jacobians += 1
            if factor_now:  # M, B of this iterate; D re-used over steps
                iteration_matrix(e, D, free, kept, ws.jac)
                lu_factor(ws.jac, ws.piv)  # in place: jac holds its LU factors
                factor_now = False
            drift = 0.0  # constraint residual before this update, m or rad
            for k in range(m):
                drift = max(drift, fabs(r[nf + k]))
            drift *= h * h * c.beta_p
            lu_solve(ws.jac, ws.piv, r, dz)
            for i in range(nf):
                trial.ud[free[i]] -= dz[i]
            for k in range(m):
                trial.lam[k] -= dz[nf + k]
            it += 1
            err = 0.0
            for i in range(nf + m):
                if not isfinite(dz[i]):
                    err = INFINITY
                elif i < nf:
                    err = max(err, fabs(dz[i]) * c.w[free[i]])
            err *= h * h * c.beta_p / c.length
            if not isfinite(err):
                break
            if err <= c.tol and drift <= c.tol * c.length:  # the update shrinks the drift further
                converged = True
                break
            trial_residual(run, xc, trial, t, h)
            if it >= C_MAX_NEWTON or (it > 1 and err > C_SLOW * last):
                if not refactored:  # first: the current M, B with the old D
                    refactored, factor_now, it, last = True, True, 0, INFINITY
                    continue
                if not fresh_d:  # then: a new D
                    want_d, it, last = True, 0, INFINITY
                    continue
                break
            last = err
        status.newton_iterations += it
        if not converged:
            status.rejected += 1
            h *= 0.5
            have_d = False
            h_prev = -1.0
            if h < 1e-14 * max(1.0, t_end):
                status.code = NEWTON_FAILED
                break
            continue
        ga_state(L, trial.ud, xc, h, c, ws.dx, trial)
        contact_growth = INFINITY
        if stops:  # the last evaluation is the converged state's, within the Newton tolerance
            stop_states(L, e.kin, ws.pen_new, ws.rate_new)
            accept, contact_growth = contact_factor(ws, speed_floor)
            if not accept:
                status.rejected += 1
                h *= contact_growth
                h_prev = -1.0
                continue
        if c.rtol > 0.0:
            est = local_error(trial.ud, trial.a, xc, h, c)
            factor = C_SAFETY * est ** (-1.0 / 3.0) if est > 0 else C_GROW
            if est > 1.0:
                status.rejected += 1
                h *= max(C_SHRINK, factor)
                continue
        if not deflection_check(L, trial.Q, c, status):
            break
        if stops:
            in_contact = contact_accepted(ws)
        h_prev = h
        t_old = t
        ws.work_old[:] = work
        swap, old, xc, trial = old, xc, trial, old  # the accepted step's start kept for the predictor
        t += h
        status.steps += 1
        status.h_min = min(status.h_min, h)
        status.h_max = max(status.h_max, h)
        if c.projected and m > 0:  # B, b_t of the last evaluation: the converged state's within newton_tol
            work[2] += project_velocities(L, e, c, ws, xc.u)
        # with the converged multipliers (the last evaluation predates them) and ud
        inertial_velocities(L, xc.A, xc.u, u_o)
        inertial_accelerations(L, xc.A, xc.u, xc.ud, ud_o)
        mass_power = 0.0
        if masses:
            markers_into(L, ws.e_col.kin, xc.R, xc.A, xc.Q, u_o, t)
            mass_power = moving_masses(L, ws.e_col.kin, xc.R, xc.A, xc.Q, u_o, ud_o, t)[0]
        expand(xc.lam, kept, lam_all)
        state_flows(L, e, xc, lam_all, mass_power, ws.flows_new)
        work[0] += 0.5 * h * (ws.flows_new[0] + flows0[0])
        work[1] += 0.5 * h * (ws.flows_new[1] + flows0[1])
        work[2] += 0.5 * h * (ws.flows_new[3] + flows0[3])
        flows0[:] = ws.flows_new
        for j in range(nj):
            refs[j] = e.coords[j, 0]
        final = t >= t_end - end_tol
        at = 1e-12 * max(1.0, fabs(t))
        stored = False
        while c.out_dt > 0.0 and next_index * c.out_dt <= t + at:
            t_k = next_index * c.out_dt
            if t_k >= t - at:  # at the step's end: its state (the interpolant's end point, to rounding)
                store_sample(buf, ns, t_k, xc.R, xc.A, xc.Q, u_o, ud_o, xc.lam, refs, work)
            else:
                theta = min(1.0, max(0.0, (t_k - t_old) / h))
                dense_state(L, old, xc, h, theta, ws, ws.dense)
                for i in range(3):
                    ws.work_k[i] = (1.0 - theta) * ws.work_old[i] + theta * work[i]
                store_sample(buf, ns, t_k, ws.dense.R, ws.dense.A, ws.dense.Q, ws.dense.u, ws.dense.ud,
                             ws.dense.lam, refs, ws.work_k)
            ns, next_index, stored = ns + 1, next_index + 1, t_k >= t - at
        if c.out_dt <= 0.0 or (final and not stored):
            store_sample(buf, ns, t, xc.R, xc.A, xc.Q, u_o, ud_o, xc.lam, refs, work)
            ns += 1
        if c.rtol > 0.0:
            h *= min(C_GROW, max(C_SHRINK, factor), max(1.0, contact_growth))
        elif in_contact:  # the contact's rate bound sets the step, at most the nominal one
            h = min(h * min(C_GROW, max(1.0, contact_growth)), c.h_nominal)
        elif h < c.h_nominal and status.steps % C_RECOVER == 0:
            h = min(2.0 * h, c.h_nominal)
        if ns == room and not final:
            break
    if t >= t_end - end_tol and status.code == RUNNING:
        status.code = FINISHED
    to_inertial_state(L, xc, x)
    run.t, run.h, run.next_index = t, h, next_index
    samples = first_samples(buf, ns)
    return samples, sample_outputs(run.post_L, run.post_L0, samples, run.post_c)
