"""Explicit Runge-Kutta methods on the index-1 form of the constrained equations:

    M ud + B_F^T lambda = f,   B ud = -gamma - 2 a g_dot - a^2 g    (Baumgarte, rate a in 1/s)

with the state y = [per body r_O (3), quaternion (4), q (nq); u (n); work (3)] (the work of
applied loads, the dissipated energy and the work of drivers are integrated with the motion,
to the method's order).  ``rk4``: classic RK4 at the fixed step h (integrators/runge_kutta.py,
the project's one RK4), compiled loop.  ``rk45`` / ``dop853``: scipy's error-controlled
RK45 / DOP853 driven step by step with the compiled right-hand side (integrators/adaptive.py).
For non-stiff scenes: the step must resolve the highest kept frequency.
"""

from __future__ import annotations

import numpy as np

from sidprep.solver.core import explicit as core
from sidprep.solver.core.records import layout_record
from sidprep.solver.core.rotations import matrix_to_quaternion
from sidprep.solver.equations.assemble import constraint_power, evaluate_into, moving_masses
from sidprep.solver.equations.rotations import jit, put, put2, quaternion_rate, quaternion_to_matrix
from sidprep.solver.integrators.base import (CHUNK, SampleBuffers, Samples, Stepper, expand, first_samples,
                                             has_friction, index1_accelerations, sample_buffers, store_sample)
from sidprep.solver.integrators.outputs import sample_outputs
from sidprep.solver.integrators.runge_kutta import hermite, rk4_combine, rk4_stage


@jit
def unpack(L, y):  # pragma: no cover - compiled
    """R (nb, 3), A (nb, 3, 3), Q, u of the explicit state y."""
    nb = L.qoff.shape[0] - 1
    R = np.empty((nb, 3))
    A = np.empty((nb, 3, 3))
    Q = np.empty(L.qoff[-1])
    o = 0
    for i in range(nb):
        nq = L.qoff[i + 1] - L.qoff[i]
        put(R[i], 0, y[o:o + 3])
        put2(A[i], 0, 0, quaternion_to_matrix(y[o + 3:o + 7]))
        put(Q, L.qoff[i], y[o + 7:o + 7 + nq])
        o += 7 + nq
    n = L.uoff[-1]
    return R, A, Q, y[o:o + n].copy()


def pack(L, R, A, Q, u, work) -> np.ndarray:
    """The explicit state y of positions, velocities and work integrals (module doc); L a layout
    (record or namedtuple)."""
    parts = []
    for i in range(len(R)):
        parts += [R[i], matrix_to_quaternion(A[i]), Q[L.qoff[i]:L.qoff[i + 1]]]
    return np.concatenate(parts + [u, work])


@jit
def index1_rhs(t, y, params):  # pragma: no cover - compiled
    """dy/dt of the explicit state; params = (L, free, kept, refs, baumgarte, lam guess (kept),
    the run's workspace W (assemble.evaluation_arrays))."""
    L, free, kept, refs, baumgarte, lam_guess, e = params
    R, A, Q, u = unpack(L, y)
    ud, lam = index1_accelerations(L, e, R, A, Q, u, t, refs, free, kept, baumgarte, lam_guess)
    put(lam_guess, 0, lam)
    lam_all = expand(lam, kept, np.zeros(e.g.shape[0]))
    if has_friction(L):  # e holds the evaluation at the last guess: only friction reads lambda
        evaluate_into(L, e, R, A, Q, u, t, lam_all, refs)
    flows = e.flows
    ydot = np.zeros(y.shape[0])
    o = 0
    for i in range(R.shape[0]):
        nq = L.qoff[i + 1] - L.qoff[i]
        s = L.uoff[i]
        put(ydot, o, u[s:s + 3])
        put(ydot, o + 3, quaternion_rate(y[o + 3:o + 7], u[s + 3:s + 6]))
        put(ydot, o + 7, u[s + 6:s + 6 + nq])
        o += 7 + nq
    n = u.shape[0]
    put(ydot, o, ud)
    ydot[o + n] = flows[0]
    ydot[o + n + 1] = flows[1]
    ydot[o + n + 2] = (flows[3] + constraint_power(L, e.B, e.bt, u, lam_all)
                       + moving_masses(L, e.kin, R, A, Q, u, ud, t)[0])
    return ydot


