"""scipy's error-controlled RK45 / DOP853 on the index-1 form (integrators/explicit.py: the
state, its compiled right-hand side and samples), driven one step at a time, with the kinks of
the force laws located (docs/solver.md, "Contacts").

The bump stops' penetrations (forces.stop_states) are event functions.  A step from an open stop
that is closing is bounded to the time it takes to close the gap at the current rate and
acceleration, so that no step jumps over a stop however thin its zone; once a bounded step has
closed the gap to ARRIVAL of what it was, the stop counts as reached and the method restarts
there with a step ARRIVAL times the last, growing from there under its error control inside the
contact.  A step whose end engages or releases a stop ends instead at the kink, located by root
finding on the method's dense output (as scipy's solve_ivp locates events), and the method
restarts there.  The breakpoints of tables over time end steps the same way (each restart's
t_bound), so a piecewise-linear load is never stepped across either.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from sidprep.solver.core.assemble import evaluate_into
from sidprep.solver.core.explicit import unpack
from sidprep.solver.core.forces import (FE_FORCE, FE_INT_JOINT, FE_INT_KIND, FE_INT_TABLE, FE_INT_TABLE_COLUMNS,
                                        FE_TORQUE, has_stops, stop_states)
from sidprep.solver.core.records import evaluation_arrays
from sidprep.solver.core.steps import SampleArrays
from sidprep.solver.integrators.base import CHUNK
from sidprep.solver.integrators.explicit import ExplicitStepper, non_finite_message

#: a stop counts as reached when a step bounded by its approach closed its gap to this fraction;
#: the method then restarts with this fraction of the last step
ARRIVAL = 1e-3


def time_kinks(L, t_end: float) -> np.ndarray:
    """Sorted breakpoints in (0, t_end] s of the tables over time (point forces and torques
    without an argument joint), periods unrolled: where their piecewise-linear loads kink; L the
    layout's namedtuple of arrays."""
    kinks = []
    for row in L.fe_int:
        if row[FE_INT_KIND] not in (FE_FORCE, FE_TORQUE) or row[FE_INT_JOINT] >= 0 or row[FE_INT_TABLE_COLUMNS] == 0:
            continue
        for curve in range(row[FE_INT_TABLE], row[FE_INT_TABLE] + row[FE_INT_TABLE_COLUMNS]):
            start, n = L.curve_meta[curve, 0], L.curve_meta[curve, 1]
            x, period = L.curve_x[start:start + n], L.curve_period[curve]
            if period > 0.0:
                shifts = period * np.arange(np.floor(-x[-1] / period), np.ceil((t_end - x[0]) / period) + 1)
                x = (x[None, :] + shifts[:, None]).ravel()
            kinks.append(x)
    x = np.unique(np.concatenate(kinks)) if kinks else np.zeros(0)
    return x[(x > 0.0) & (x <= t_end)]


class StopEvents:
    """The bump stops of a run as event functions of the explicit state y (module doc): their
    penetrations and rates (m, m/s) at (t, y) by the compiled stop_states on the evaluated
    markers."""

    def __init__(self, L, refs):
        """L: the run's Layout record, refs (nj,) its angle references."""
        self.L, self.refs = L, refs
        self.e = evaluation_arrays(L)  # the evaluation at the event's state, zero multipliers
        self.lam = np.zeros(self.e.g.shape[0])
        nb = L.qoff.shape[0] - 1  # the unpacked state
        self.R, self.A = np.empty((nb, 3)), np.empty((nb, 3, 3))
        self.Q, self.u = np.empty(L.qoff[nb]), np.empty(L.uoff[nb])

    def pen_rate(self, t: float, y: np.ndarray):
        """(penetrations, rates) (nfe,) at (t, y); -inf for elements without a stop."""
        unpack(self.L, np.ascontiguousarray(y, dtype=float), self.R, self.A, self.Q, self.u)
        evaluate_into(self.L, self.e, self.R, self.A, self.Q, self.u, t, self.lam, self.refs)
        nfe = self.L.fe_int.shape[0]
        pen, rate = np.empty(nfe), np.empty(nfe)
        stop_states(self.L, self.e.kin, pen, rate)
        return pen, rate

    @staticmethod
    def closing_times(pen, rate, closing_acc) -> np.ndarray:
        """The time (s, inf for none) each open stop takes to close its gap -pen at the closing
        ``rate`` with the acceleration ``closing_acc`` (nfe,; m/s^2)."""
        tau = np.full(pen.shape, np.inf)
        for i, (gap, v, a) in enumerate(zip(-pen, rate, closing_acc)):
            if not (0.0 <= gap < np.inf) or (v <= 0.0 and a <= 0.0):
                continue
            if a <= 0.0:
                tau[i] = gap / v if v * v + 2.0 * a * gap >= 0.0 or a == 0.0 else np.inf
                if a < 0.0 and v * v + 2.0 * a * gap >= 0.0:
                    tau[i] = (v - np.sqrt(v * v + 2.0 * a * gap)) / -a
            else:
                tau[i] = (np.sqrt(v * v + 2.0 * a * gap) - v) / a
        return tau

    def crossing(self, dense, t0: float, t1: float, pen0, pen1):
        """(time, stop) of the earliest engagement or release of a stop in (t0, t1] (pen0, pen1
        the penetrations at both ends; located on the dense output by Brent's method), or None."""
        from scipy.optimize import brentq  # deferred: the import costs 0.2 CPU-s, a run with stops needs it

        first = None
        for i in np.flatnonzero(np.isfinite(pen0) & ((pen0 <= 0.0) != (pen1 <= 0.0))):
            def pen(tk, i=i):
                return self.pen_rate(tk, dense(tk))[0][i]

            if (pen(t0) <= 0.0) == (pen1[i] <= 0.0):  # a stop counted engaged on arrival that did not engage
                continue
            root = brentq(pen, t0, t1, xtol=1e-14 * max(1.0, t1), rtol=4 * np.finfo(float).eps)
            if first is None or root < first[0]:
                first = (root, i)
        return first


