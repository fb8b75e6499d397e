"""Lie-group generalised-alpha for the index-3 DAE (Arnold & Bruls 2007; Bruls, Cardona &
Arnold 2012), on SE(3) x R^nq per body (se3.py: body-frame translational velocities, so that a
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

Contacts (bump stops, forces.stop_states; docs/solver.md "Contacts"): a step whose end engages or
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

from __future__ import annotations

from collections import namedtuple

import numpy as np

from sidprep.solver.core import genalpha as core
from sidprep.solver.core.outputs import PostConstants as CorePostConstants
from sidprep.solver.core.records import layout_record
from sidprep.solver.equations.assemble import (constraint_power, evaluate_into, evaluation_arrays, has_moving_masses,
                                               markers_into, moving_masses)
from sidprep.solver.equations.forces import has_stops, stop_states
from sidprep.solver.equations.rotations import jit, put
from sidprep.solver.integrators.base import (APPROACH_REACH, CHUNK, FINISHED, LARGE_DEFORMATION, MAX_STEPS,
                                             NEWTON_FAILED, RUNNING, Samples, Stepper, advance_pose, constraint_rows,
                                             expand, first_samples, lu_factor, lu_solve, sample_buffers,
                                             store_sample)
from sidprep.solver.integrators.outputs import sample_outputs
from sidprep.solver.integrators.runge_kutta import hermite
from sidprep.solver.integrators.se3 import (body_accelerations, body_frame_free, body_increment, body_velocities,
                                            inertial_accelerations, inertial_velocities, to_body_frame)

#: maximum Newton iterations with one iteration matrix
MAX_NEWTON = 6
#: contraction factor above which the iteration matrix is renewed
SLOW_CONTRACTION = 0.3
#: fixed-step mode: successful steps after a step cut before the step is doubled again
RECOVER_STEPS = 4
#: step-size factor limits and safety factor of the error control
H_GROW, H_SHRINK, SAFETY = 2.0, 0.2, 0.9
#: contacts (module doc): fewest steps over an impact (the normal rate reverses by 2 V over it;
#: tests/test_impacts.py: the Hertz rebound of a ball at h = 1 ms, rho_inf = 0.9)
CONTACT_STEPS = 100
#: a step engaging or releasing a stop is accepted when the kink lies in this last fraction of it
CROSSING_TAIL = 0.05
#: floor of the contact's speed scale, in system lengths per nominal step (a resting contact)
CONTACT_REST_SPEED = 1e-6

#: the state of the method: positions R, A, Q, velocities u, accelerations ud, the alpha-lagged
#: accelerations a and the kept multipliers lam
GaState = namedtuple("GaState", ["R", "A", "Q", "u", "ud", "a", "lam"])
#: a run's constants: prm = (alpha_m, alpha_f, gamma, beta, beta') , the integrated coordinates
#: free and kept rows, length weights w (m per unit), the system length (m), the bodies'
#: deflection limits (nb,) m, the Newton tolerance, rtol (<= 0: fixed step), atol (m), the
#: nominal step (s) and the output interval (s; <= 0: every step)
GaConstants = namedtuple("GaConstants", ["prm", "free", "kept", "w", "length", "limits", "tol", "rtol", "atol",
                                         "h_nominal", "out_dt"])
#: a run's workspace (made once per run, ``ga_workspace``): the Evaluations (assemble.evaluation_arrays)
#: of the Newton iterate e and of the finite-difference columns e_col, the multipliers of all rows
#: lam_all (m_all,), the Newton residuals r and r_col (free + kept,), the iteration matrix jac
#: (free + kept, free + kept), and the run's work integrals
#: work (3,) = [applied loads, dissipated, drivers] (J) and power flows at its current state
#: flows (4,) (W; NaN before the first step), carried from one call of ga_loop to the next
#: and the force elements' bump-stop penetrations pen and their rates rate (nfe,; m, m/s) at the
#: current state, those at the end of the step on trial, pen_new and rate_new, and the largest
#: normal speed of each stop's current contact, speed (nfe,; m/s; forces.stop_states)
GaWorkspace = namedtuple("GaWorkspace", ["e", "e_col", "lam_all", "r", "r_col", "jac", "work", "flows", "pen",
                                         "rate", "pen_new", "rate_new", "speed"])


def ga_workspace(L, constants) -> GaWorkspace:
    """The GaWorkspace of a run with layout L and GaConstants ``constants``."""
    m_all = constraint_rows(L)
    size = constants.free.size + constants.kept.size
    nfe = L.fe_int.shape[0]
    return GaWorkspace(evaluation_arrays(L), evaluation_arrays(L), np.zeros(m_all), np.zeros(size), np.zeros(size),
                       np.zeros((size, size)), np.zeros(3), np.full(4, np.nan), np.full(nfe, -np.inf), np.zeros(nfe),
                       np.full(nfe, -np.inf), np.zeros(nfe), np.zeros(nfe))


def genalpha_parameters(rho_inf: float) -> tuple[float, float, float, float]:
    """(alpha_m, alpha_f, gamma, beta) of Chung & Hulbert (1993) for spectral radius rho_inf."""
    if not 0.0 <= rho_inf <= 1.0:
        raise ValueError(f"rho_inf must be in [0, 1], got {rho_inf}")
    am = (2 * rho_inf - 1) / (rho_inf + 1)
    af = rho_inf / (rho_inf + 1)
    gamma = 0.5 + af - am
    return am, af, gamma, 0.25 * (gamma + 0.5) ** 2


@jit
def ga_state(L, udn, x, h, prm):  # pragma: no cover - compiled
    """(a_{n+1}, R, A, Q, u_{n+1}) of the update of the GaState x for ud_{n+1} (module doc)."""
    am, af, gamma, beta = prm[0], prm[1], prm[2], prm[3]
    n = udn.shape[0]
    an, dx, un = np.empty(n), np.empty(n), np.empty(n)
    for i in range(n):  # element by element: three arrays instead of one per operation
        an[i] = (af * x.ud[i] + (1 - af) * udn[i] - am * x.a[i]) / (1 - am)
        dx[i] = h * x.u[i] + h * h * ((0.5 - beta) * x.a[i] + beta * an[i])
        un[i] = x.u[i] + h * ((1 - gamma) * x.a[i] + gamma * an[i])
    R2, A2, Q2 = advance_pose(L, x.R, x.A, x.Q, dx, True)
    return an, R2, A2, Q2, un


@jit
def newton_residual(e, udn, lamn, h, c, r):  # pragma: no cover - compiled
    """r (free + kept,; written in place) = [M ud - f + B_F^T lambda; g / (h^2 beta')] on the
    free coordinates and kept rows of the GaConstants c, from the Evaluation e at the state
    updated for (udn, lamn).  (The loop calls evaluate_into itself: every compiled function
    that calls it re-optimises its whole call tree, seconds of compilation each;
    docs/performance.md.)"""
    free, kept = c.free, c.kept
    nf, m = free.shape[0], kept.shape[0]
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
        r[nf + k] = e.g[kept[k]] / (h * h * c.prm[4])


@jit
def dense_state(L, x0, x1, h, theta):  # pragma: no cover - compiled
    """(R, A, Q, u, ud, lam) at t_n + theta h inside the step from GaState x0 to x1 (module doc,
    Output): the increment delta(theta) on the Lie group, u by cubic Hermite, ud and lam linear;
    u, ud handed out inertial (se3.py)."""
    b00, b10, b01, b11 = hermite(theta)
    step = body_increment(L, x0.R, x0.A, x1.R, x1.A, x0.Q, x1.Q)  # h dx: what took x0 to x1 (ga_state)
    n, m = step.shape[0], x0.lam.shape[0]
    delta, u, ud, lam = np.empty(n), np.empty(n), np.empty(n), np.empty(m)
    for i in range(n):  # element by element: one array per quantity
        delta[i] = b10 * h * x0.u[i] + b01 * step[i] + b11 * h * x1.u[i]
        u[i] = b00 * x0.u[i] + b10 * h * x0.ud[i] + b01 * x1.u[i] + b11 * h * x1.ud[i]
        ud[i] = (1.0 - theta) * x0.ud[i] + theta * x1.ud[i]
    for k in range(m):
        lam[k] = (1.0 - theta) * x0.lam[k] + theta * x1.lam[k]
    R, A, Q = advance_pose(L, x0.R, x0.A, x0.Q, delta, True)
    return R, A, Q, inertial_velocities(L, A, u), inertial_accelerations(L, A, u, ud), lam


@jit
def state_flows(L, e, x, lam_all, mass_power):  # pragma: no cover - compiled
    """The power flows (4,) at the GaState x (SE(3) coordinates) from its Evaluation e (the same
    coordinates): e.flows, to whose drives' power flows[3] the power through the rheonomic rows
    at the multipliers lam_all (m_all,) and that of the moving masses (mass_power, W;
    assemble.moving_masses, computed by the loop) are added."""
    flows = e.flows.copy()
    flows[3] += constraint_power(L, e.B, e.bt, x.u, lam_all) + mass_power
    return flows


@jit
def iteration_matrix(e, D, free, kept, jac):  # pragma: no cover - compiled
    """[M + D, B_F^T; B, 0] (free + kept, free + kept) written into jac, with M, B, B_F of the
    Evaluation e restricted to the free coordinates and the kept rows."""
    nf, m = free.shape[0], kept.shape[0]
    for i in range(nf):
        for j in range(nf):
            jac[i, j] = e.M[free[i], free[j]] + D[i, j]
        for k in range(m):
            jac[i, nf + k] = e.BF[kept[k], free[i]]
            jac[nf + k, i] = e.B[kept[k], free[i]]
    for k in range(m):
        for j in range(m):
            jac[nf + k, nf + j] = 0.0


@jit
def local_error(udn, an, x, h, c):  # pragma: no cover - compiled
    """RMS of the weighted local error estimate (module doc) of the step from GaState x to
    (udn, an) over the free coordinates, in units of atol + rtol L (<= 1: accept)."""
    gamma, beta = c.prm[2], c.prm[3]
    acc = 0.0
    for k in range(c.free.shape[0]):
        i = c.free[k]
        ex = h * h * ((0.5 - beta) * x.a[i] + beta * an[i] - x.ud[i] / 3.0 - udn[i] / 6.0)
        eu = h * h * ((1 - gamma) * x.a[i] + gamma * an[i] - 0.5 * (x.ud[i] + udn[i]))
        e = max(abs(ex), abs(eu)) * c.w[i] / (c.atol + c.rtol * c.length)
        acc += e * e
    return np.sqrt(acc / max(c.free.shape[0], 1))


@jit
def approach_bound(ws, h):  # pragma: no cover - compiled
    """The step h (s) bounded so that no open stop closing at its current rate is reached
    beyond APPROACH_REACH times its gap (module doc, Contacts)."""
    for i in range(ws.pen.shape[0]):
        if -np.inf < ws.pen[i] <= 0.0 and ws.rate[i] > 0.0:
            h = min(h, max(APPROACH_REACH * -ws.pen[i] / ws.rate[i], 1e-3 * h))
    return h


@jit
def contact_factor(ws, speed_floor):  # pragma: no cover - compiled
    """(accept, factor) of a converged step from the stop states ws.pen, ws.rate to
    ws.pen_new, ws.rate_new (module doc, Contacts): a step that engages or releases a stop
    with the kink before its last CROSSING_TAIL, or changes an engaged stop's normal rate by
    more than 2 V / CONTACT_STEPS, is rejected and factor (< 1) shortens it; an accepted step's
    factor (>= 1 or inf) bounds the growth of the next.  speed_floor: the least V, m/s."""
    accept, factor = True, np.inf
    for i in range(ws.pen.shape[0]):
        p0, p1 = ws.pen[i], ws.pen_new[i]
        if p0 == -np.inf:
            continue
        if (p0 <= 0.0) != (p1 <= 0.0):  # a kink inside the step: at theta of it (secant)
            theta = p0 / (p0 - p1)
            if theta < 1.0 - CROSSING_TAIL:
                accept, factor = False, min(factor, max(theta, 1e-6) / (1.0 - 0.5 * CROSSING_TAIL))
                continue
        if p0 > 0.0 or p1 > 0.0:
            v = max(ws.speed[i], abs(ws.rate[i]), abs(ws.rate_new[i]), speed_floor)
            change = abs(ws.rate_new[i] - ws.rate[i])
            bound = 2.0 * v / CONTACT_STEPS
            if change > bound:
                accept = False
                factor = min(factor, max(H_SHRINK, SAFETY * bound / change))
            elif accept and change > 0.0:
                factor = min(factor, SAFETY * bound / change)
    return accept, factor


@jit
def contact_accepted(ws):  # pragma: no cover - compiled
    """Take the trial stop states as the current ones; the speed scale of each engaged stop's
    contact grows to its largest normal speed, an open stop's is reset.  True when a stop is
    engaged."""
    engaged = False
    for i in range(ws.pen.shape[0]):
        if ws.pen_new[i] > 0.0:
            engaged = True
            ws.speed[i] = max(ws.speed[i], abs(ws.rate[i]), abs(ws.rate_new[i]))
        else:
            ws.speed[i] = 0.0
        ws.pen[i], ws.rate[i] = ws.pen_new[i], ws.rate_new[i]
    return engaged


@jit
def deflection_check(L, Q, c, status):  # pragma: no cover - compiled
    """False (and the body and its deflection, m, in status) when a body's elastic deflection
    |w Q| exceeds its limit (the floating frame's small-deformation range)."""
    within = True
    for b in range(L.qoff.shape[0] - 1):
        d2 = 0.0
        for k in range(L.qoff[b + 1] - L.qoff[b]):
            d2 += (Q[L.qoff[b] + k] * c.w[L.uoff[b] + 6 + k]) ** 2
        if not np.sqrt(d2) <= c.limits[b]:
            status.code, status.body, status.deflection = LARGE_DEFORMATION, b, np.sqrt(d2)
            within = False
    return within


@jit
def ga_loop(L, c, ws, x, t, t_end, h, next_index, refs, stats, capacity, post):  # pragma: no cover - compiled
    """Generalised-alpha steps of the GaState x from t until t_end or until ``capacity`` output
    samples besides the start's (so that the stretches end at the same steps whether or not it is
    recorded), with the run's GaConstants c and GaWorkspace ws; samples at next_index c.out_dt,
    (next_index + 1) c.out_dt, ... (dense_state; a sample at a step's end is that step's state),
    or after every step (c.out_dt <= 0), and at t_end; the first call records the start as the
    run's first sample.  The samples' outputs (outputs.sample_outputs with the PostSetup post)
    are computed here too, so that one compiled entry holds the evaluation's call tree.

    c.rtol <= 0: fixed step h (cut in halves when Newton fails, then doubled back).  ws.work (3,)
    the work integrals [applied loads, dissipated, drivers] and ws.flows (4,) the power flows at
    the current state (NaN before the first call: computed here, and x.a set to x.ud) are
    updated in place, as refs (angle references) and stats (base.STATUS, one record).  Returns
    the new GaState, t, step size, next output index, the samples and their SampledOutputs.
    x.u, x.ud in and out and the samples are inertial (v_O); the steps are taken in the SE(3)
    coordinates of se3.py, in which x.a is kept.
    """
    first_call = not np.isfinite(ws.flows[0])
    ns0 = 1 if first_call else 0  # the start's row, before the loop's own samples
    room = capacity + ns0
    buf = sample_buffers(room, x.R, x.Q, x.u, x.lam, refs)
    ns = ns0
    if first_call:  # the start as given (inertial), before any conversion
        store_sample(buf, 0, t, x.R, x.A, x.Q, x.u, x.ud, x.lam, refs, ws.work)
    u_k = body_velocities(L, x.A, x.u)
    x = GaState(x.R, x.A, x.Q, u_k, body_accelerations(L, x.A, u_k, x.ud), x.a, x.lam)
    status = stats[0]
    free, kept = c.free, c.kept
    nf, m = free.shape[0], kept.shape[0]
    nj = refs.shape[0]
    masses = has_moving_masses(L)
    e, work, flows0, lam_all, r = ws.e, ws.work, ws.flows, ws.lam_all, ws.r
    if first_call:  # a = ud and the power flows at the start state
        x = GaState(x.R, x.A, x.Q, x.u, x.ud, x.ud.copy(), x.lam)
        expand(x.lam, kept, lam_all)
        u_o, ud_o = inertial_velocities(L, x.A, x.u), inertial_accelerations(L, x.A, x.u, x.ud)
        evaluate_into(L, e, x.R, x.A, x.Q, u_o, t, lam_all, refs)
        mass_power = moving_masses(L, e.kin, x.R, x.A, x.Q, u_o, ud_o, t)[0] if masses else 0.0
        stop_states(L, e.kin, ws.pen, ws.rate)
        to_body_frame(L, x.A, x.u, e)
        put(flows0, 0, state_flows(L, e, x, lam_all, mass_power))
    end_tol = 1e-12 * max(1.0, t_end)
    D = np.zeros((nf, nf))
    D_h = 0.0
    lu = np.zeros((nf + m, nf + m))
    piv = np.zeros(nf + m, dtype=np.int32)
    have_d = False
    ud_prev = x.ud.copy()
    lam_prev = x.lam.copy()
    h_prev = -1.0
    factor = 1.0
    stops = has_stops(L)
    speed_floor = CONTACT_REST_SPEED * c.length / c.h_nominal
    in_contact = False
    status.code = RUNNING
    while t < t_end - end_tol:
        if status.steps >= status.max_steps:
            status.code = MAX_STEPS
            break
        if stops:
            h = approach_bound(ws, h)
        h = min(h, t_end - t)
        if c.out_dt > 0.0 and ns > ns0 and ns + int(h / c.out_dt) + 2 > room:
            break  # the samples this step may give would not fit: the stepper resumes
        if h == h_prev:  # linear extrapolation predictor
            udn, lamn = 2.0 * x.ud - ud_prev, 2.0 * x.lam - lam_prev
        else:
            udn, lamn = x.ud.copy(), x.lam.copy()
        if have_d and D_h != h:  # the stiffness part scales with h^2; a poor fit is caught by the monitor
            D = D * (h / D_h) ** 2
            D_h = h
        want_d, fresh_d, refactored, factor_now = not have_d, False, False, True
        last = np.inf
        it = 0
        converged = False
        _, R2, A2, Q2, un = ga_state(L, udn, x, h, c.prm)
        evaluate_into(L, e, R2, A2, Q2, inertial_velocities(L, A2, un), t + h, expand(lamn, kept, lam_all), refs)
        to_body_frame(L, A2, un, e)
        newton_residual(e, udn, lamn, h, c, r)
        while True:
            if want_d:  # D = d r1 / d ud - M by forward differences at the current iterate
                eps_pos = np.sqrt(np.finfo(np.float64).eps) / (h * h * c.prm[4])
                D = np.empty((nf, nf))
                for col in range(nf):
                    delta = max(1e-7 * abs(udn[free[col]]), eps_pos)
                    trial = udn.copy()
                    trial[free[col]] += delta
                    _, R3, A3, Q3, u3 = ga_state(L, trial, x, h, c.prm)
                    evaluate_into(L, ws.e_col, R3, A3, Q3, inertial_velocities(L, A3, u3), t + h, lam_all, refs)
                    to_body_frame(L, A3, u3, ws.e_col)
                    newton_residual(ws.e_col, trial, lamn, h, c, ws.r_col)
                    r1 = ws.r_col
                    for row in range(nf):
                        D[row, col] = (r1[row] - r[row]) / delta - e.M[free[row], free[col]]
                D_h, have_d, fresh_d, want_d, factor_now = h, True, True, False, True
                status.jacobians += 1
            if factor_now:  # M, B of this iterate; D re-used over steps
                iteration_matrix(e, D, free, kept, ws.jac)
                lu, piv = lu_factor(ws.jac)
                factor_now = False
            drift = 0.0  # constraint residual before this update, m or rad
            for k in range(m):
                drift = max(drift, abs(r[nf + k]))
            drift *= h * h * c.prm[4]
            dz = lu_solve(lu, piv, r)
            for i in range(nf):
                udn[free[i]] -= dz[i]
            for k in range(m):
                lamn[k] -= dz[nf + k]
            it += 1
            err = 0.0
            for i in range(nf + m):
                if not np.isfinite(dz[i]):
                    err = np.inf
                elif i < nf:
                    err = max(err, abs(dz[i]) * c.w[free[i]])
            err *= h * h * c.prm[4] / c.length
            if not np.isfinite(err):
                break
            if err <= c.tol and drift <= c.tol * c.length:  # the update shrinks the drift further
                converged = True
                break
            _, R2, A2, Q2, un = ga_state(L, udn, x, h, c.prm)
            evaluate_into(L, e, R2, A2, Q2, inertial_velocities(L, A2, un), t + h, expand(lamn, kept, lam_all),
                          refs)
            to_body_frame(L, A2, un, e)
            newton_residual(e, udn, lamn, h, c, r)
            if it >= MAX_NEWTON or (it > 1 and err > SLOW_CONTRACTION * last):
                if not refactored:  # first: the current M, B with the old D
                    refactored, factor_now, it, last = True, True, 0, np.inf
                    continue
                if not fresh_d:  # then: a new D
                    want_d, it, last = True, 0, np.inf
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
        an, R2, A2, Q2, un = ga_state(L, udn, x, h, c.prm)
        contact_growth = np.inf
        if stops:  # the last evaluation is the converged state's, within the Newton tolerance
            stop_states(L, e.kin, ws.pen_new, ws.rate_new)
            accept, contact_growth = contact_factor(ws, speed_floor)
            if not accept:
                status.rejected += 1
                h *= contact_growth
                h_prev = -1.0
                continue
        if c.rtol > 0.0:
            est = local_error(udn, an, x, h, c)
            factor = SAFETY * est ** (-1.0 / 3.0) if est > 0 else H_GROW
            if est > 1.0:
                status.rejected += 1
                h *= max(H_SHRINK, factor)
                continue
        if not deflection_check(L, Q2, c, status):
            break
        if stops:
            in_contact = contact_accepted(ws)
        ud_prev, lam_prev, h_prev = x.ud, x.lam, h
        t_old, x_old, work_old = t, x, work.copy()
        t += h
        x = GaState(R2, A2, Q2, un, udn, an, lamn)
        status.steps += 1
        status.h_min = min(status.h_min, h)
        status.h_max = max(status.h_max, h)
        # with the converged multipliers (the last evaluation predates them) and ud
        u_o, ud_o = inertial_velocities(L, x.A, x.u), inertial_accelerations(L, x.A, x.u, x.ud)
        mass_power = 0.0
        if masses:
            markers_into(L, ws.e_col.kin, x.R, x.A, x.Q, u_o, t)
            mass_power = moving_masses(L, ws.e_col.kin, x.R, x.A, x.Q, u_o, ud_o, t)[0]
        flows = state_flows(L, e, x, expand(lamn, kept, lam_all), mass_power)
        work[0] += 0.5 * h * (flows[0] + flows0[0])
        work[1] += 0.5 * h * (flows[1] + flows0[1])
        work[2] += 0.5 * h * (flows[3] + flows0[3])
        put(flows0, 0, flows)
        for j in range(nj):
            refs[j] = e.coords[j, 0]
        final = t >= t_end - end_tol
        at = 1e-12 * max(1.0, abs(t))
        stored = False
        while c.out_dt > 0.0 and next_index * c.out_dt <= t + at:
            t_k = next_index * c.out_dt
            if t_k >= t - at:  # at the step's end: its state (the interpolant's end point, to rounding)
                store_sample(buf, ns, t_k, x.R, x.A, x.Q, u_o, ud_o, x.lam, refs, work)
            else:
                theta = min(1.0, max(0.0, (t_k - t_old) / h))
                R_k, A_k, Q_k, u_k, ud_k, lam_k = dense_state(L, x_old, x, h, theta)
                store_sample(buf, ns, t_k, R_k, A_k, Q_k, u_k, ud_k, lam_k, refs,
                             (1.0 - theta) * work_old + theta * work)
            ns, next_index, stored = ns + 1, next_index + 1, t_k >= t - at
        if c.out_dt <= 0.0 or (final and not stored):
            store_sample(buf, ns, t, x.R, x.A, x.Q, u_o, ud_o, x.lam, refs, work)
            ns += 1
        if c.rtol > 0.0:
            h *= min(H_GROW, max(H_SHRINK, factor), max(1.0, contact_growth))
        elif in_contact:  # the contact's rate bound sets the step, at most the nominal one
            h = min(h * min(H_GROW, max(1.0, contact_growth)), c.h_nominal)
        elif h < c.h_nominal and status.steps % RECOVER_STEPS == 0:
            h = min(2.0 * h, c.h_nominal)
        if ns == room and not final:
            break
    if t >= t_end - end_tol and status.code == RUNNING:
        status.code = FINISHED
    x = GaState(x.R, x.A, x.Q, inertial_velocities(L, x.A, x.u), inertial_accelerations(L, x.A, x.u, x.ud), x.a,
                x.lam)
    samples = first_samples(buf, ns)
    return x, t, h, next_index, samples, sample_outputs(post.L, post.L0, samples, post.c)


def core_post(post):
    """The PostSetup ``post`` with the core's records: its layouts as Layout records (one record
    when L0 is L) and its PostConstants as the core's."""
    L = layout_record(post.L)
    L0 = L if post.L0 is post.L else layout_record(post.L0)
    c = post.c if isinstance(post.c, CorePostConstants) else CorePostConstants(*post.c)
    return post._replace(L=L, L0=L0, c=c)


class GeneralizedAlpha(Stepper):
    """The generalised-alpha stepper (module doc) on the compiled loop (core/genalpha.pyx ga_loop)."""

    name = "genalpha"

    def __init__(self, problem, state, settings):
        super().__init__(problem, state, settings)
        am, af, gamma, beta = genalpha_parameters(settings.rho_inf)
        L = layout_record(problem.L)
        constants = core.GaConstants((am, af, gamma, beta, beta * (1 - af) / (1 - am)),
                                     body_frame_free(problem.free, np.asarray(L.uoff)), problem.kept, problem.weights,
                                     float(problem.length), settings.deformation_limit * problem.sizes,
                                     float(settings.newton_tol), float(settings.tolerance or 0.0),
                                     float(settings.atol), float(settings.h), float(settings.output_dt or 0.0))
        self.loop = core.GaRun(L, constants, problem.refs, settings.max_steps, core_post(problem.post), settings.h)
        self.loop.t = state.t
        # the loop's state (its own arrays; a in the coordinates of se3.py: ga_loop starts it at ud)
        self.x = core.GaState(*(np.array(v, dtype=float) for v in (state.R, state.A, state.Q, state.u, state.ud)),
                              np.full(state.u.size, np.nan), np.array(state.lam, dtype=float))
        self.outputs = []

    def advance(self, t_stop: float) -> Samples:
        p, s, st, loop = self.problem, self.state, self.settings, self.loop
        samples, out = core.ga_loop(loop, self.x, t_stop, CHUNK)
        self.outputs.append(out)
        s.t = loop.t
        s.R, s.A, s.Q, s.u, s.ud, _, s.lam = (v.copy() for v in self.x.arrays())
        record = loop.status
        if record.code == MAX_STEPS:
            self.status, self.message = "failed", (f"max_steps = {st.max_steps} reached at t = {s.t:.6g} s; raise "
                                                   "max_steps or the step size h")
        elif record.code == LARGE_DEFORMATION:
            body, deflection = int(record.body), float(record.deflection)
            self.status, self.large_deformation = "failed", (body, deflection, s.t + loop.h)
            self.message = (f"body {body} left its small-deformation range at t = {s.t + loop.h:.6g} s "
                            f"(deflection {deflection:.3g} m)")
        elif record.code == NEWTON_FAILED:
            self.status, self.message = "failed", (f"Newton did not converge at t = {s.t:.6g} s even with tiny steps; "
                                                   "check the scene (joint axes, loads, units) or raise newton_tol")
        elif record.code == FINISHED and s.t >= p.t_end - 1e-12 * max(1.0, p.t_end):
            self.status = "finished"
        for key in ("steps", "rejected", "newton_iterations", "jacobians", "h_min", "h_max"):
            self.stats[key] = float(getattr(record, key)) if key.startswith("h_") else int(getattr(record, key))
        return Samples(*samples)