@jit
def sample(L, t, y, params, refs):  # pragma: no cover - compiled
    """(R, A, Q, u, ud, lam, work) at an accepted state, refs updated to its joint angles."""
    L_, free, kept, _, baumgarte, lam_guess, e = params
    R, A, Q, u = unpack(L, y)
    ud, lam = index1_accelerations(L, e, R, A, Q, u, t, refs, free, kept, baumgarte, lam_guess)
    for j in range(refs.shape[0]):  # the joint coordinates are kinematic: e's at any multipliers
        refs[j] = e.coords[j, 0]
    return R, A, Q, u, ud, lam, y[y.shape[0] - 3:].copy()


@jit
def rk4_loop(t, y, t_end, h, out_dt, next_index, params, capacity, steps, first, post):  # pragma: no cover
    """Fixed-step RK4 (runge_kutta.rk4_stage / rk4_combine around index1_rhs) from t to t_end
    (the last step shortened to land on it) or until ``capacity`` samples besides those of
    ``first``; steps (2,) counts
    the steps (up to max_steps, steps[1]); refs (params[3]) follow the accepted steps.  Samples:
    the rows of the SampleBuffers ``first`` (the start on the first call, none after), then at
    next_index out_dt, (next_index + 1) out_dt, ... from the cubic Hermite interpolant of y
    with the slopes ydot at both ends (error O(h^4), RK4's order), or after every step
    (out_dt <= 0), and at t_end.  A step whose result is not finite (beyond the stability
    limit) is not taken: the loop returns that non-finite y with t and the samples before it.
    Returns t, y, the next output index, the samples and their SampledOutputs
    (outputs.sample_outputs with the PostSetup post: one compiled entry for the steps and their
    outputs)."""
    L, refs = params[0], params[3]
    R0, A0, Q0, u0 = unpack(L, y)
    ns0 = first.t.shape[0]
    room = capacity + ns0
    buf = sample_buffers(room, R0, Q0, u0, params[5], refs)
    ns = ns0
    for k in range(ns0):
        store_sample(buf, k, first.t[k], first.R[k], first.A[k], first.Q[k], first.u[k], first.ud[k], first.lam[k],
                     first.refs[k], first.work[k])
    end_tol = 1e-12 * max(1.0, t_end)
    k1 = index1_rhs(t, y, params)
    while t < t_end - end_tol and steps[0] < steps[1]:
        step = min(h, t_end - t)
        if out_dt > 0.0 and ns > ns0 and ns + int(step / out_dt) + 2 > room:
            break  # the samples this step may give would not fit: the stepper resumes
        half = 0.5 * step
        k2 = index1_rhs(t + half, rk4_stage(y, half, k1), params)
        k3 = index1_rhs(t + half, rk4_stage(y, half, k2), params)
        k4 = index1_rhs(t + step, rk4_stage(y, step, k3), params)
        y_old, slope_old, t_old = y, k1, t
        y = rk4_combine(y, step, k1, k2, k3, k4)
        if not np.all(np.isfinite(y)):
            break  # blew up: the caller stops the run at t (the last finite state)
        t += step
        steps[0] += 1
        k1 = index1_rhs(t, y, params)  # the next step's first stage: the interpolant's end slope
        final = t >= t_end - end_tol
        at = 1e-12 * max(1.0, abs(t))
        stored = False
        while out_dt > 0.0 and next_index * out_dt <= t + at:
            t_k = next_index * out_dt
            b00, b10, b01, b11 = hermite(min(1.0, max(0.0, (t_k - t_old) / step)))
            y_k = b00 * y_old + b10 * step * slope_old + b01 * y + b11 * step * k1
            R, A, Q, u, ud, lam, work = sample(L, t_k, y_k, params, refs)
            store_sample(buf, ns, t_k, R, A, Q, u, ud, lam, refs, work)
            ns, next_index, stored = ns + 1, next_index + 1, t_k >= t - at
        if out_dt <= 0.0 or (final and not stored):
            R, A, Q, u, ud, lam, work = sample(L, t, y, params, refs)
            store_sample(buf, ns, t, R, A, Q, u, ud, lam, refs, work)
            ns += 1
        else:  # keep the angle references current between samples
            sample(L, t, y, params, refs)
        if ns == room:
            break
    samples = first_samples(buf, ns)
    return t, y, next_index, samples, sample_outputs(post.L, post.L0, samples, post.c)