class ScipyRungeKutta(ExplicitStepper):
    """scipy's RK45 / DOP853 (error control), one step at a time, with a compiled rhs; steps
    end at the contacts' kinks and the tables' breakpoints (module doc)."""

    def __init__(self, problem, state, settings):
        super().__init__(problem, state, settings)
        from scipy.integrate import DOP853, RK45  # deferred: 0.42 CPU-s of import

        self.cls = {"rk45": RK45, "dop853": DOP853}[settings.method]
        self.name = settings.method
        #: right-hand-side evaluations so far (into ``stats`` at the end of each advance)
        self.evaluations = 0

        def fun(t, y):
            self.evaluations += 1
            return self.rhs(t, y)

        self.fun = fun
        L = self.L
        self.kinks = time_kinks(L.arrays, problem.t_end)
        self.events = StopEvents(L, problem.refs) if has_stops(L) else None
        self.max_step = np.inf
        if self.events is not None:
            self.pen, self.rate = self.events.pen_rate(state.t, self.y)
            self.closing_acc = np.zeros_like(self.rate)
        self.solver = self.restart(state.t, self.y, min(settings.h, problem.t_end), np.inf)

    def restart(self, t: float, y: np.ndarray, first_step: float, max_step: float):
        """A fresh scipy solver from (t, y) up to the next table breakpoint (or t_end)."""
        later = self.kinks[self.kinks > t + 1e-12 * max(1.0, t)]
        bound = float(later[0]) if later.size else self.problem.t_end
        self.max_step = max_step
        return self.cls(self.fun, t, y, bound, rtol=self.settings.tolerance, atol=self.settings.atol,
                        first_step=max(min(first_step, bound - t, max_step), 1e-12 * max(1.0, t)), max_step=max_step)

    def bound_approach(self) -> None:
        """Restart the solver with the time to the nearest open, closing stop as its max_step
        when that changed by more than a fifth (module doc)."""
        bound = float(np.min(self.events.closing_times(self.pen, self.rate, self.closing_acc), initial=np.inf))
        if bound == self.max_step or (np.isfinite(bound) and 0.8 * self.max_step <= bound <= self.max_step):
            return
        solver = self.solver
        last = solver.step_size if solver.step_size is not None else self.settings.h
        self.solver = self.restart(solver.t, solver.y, last, bound)

    def end_of_step(self, t_old: float):
        """(t, y, dense) where the step from t_old ends: the solver's own end, or the earliest
        kink of a stop inside the step, where the solver restarts."""
        solver = self.solver
        dense = None
        if self.events is not None:
            pen, rate = self.events.pen_rate(solver.t, solver.y)
            dense = solver.dense_output()
            kink = self.events.crossing(dense, t_old, solver.t, self.pen, pen)
            if kink is not None:  # restart at the kink, even at the step's end: the next step starts small
                t_kink, i = kink
                y = dense(t_kink) if t_kink < solver.t else solver.y
                engages = self.pen[i] <= 0.0
                pen, rate = self.events.pen_rate(t_kink, y)
                # the located stop is on its far side from here on (its penetration is ~0 there)
                pen[i] = max(pen[i], np.finfo(float).tiny) if engages else min(pen[i], 0.0)
                h = t_kink - t_old
                self.update_stops(pen, rate, h)
                self.solver = self.restart(t_kink, y, max(1e-2 * h, 1e-12), self.max_step)
                return t_kink, y, dense
            h = solver.t - t_old
            bounded = np.isfinite(self.max_step) and h >= (1.0 - 1e-9) * self.max_step
            arrived = bounded & (pen <= 0.0) & (-pen <= ARRIVAL * -self.pen) & (rate > 0.0)
            self.update_stops(pen, rate, h)
            if np.any(arrived):  # at the stop: it counts as engaged (its force is ~0 there)
                self.pen[arrived] = np.finfo(float).tiny
                self.solver = self.restart(solver.t, solver.y, ARRIVAL * h, np.inf)
                return solver.t, solver.y, dense
        if solver.status == "finished" and solver.t < self.problem.t_end - 1e-12 * max(1.0, self.problem.t_end):
            self.solver = self.restart(solver.t, solver.y, solver.step_size, self.max_step)  # a table breakpoint
        return solver.t, solver.y, dense

    def update_stops(self, pen, rate, h: float) -> None:
        """The stops' state after a step of h s: penetrations, rates and closing accelerations."""
        if h > 0.0:
            self.closing_acc = np.where(np.isfinite(pen), (rate - self.rate) / h, 0.0)
        self.pen, self.rate = pen, rate

    def advance(self, t_stop: float) -> SampleArrays:
        st = self.settings
        rows = []
        dt = st.output_dt
        end_tol = 1e-12 * max(1.0, self.problem.t_end)
        while self.solver.t < min(t_stop, self.problem.t_end) - end_tol and len(rows) < CHUNK:
            if self.stats.steps >= st.max_steps:
                self.status, self.message = "failed", f"max_steps = {st.max_steps} reached at t = {self.solver.t:.6g} s"
                break
            if self.events is not None:
                self.bound_approach()
            solver = self.solver
            t_old = solver.t
            message = solver.step()
            if not np.all(np.isfinite(solver.y)):
                self.status, self.message = "failed", non_finite_message(t_old, solver.t - t_old)
                break
            if solver.status == "failed":
                self.status, self.message = "failed", f"{self.name}: {message}; use method = 'genalpha' for stiff scenes"
                break
            t_new, y_new, dense = self.end_of_step(t_old)
            h = t_new - t_old
            self.stats = replace(self.stats, steps=self.stats.steps + 1, h_min=min(self.stats.h_min, h),
                                 h_max=max(self.stats.h_max, h))
            final = t_new >= self.problem.t_end - end_tol
            times = [t_new] if dt is None else []
            if dt is not None:
                while self.next_out <= t_new + 1e-12 * max(1.0, t_new):
                    if self.next_out > t_old:
                        times.append(self.next_out)
                    self.next_out += dt
                if final and (not times or times[-1] < t_new - 1e-9 * max(1.0, t_new)):
                    times.append(t_new)
            if dense is None and any(tk != t_new for tk in times):
                dense = solver.dense_output()
            for tk in times:
                y = y_new if tk == t_new else dense(min(tk, t_new))
                rows.append((tk, self.sample(tk, y), self.problem.refs.copy()))
            if not times:  # keep the angle references current between samples
                self.sample(t_new, y_new)
        self.stats = replace(self.stats, rhs_evaluations=self.evaluations)
        if rows:
            self._set_state(rows[-1][0], rows[-1][1])
        self.state.t = self.solver.t
        if self.status == "running" and self.solver.t >= self.problem.t_end - end_tol:
            self.status = "finished"
        if not rows:
            return empty_samples(self.problem, self.state)
        stack = [np.array([r[1][k] for r in rows]) for k in range(7)]
        refs = np.array([r[2] for r in rows])
        return SampleArrays(np.array([r[0] for r in rows]), stack[0], stack[1], stack[2], stack[3], stack[4], stack[5],
                            refs, stack[6])


def empty_samples(problem, state) -> SampleArrays:
    """SampleArrays with no rows."""
    z = np.zeros
    return SampleArrays(z(0), z((0,) + state.R.shape), z((0,) + state.A.shape), z((0, state.Q.size)),
                   z((0, state.u.size)), z((0, state.u.size)), z((0, state.lam.size)), z((0, problem.refs.size)),
                   z((0, 3)))
