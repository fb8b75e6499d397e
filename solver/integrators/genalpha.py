"""Lie-group generalised-alpha for the index-3 DAE (Arnold & Bruls 2007; Bruls, Cardona &
Arnold 2012), on SE(3) x R^nq per body (se3.py: body-frame translational velocities, so that a
uniform rotation about any fixed axis is integrated exactly; on R^3 x SO(3) a body whirling
about a hinge away from its frame origin gained energy ~ h^2 Omega^3, issue 22):

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

Error control (rtol given): the local error of the step against the third-order Taylor
expansion written with the true accelerations ud (not the alpha-lagged a),

    e_x = h^2 [(1/2 - beta) a_n + beta a_{n+1} - ud_n / 3 - ud_{n+1} / 6]
    e_u = h   [(1 - gamma) a_n + gamma a_{n+1} - (ud_n + ud_{n+1}) / 2]

measured in lengths (e_x and h e_u, weighted to metres), RMS against atol + rtol L.  For
Newmark (a = ud) e_x reduces to the classic h^2 (beta - 1/6) (ud_{n+1} - ud_n); with alpha
damping it also sees the lag of a behind ud, which the classic estimate misses.
"""

from __future__ import annotations

import numpy as np

from sidprep.solver.equations.assemble import constraint_power, evaluate, moving_masses
from sidprep.solver.equations.rotations import jit, matvec, put, put2
from sidprep.solver.integrators.base import (CHUNK, Samples, Stepper, advance_pose, expand, lu_factor, lu_solve,
                                             restrict, store_sample)
from sidprep.solver.integrators.se3 import (body_accelerations, body_frame_free, body_velocities,
                                            evaluate_se3, inertial_accelerations, inertial_velocities)

#: maximum Newton iterations with one iteration matrix
MAX_NEWTON = 6
#: contraction factor above which the iteration matrix is renewed
SLOW_CONTRACTION = 0.3
#: fixed-step mode: successful steps after a step cut before the step is doubled again
RECOVER_STEPS = 4
#: step-size factor limits and safety factor of the error control
H_GROW, H_SHRINK, SAFETY = 2.0, 0.2, 0.9
#: run status codes of the compiled loop
RUNNING, FINISHED, MAX_STEPS, NEWTON_FAILED, LARGE_DEFORMATION = 0, 1, 2, 3, 4



def genalpha_parameters(rho_inf: float) -> tuple[float, float, float, float]:
    """(alpha_m, alpha_f, gamma, beta) of Chung & Hulbert (1993) for spectral radius rho_inf."""
    if not 0.0 <= rho_inf <= 1.0:
        raise ValueError(f"rho_inf must be in [0, 1], got {rho_inf}")
    am = (2 * rho_inf - 1) / (rho_inf + 1)
    af = rho_inf / (rho_inf + 1)
    gamma = 0.5 + af - am
    return am, af, gamma, 0.25 * (gamma + 0.5) ** 2


@jit
def ga_state(L, udn, R, A, Q, u, ud, a, h, prm):  # pragma: no cover - compiled
    """(a_{n+1}, R, A, Q, u_{n+1}) of the update for ud_{n+1} (module doc)."""
    am, af, gamma, beta = prm[0], prm[1], prm[2], prm[3]
    an = (af * ud + (1 - af) * udn - am * a) / (1 - am)
    R2, A2, Q2 = advance_pose(L, R, A, Q, h * u + h * h * ((0.5 - beta) * a + beta * an), True)
    return an, R2, A2, Q2, u + h * ((1 - gamma) * a + gamma * an)


@jit
def ga_residual(L, udn, lamn, R, A, Q, u, ud, a, h, t, refs, prm, free, kept):  # pragma: no cover - compiled
    """r = [M ud - f + B_F^T lambda; g / (h^2 beta')] on the free coordinates and kept rows,
    and M, f, B, B_F (all coordinates and rows), the joint coordinates and the power flows at the
    updated state."""
    m_all = L.joint_off[-1] + L.drv_joint.shape[0]
    _, R2, A2, Q2, un = ga_state(L, udn, R, A, Q, u, ud, a, h, prm)
    M, f, g, B, BF, bt, C, coords, loads, flows = evaluate_se3(L, R2, A2, Q2, un, t, expand(lamn, kept, m_all), refs)
    nf, m = free.shape[0], kept.shape[0]
    r = np.empty(nf + m)
    full = matvec(M, udn)
    for i in range(nf):
        acc = full[free[i]] - f[free[i]]
        for k in range(m):
            acc += BF[kept[k], free[i]] * lamn[k]
        r[i] = acc
    for k in range(m):
        r[nf + k] = g[kept[k]] / (h * h * prm[4])
    return r, M, f, B, BF, bt, coords, flows