def non_finite_message(t: float, h: float) -> str:
    """The failure of an explicit step from t (s) of size h (s) whose state is not finite."""
    return (f"non-finite state (NaN or inf) in the step from t = {t:.6g} s (h = {h:.3g} s): the step is beyond the "
            "stability limit of the explicit method (h omega_max > 2.8 for rk4: a stiff mode or contact); use "
            "method = \"genalpha\" or a smaller step")


class ExplicitStepper(Stepper):
    """Shared set-up of the explicit steppers: the state vector, the compiled right-hand side's
    parameters (core.explicit.RhsParams: the run's workspaces) and its samples."""

    def __init__(self, problem, state, settings):
        super().__init__(problem, state, settings)
        self.L = layout_record(problem.L)
        self.y = pack(self.L, state.R, state.A, state.Q, state.u, np.zeros(3))
        self.params = core.rhs_params(self.L, problem.free, problem.kept, problem.refs, float(settings.baumgarte),
                                      state.lam)
        self.next_out = settings.output_dt or 0.0
        self.next_index = 1

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        """dy/dt (core.explicit.index1_rhs) of the explicit state y at t (s)."""
        ydot = np.empty(y.shape[0])
        core.index1_rhs(t, np.ascontiguousarray(y, dtype=float), self.params, ydot)
        return ydot

    def sample(self, t: float, y: np.ndarray) -> tuple:
        """(R, A, Q, u, ud, lam, work) at the accepted state y at t (s) (core.explicit.sample); the
        run's angle references follow it."""
        p = self.params
        core.sample(t, np.ascontiguousarray(y, dtype=float), p)
        return tuple(np.array(a) for a in (p.R, p.A, p.Q, p.u, p.ud, p.lam)) + (y[-3:].copy(),)

    def _set_state(self, t, sample_):
        R, A, Q, u, ud, lam, _ = sample_
        self.state = type(self.state)(t, R, A, Q, u, ud, lam)


class RungeKutta4(ExplicitStepper):
    """Classic RK4 at the fixed step h (compiled loop: core.explicit.rk4_loop)."""

    name = "rk4"

    def __init__(self, problem, state, settings):
        super().__init__(problem, state, settings)
        self.outputs = []

    def first_rows(self) -> SampleBuffers:
        """The start as the run's first sample on the first call, no rows after (rk4_loop)."""
        s, rows = self.state, 0 if self.outputs else 1
        return SampleBuffers(np.full(rows, s.t), np.repeat(s.R[None], rows, 0), np.repeat(s.A[None], rows, 0),
                             np.repeat(s.Q[None], rows, 0), np.repeat(s.u[None], rows, 0),
                             np.repeat(s.ud[None], rows, 0), np.repeat(s.lam[None], rows, 0),
                             np.repeat(self.problem.refs[None], rows, 0), np.zeros((rows, 3)))

    def advance(self, t_stop: float) -> Samples:
        st = self.settings
        steps = np.array([self.stats["steps"], st.max_steps], dtype=np.int64)
        t, self.y, self.next_index, buf, out = core.rk4_loop(self.state.t, self.y, t_stop, st.h, st.output_dt or 0.0,
                                                             self.next_index, self.params, CHUNK, steps,
                                                             self.first_rows(), self.problem.post)
        self.outputs.append(out)
        arrays = tuple(buf)
        self.stats["steps"] = int(steps[0])
        self.stats["rhs_evaluations"] = 4 * int(steps[0])
        self.stats["h_min"] = self.stats["h_max"] = st.h
        if len(arrays[0]):
            self.state = type(self.state)(t, arrays[1][-1], arrays[2][-1], arrays[3][-1], arrays[4][-1],
                                          arrays[5][-1], arrays[6][-1])
        self.state.t = t
        if not np.all(np.isfinite(self.y)):
            self.status, self.message = "failed", non_finite_message(t, st.h)
        elif t >= self.problem.t_end - 1e-12 * max(1.0, self.problem.t_end):
            self.status = "finished"
        elif steps[0] >= st.max_steps:
            self.status, self.message = "failed", f"max_steps = {st.max_steps} reached at t = {t:.6g} s"
        return Samples(*arrays)
