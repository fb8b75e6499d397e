"""Explicit Runge-Kutta methods on the index-1 form of the constrained equations:

    M ud + B_F^T lambda = f,   B ud = -gamma - 2 a g_dot - a^2 g    (Baumgarte, rate a in 1/s)

with the state y = [per body r_O (3), quaternion (4), q (nq); u (n); work (3)] (the work of
applied loads, the dissipated energy and the work of drivers are integrated with the motion,
to the method's order).  ``rk4``: classic RK4 at the fixed step h (core/runge_kutta.pyx,
the project's one RK4), compiled loop (core/explicit.pyx).  ``rk45`` / ``dop853``: scipy's error-controlled
RK45 / DOP853 driven step by step with the compiled right-hand side (integrators/adaptive.py).
For non-stiff scenes: the step must resolve the highest kept frequency.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from sidprep.solver.core import explicit as core
from sidprep.solver.core.records import layout_record
from sidprep.solver.core.rotations import matrix_to_quaternion
from sidprep.solver.core.steps import SampleArrays
from sidprep.solver.integrators.base import CHUNK, Stepper


def pack(L, R, A, Q, u, work) -> np.ndarray:
    """The explicit state y of positions, velocities and work integrals (module doc); L a layout
    (record or namedtuple)."""
    parts = []
    for i in range(len(R)):
        parts += [R[i], matrix_to_quaternion(A[i]), Q[L.qoff[i]:L.qoff[i + 1]]]
    return np.concatenate(parts + [u, work])


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

    def first_rows(self) -> SampleArrays:
        """The start as the run's first sample on the first call, no rows after (rk4_loop)."""
        s, rows = self.state, 0 if self.outputs else 1
        return SampleArrays(np.full(rows, s.t), np.repeat(s.R[None], rows, 0), np.repeat(s.A[None], rows, 0),
                            np.repeat(s.Q[None], rows, 0), np.repeat(s.u[None], rows, 0),
                            np.repeat(s.ud[None], rows, 0), np.repeat(s.lam[None], rows, 0),
                            np.repeat(self.problem.refs[None], rows, 0), np.zeros((rows, 3)))

    def advance(self, t_stop: float) -> SampleArrays:
        st = self.settings
        steps = np.array([self.stats.steps, st.max_steps], dtype=np.int64)
        t, self.y, self.next_index, buf, out = core.rk4_loop(self.state.t, self.y, t_stop, st.h, st.output_dt or 0.0,
                                                             self.next_index, self.params, CHUNK, steps,
                                                             self.first_rows(), self.problem.post)
        self.outputs.append(out)
        arrays = tuple(buf)
        self.stats = replace(self.stats, steps=int(steps[0]), rhs_evaluations=4 * int(steps[0]), h_min=st.h, h_max=st.h)
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
        return buf