@jit
def iteration_matrix(Mf, D, Bk, BFk):  # pragma: no cover - compiled
    """[M + D, B_F^T; B, 0]."""
    nf, m = Mf.shape[0], Bk.shape[0]
    jac = np.zeros((nf + m, nf + m))
    put2(jac, 0, 0, Mf + D)
    put2(jac, 0, nf, BFk.T)
    put2(jac, nf, 0, Bk)
    return jac


@jit
def local_error(udn, ud, an, a, h, prm, w, free, atol, rtol, length):  # pragma: no cover - compiled
    """RMS of the weighted local error estimate (module doc) over the free coordinates, in
    units of atol + rtol L (<= 1: accept)."""
    gamma, beta = prm[2], prm[3]
    acc = 0.0
    for k in range(free.shape[0]):
        i = free[k]
        ex = h * h * ((0.5 - beta) * a[i] + beta * an[i] - ud[i] / 3.0 - udn[i] / 6.0)
        eu = h * h * ((1 - gamma) * a[i] + gamma * an[i] - 0.5 * (ud[i] + udn[i]))
        e = max(abs(ex), abs(eu)) * w[i] / (atol + rtol * length)
        acc += e * e
    return np.sqrt(acc / max(free.shape[0], 1))


@jit
def ga_loop(L, R, A, Q, u, ud, a, lam, t, t_end, h, h_nominal, prm, free, kept, w, length, limits, tol, rtol, atol,
            out_dt, next_out, refs, work, flows0, stats, capacity):  # pragma: no cover - compiled
    """Generalised-alpha steps from t until t_end or until ``capacity`` output samples.

    rtol <= 0: fixed step h (cut in halves when Newton fails, then doubled back).  work (3,)
    the work integrals [applied loads, dissipated, drivers] and flows0 (4,) the power flows at
    the current state are updated in place, as refs (angle references) and stats [steps,
    rejected, newton iterations, jacobians, h_min, h_max, status, max_steps, body, deflection]
    (the last two: the body that left its small-deformation range, ``limits`` (nb,) m, and its
    deflection, m).  Returns the new state, step size, next output time and the samples.
    u, ud in and out and the samples are inertial (v_O); the steps are taken in the SE(3)
    coordinates of se3.py, in which ``a`` is kept.
    """
    u = body_velocities(L, A, u)
    ud = body_accelerations(L, A, u, ud)
    nf, m, n = free.shape[0], kept.shape[0], u.shape[0]
    nj = refs.shape[0]
    m_all = L.joint_off[-1] + L.drv_joint.shape[0]
    ts = np.empty(capacity)
    Rs = np.empty((capacity,) + R.shape)
    As = np.empty((capacity,) + A.shape)
    Qs = np.empty((capacity, Q.shape[0]))
    us = np.empty((capacity, n))
    uds = np.empty((capacity, n))
    lams = np.empty((capacity, m))
    refss = np.empty((capacity, nj))
    works = np.empty((capacity, 3))
    ns = 0
    end_tol = 1e-12 * max(1.0, t_end)
    D = np.zeros((nf, nf))
    D_h = 0.0
    lu = np.zeros((nf + m, nf + m))
    piv = np.zeros(nf + m, dtype=np.int32)
    have_d = False
    ud_prev = ud.copy()
    lam_prev = lam.copy()
    h_prev = -1.0
    factor = 1.0
    stats[6] = RUNNING
    while t < t_end - end_tol:
        if stats[0] >= stats[7]:
            stats[6] = MAX_STEPS
            break
        h = min(h, t_end - t)
        if rtol > 0.0 and out_dt > 0.0 and next_out - t > end_tol:
            h = min(h, next_out - t)
        if h == h_prev:  # linear extrapolation predictor
            udn, lamn = 2.0 * ud - ud_prev, 2.0 * lam - lam_prev
        else:
            udn, lamn = ud.copy(), lam.copy()
        if have_d and D_h != h:  # the stiffness part scales with h^2; a poor fit is caught by the monitor
            D = D * (h / D_h) ** 2
            D_h = h
        want_d, fresh_d, refactored, factor_now = not have_d, False, False, True
        last = np.inf
        it = 0
        converged = False
        r, M, f, B, BF, bt, coords, flows = ga_residual(L, udn, lamn, R, A, Q, u, ud, a, h, t + h, refs, prm, free, kept)
        while True:
            if want_d:  # D = d r1 / d ud - M by forward differences at the current iterate
                eps_pos = np.sqrt(np.finfo(np.float64).eps) / (h * h * prm[4])
                D = np.empty((nf, nf))
                for col in range(nf):
                    e = max(1e-7 * abs(udn[free[col]]), eps_pos)
                    x = udn.copy()
                    x[free[col]] += e
                    r1 = ga_residual(L, x, lamn, R, A, Q, u, ud, a, h, t + h, refs, prm, free, kept)[0]
                    for row in range(nf):
                        D[row, col] = (r1[row] - r[row]) / e - M[free[row], free[col]]
                D_h, have_d, fresh_d, want_d, factor_now = h, True, True, False, True
                stats[3] += 1
            if factor_now:  # M, B of this iterate; D re-used over steps
                Mf, _, Bk, BFk = restrict(M, f, B, BF, free, kept)
                lu, piv = lu_factor(iteration_matrix(Mf, D, Bk, BFk))
                factor_now = False
            drift = 0.0  # constraint residual before this update, m or rad
            for k in range(m):
                drift = max(drift, abs(r[nf + k]))
            drift *= h * h * prm[4]
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
                    err = max(err, abs(dz[i]) * w[free[i]])
            err *= h * h * prm[4] / length
            if not np.isfinite(err):
                break
            if err <= tol and drift <= tol * length:  # the update shrinks the drift further
                converged = True
                break
            r, M, f, B, BF, bt, coords, flows = ga_residual(L, udn, lamn, R, A, Q, u, ud, a, h, t + h, refs, prm, free,
                                                        kept)
            if it >= MAX_NEWTON or (it > 1 and err > SLOW_CONTRACTION * last):
                if not refactored:  # first: the current M, B with the old D
                    refactored, factor_now, it, last = True, True, 0, np.inf
                    continue
                if not fresh_d:  # then: a new D
                    want_d, it, last = True, 0, np.inf
                    continue
                break
            last = err
        stats[2] += it
        if not converged:
            stats[1] += 1
            h *= 0.5
            have_d = False
            h_prev = -1.0
            if h < 1e-14 * max(1.0, t_end):
                stats[6] = NEWTON_FAILED
                break
            continue
        an, R2, A2, Q2, un = ga_state(L, udn, R, A, Q, u, ud, a, h, prm)
        if rtol > 0.0:
            est = local_error(udn, ud, an, a, h, prm, w, free, atol, rtol, length)
            factor = SAFETY * est ** (-1.0 / 3.0) if est > 0 else H_GROW
            if est > 1.0:
                stats[1] += 1
                h *= max(H_SHRINK, factor)
                continue
        for b in range(L.qoff.shape[0] - 1):  # elastic deflections within the small-deformation range
            d2 = 0.0
            for k in range(L.qoff[b + 1] - L.qoff[b]):
                d2 += (Q2[L.qoff[b] + k] * w[L.uoff[b] + 6 + k]) ** 2
            if not np.sqrt(d2) <= limits[b]:
                stats[6], stats[8], stats[9] = LARGE_DEFORMATION, b, np.sqrt(d2)
        if stats[6] == LARGE_DEFORMATION:
            break
        ud_prev, lam_prev, h_prev = ud, lam, h
        t += h
        R, A, Q, u, ud, a, lam = R2, A2, Q2, un, udn, an, lamn
        stats[0] += 1
        stats[4] = min(stats[4], h)
        stats[5] = max(stats[5], h)
        # the drives' power through their rows with the converged multipliers (the last evaluation
        # predates them), and that of the moving masses with the converged ud
        u_O, ud_O = inertial_velocities(L, A, u), inertial_accelerations(L, A, u, ud)
        flows[3] += (constraint_power(L, B, bt, u, expand(lamn, kept, m_all))
                     + moving_masses(L, R, A, Q, u_O, ud_O, t)[0])
        work[0] += 0.5 * h * (flows[0] + flows0[0])
        work[1] += 0.5 * h * (flows[1] + flows0[1])
        work[2] += 0.5 * h * (flows[3] + flows0[3])
        put(flows0, 0, flows)
        for j in range(nj):
            refs[j] = coords[j, 0]
        final = t >= t_end - end_tol
        if final or out_dt <= 0.0 or t >= next_out - 1e-12 * max(1.0, abs(t)):
            store_sample(ns, ts, Rs, As, Qs, us, uds, lams, refss, works, t, R, A, Q, u_O, ud_O, lam, refs, work)
            ns += 1
            while out_dt > 0.0 and next_out <= t + 1e-12 * max(1.0, abs(t)):
                next_out += out_dt
        if rtol > 0.0:
            h *= min(H_GROW, max(H_SHRINK, factor))
        elif h < h_nominal and int(stats[0]) % RECOVER_STEPS == 0:
            h = min(2.0 * h, h_nominal)
        if ns == capacity and not final:
            break
    if t >= t_end - end_tol and stats[6] == RUNNING:
        stats[6] = FINISHED
    ud = inertial_accelerations(L, A, u, ud)
    u = inertial_velocities(L, A, u)
    return (R, A, Q, u, ud, a, lam, t, h, next_out, ts[:ns], Rs[:ns], As[:ns], Qs[:ns], us[:ns], uds[:ns], lams[:ns],
            refss[:ns], works[:ns])


class GeneralizedAlpha(Stepper):
    """The generalised-alpha stepper (module doc)."""

    name = "genalpha"

    def __init__(self, problem, state, settings):
        super().__init__(problem, state, settings)
        am, af, gamma, beta = genalpha_parameters(settings.rho_inf)
        self.prm = np.array([am, af, gamma, beta, beta * (1 - af) / (1 - am)])
        u_k = body_velocities(problem.L, state.A, state.u)
        self.a = body_accelerations(problem.L, state.A, u_k, state.ud)  # in the coordinates of se3.py
        self.free = body_frame_free(problem.free, problem.L.uoff)
        self.h = settings.h
        self.next_out = settings.output_dt or 0.0
        self.work = np.zeros(3)
        lam_full = np.zeros(problem.m_all)
        lam_full[problem.kept] = state.lam
        out = evaluate(problem.L, state.R, state.A, state.Q, state.u, state.t, lam_full, problem.refs)
        self.flows = out[-1]
        self.flows[3] += (constraint_power(problem.L, out[3], out[5], state.u, lam_full)
                          + moving_masses(problem.L, state.R, state.A, state.Q, state.u, state.ud, state.t)[0])
        self.raw = np.zeros(10)
        self.raw[4], self.raw[7] = np.inf, settings.max_steps

    def advance(self, t_stop: float) -> Samples:
        p, s, st = self.problem, self.state, self.settings
        out = ga_loop(p.L, s.R, s.A, s.Q, s.u, s.ud, self.a, s.lam, s.t, t_stop, self.h, st.h, self.prm, self.free, p.kept,
                      p.weights, p.length, st.deformation_limit * p.sizes, st.newton_tol, st.tolerance or 0.0, st.atol,
                      st.output_dt or 0.0,
                      self.next_out, p.refs, self.work, self.flows, self.raw, CHUNK)
        (s.R, s.A, s.Q, s.u, s.ud, self.a, s.lam, s.t, self.h, self.next_out) = out[:10]
        status = int(self.raw[6])
        if status == MAX_STEPS:
            self.status, self.message = "failed", (f"max_steps = {st.max_steps} reached at t = {s.t:.6g} s; raise "
                                                   "max_steps or the step size h")
        elif status == LARGE_DEFORMATION:
            body, deflection = int(self.raw[8]), float(self.raw[9])
            self.status, self.large_deformation = "failed", (body, deflection, s.t + self.h)
            self.message = (f"body {body} left its small-deformation range at t = {s.t + self.h:.6g} s "
                            f"(deflection {deflection:.3g} m)")
        elif status == NEWTON_FAILED:
            self.status, self.message = "failed", (f"Newton did not converge at t = {s.t:.6g} s even with tiny steps; "
                                                   "check the scene (joint axes, loads, units) or raise newton_tol")
        elif status == FINISHED and s.t >= p.t_end - 1e-12 * max(1.0, p.t_end):
            self.status = "finished"
        for k, key in enumerate(("steps", "rejected", "newton_iterations", "jacobians", "h_min", "h_max")):
            self.stats[key] = float(self.raw[k]) if key.startswith("h_") else int(self.raw[k])
        return Samples(*out[10:])
