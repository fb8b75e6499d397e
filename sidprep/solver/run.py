"""A run: one simulation of a System, owning everything that belongs to it.

The System stays a description.  The run chooses the effects and builds each body's terms,
the compiled layout (with the spring lengths resolved at the assembled start), the kept
constraint rows and integrated coordinates, the angle references, the stepper and the
recorded samples; ``execute`` returns the Result.  Running the same System twice gives the
same Result.
"""

from __future__ import annotations

import copy
import math
import time
from dataclasses import asdict, replace

import numpy as np

from sidprep.errors import InputError, SimulationFailed
from sidprep.solver.compile.layout import build_layout, constraint_count
from sidprep.solver.compile.path_range import left_path, path_marker_problems
from sidprep.solver.effects import choose_effects
from sidprep.solver.energy import EnergyBalance, balance_beyond, balance_warning, energy_balance
from sidprep.solver.core.forces import FE_INT_KIND, FE_INT_MARKER1, FE_INT_MARKER2, FE_PAR_LENGTH, FE_SPRING
from sidprep.solver.core.outputs import SampledOutputs
from sidprep.solver.core.steps import SampleArrays
from sidprep.solver.integrators.base import Problem, State, evaluate, marker_kinematics
from sidprep.solver.integrators.adaptive import ScipyRungeKutta
from sidprep.solver.integrators.explicit import RungeKutta4
from sidprep.solver.integrators.genalpha import GeneralizedAlpha
from sidprep.solver.integrators.initial import (POSITION_TOL, accelerations, assemble_positions, body_sizes,
    independent_rows, length_weights, project_velocities, quasi_static_elastic)
from sidprep.solver.integrators.planar import planar_coordinates
from sidprep.solver.integrators.settings import SolverSettings, check_run_size
from sidprep.solver.model.bodies import RigidBody
from sidprep.solver.model.effects import EFFECTS, parse_effects
from sidprep.solver.model.joints import ConstantSpeed, Driver
from sidprep.solver.postprocess import post_setup, postprocess
from sidprep.solver.statistics import RunStatistics

STEPPERS = {"genalpha": GeneralizedAlpha, "rk4": RungeKutta4, "rk45": ScipyRungeKutta, "dop853": ScipyRungeKutta}
#: the start reports bodies moved by more than this (m or rad) from their placed positions
MOVED_TOL = 1e-9


def choose_terms(system, spec):
    """Per body: the BodyTerms of its effects and whether its node markers are load-stiffened;
    and {flexible body name: (body, chosen effects, reasons)} for the effects report."""
    parsed = parse_effects(spec)
    gravity_on = parsed == "auto" or "gravity" in parsed
    terms, stiffened, choices = [], [], {}
    for b in system.bodies:
        if isinstance(b, RigidBody):
            terms.append(b.terms(set(EFFECTS), gravity=gravity_on and bool(np.any(system.gravity))))
            stiffened.append(False)
            continue
        own = parse_effects(b.effects) if b.effects is not None else parsed
        chosen, reasons = choose_effects(system, b, own)
        terms.append(b.terms(chosen, gravity="gravity" in chosen))
        stiffened.append("load_stiffening" in chosen)
        choices[b.name] = (b, chosen, reasons)
    return terms, stiffened, choices


def row_names(system) -> list[str]:
    """The joint or driver name of every constraint row."""
    return [c.name for c in system.joints for _ in c.rows] + [d.name for d in system.drivers]


#: a failed run whose energy balance was off by more than this fraction of the energy exchanged
#: before the failure names the integration as the likely cause (either sign: the balance books
#: all work and dissipation, so any change is integration error)
BALANCE_BEFORE_FAILURE = 0.1


def numerical_fix(settings) -> str:
    """The fix of an inaccurate or unstable integration with ``settings``."""
    if settings.method == "genalpha":
        return "halve h" + (" or lower rho_inf to 0.9" if settings.rho_inf > 0.9 else "")
    if settings.tolerance:
        return "tighten rtol or use method = \"genalpha\""
    return "halve h or use method = \"genalpha\""


def numerical_cause(balance: EnergyBalance, settings) -> str:
    """'; before it ...' naming the integration as the cause of a failure when the energy
    balance was off by more than BALANCE_BEFORE_FAILURE of the energy exchanged (else '')."""
    if not balance_beyond(balance, BALANCE_BEFORE_FAILURE):
        return ""
    how = "grew" if balance.change > 0 else "fell"
    step = f"h = {settings.h:g} s" + (f", rho_inf = {settings.rho_inf:g}" if settings.method == "genalpha" else "")
    return (f"; before it the energy {how} by {abs(balance.change):.3g} J that no work or dissipation accounts for "
            f"({balance.balance_error:.2g} of the {balance.exchanged:.3g} J exchanged): a numerical "
            f"instability of the integration ({settings.method}, {step}), not the scene; fix: {numerical_fix(settings)}")


def check_settings(settings, t_end: float) -> None:
    """Refuse, before the work, settings that cannot mean what they say for a run to ``t_end`` (s):
    t_end not finite and > 0, a step longer than the run, an rtol that the method does not use
    (rk4 steps at the fixed h)."""
    if not (t_end > 0 and math.isfinite(t_end)):
        raise InputError(f"simulate: t_end = {t_end} s must be > 0 and finite; fix the [solver] value")
    if not settings.h <= t_end:
        raise InputError(f"step = {settings.h:g} s is longer than t_end = {t_end:g} s; give a step of the scene's "
                         "time scale (e.g. 1e-3 s)")
    if settings.rtol is not None and settings.method == "rk4":
        raise InputError(f"rtol = {settings.rtol:g}: rk4 steps at the fixed step h and has no error control to use "
                         "it; leave rtol out, or choose method = \"rk45\", \"dop853\" or \"genalpha\" (error control)")


class Run:
    """One simulation of ``system`` to ``t_end`` (s) with ``settings`` (SolverSettings)."""

    def __init__(self, system, t_end: float, settings):
        check_settings(settings, t_end)
        check_run_size(t_end, settings.h, settings.output_dt, settings.tolerance is None)
        path_errors, path_notes = path_marker_problems(system, t_end)
        if path_errors:
            raise InputError(f"simulate: {path_errors[0]}")
        try:
            system.check()
        except ValueError as exc:
            raise InputError(str(exc)) from None
        self.system, self.t_end, self.settings = system, float(t_end), settings
        spec = settings.effects if settings.effects is not None else system.effects
        self.terms, self.stiffened, self.choices = choose_terms(system, spec)
        self.L = build_layout(system, self.terms, self.stiffened)
        self.weights, self.length = length_weights(system, self.terms, self.L)
        self.refs = np.zeros(len(system.joints))
        self.names = row_names(system)
        self.notes: list[str] = list(path_notes)
        self.free = np.arange(int(self.L.uoff[-1]))
        self.kept = np.arange(constraint_count(system))
        self.kept_3d = self.kept

    # ------------------------------------------------------------------ start
    def initial_positions(self):
        """R (nb, 3), A (nb, 3, 3), Q, u from the bodies' initial values (not yet consistent)."""
        b = self.system.bodies
        R = np.array([x.position0 for x in b], float).reshape(-1, 3)
        A = np.array([x.rotation0 for x in b], float).reshape(-1, 3, 3)
        Q = np.concatenate([x.initial_q()[0] for x in b] + [np.zeros(0)])
        u = np.concatenate([np.concatenate([x.velocity0, x.omega0, x.initial_q()[1]]) for x in b] + [np.zeros(0)])
        return R, A, Q, u

    def resolve_spring_lengths(self, R, A, Q) -> None:
        """Springs without a length take the marker distance at the assembled start (this
        run's layout; the System is not changed)."""
        rows = np.flatnonzero((self.L.fe_int[:, FE_INT_KIND] == FE_SPRING) & np.isnan(self.L.fe_par[:, FE_PAR_LENGTH]))
        if rows.size:
            P = marker_kinematics(self.L, R, A, Q).P
            for r in rows:
                marker1, marker2 = self.L.fe_int[r, FE_INT_MARKER1], self.L.fe_int[r, FE_INT_MARKER2]
                self.L.fe_par[r, FE_PAR_LENGTH] = np.linalg.norm(P[marker2] - P[marker1])

    def consistent_start(self) -> State:
        """Assembly, redundant rows, planar reduction, velocities, accelerations at t = 0."""
        L, w, st = self.L, self.weights, self.settings
        R, A, Q, u = self.initial_positions()
        R, A, Q = assemble_positions(L, R, A, Q, 0.0, self.refs, self.kept, w, self.names, self.length)
        self.refs[:] = evaluate(L, R, A, Q, u, 0.0, np.zeros(len(self.names)), self.refs).coords[:, 0]
        R, A, Q, u = self.start_from_joints(R, A, Q, u)
        self.note_moved_bodies(R, A)
        self.resolve_spring_lengths(R, A, Q)
        e = evaluate(L, R, A, Q, u, 0.0, np.zeros(len(self.names)), self.refs)
        g, B = e.g, e.B
        self.kept = self.kept_3d = np.flatnonzero(independent_rows(B))
        self.note_inconsistent_rows(g)
        if st.static_start:
            v = project_velocities(L, R, A, Q, u, 0.0, self.refs, self.kept, w)
            R, A, Q = quasi_static_elastic(L, (R, A, Q), v, 0.0, self.refs, self.free, self.kept, w, self.length,
                                           self.names)
        u = project_velocities(L, R, A, Q, u, 0.0, self.refs, self.kept, w)
        state = State(0.0, R, A, Q, u, np.zeros_like(u), np.zeros(self.kept.size))
        if self.system.planar is not False:
            free, rows, note = planar_coordinates(self.system, L, state, self.refs, self.kept, w, self.length,
                                                  self.t_end)
            if note:
                self.notes.append(note)
            if free is not None:
                B = evaluate(L, R, A, Q, u, 0.0, np.zeros(B.shape[0]), self.refs).B
                self.free = free
                self.kept = rows[independent_rows(B[rows][:, free])]
            elif self.system.planar:
                raise InputError("simulate: planar = true but the scene is not planar (rigid bodies only, joint axes "
                                 "parallel to a coordinate axis, gravity and initial velocities in the plane, no "
                                 "out-of-plane load); remove it")
        state.ud, state.lam = accelerations(L, R, A, Q, u, 0.0, self.refs, self.free, self.kept)
        return state

    def note_moved_bodies(self, R, A) -> None:
        """A note of how far the consistent start moved each body from where the scene placed it
        (assembly onto the constraints and the joints' initial values)."""
        R0, A0 = self.initial_positions()[:2]
        shift = np.linalg.norm(R - R0, axis=1)
        turn = np.array([np.arccos(np.clip((np.trace(a0.T @ a) - 1) / 2, -1.0, 1.0)) for a0, a in zip(A0, A)])
        moved = [i for i in np.argsort(-shift) if shift[i] > MOVED_TOL or turn[i] > MOVED_TOL]
        if moved:
            self.notes.append("the consistent start moved " + ", ".join(
                f"'{self.system.bodies[i].name}' by {shift[i]:.3g} m and {np.degrees(turn[i]):.3g} deg" for i in moved)
                + " from where the scene placed them (assembly onto the joints and their initial values)")

    def note_inconsistent_rows(self, g) -> None:
        """A note for redundant rows that the assembled positions do not satisfy (dropped rows
        of a loop whose redundant constraints contradict each other by a little)."""
        dropped = np.setdiff1d(np.arange(g.size), self.kept)
        bad = dropped[np.abs(g[dropped]) > 10 * POSITION_TOL]
        if bad.size:
            worst = int(bad[np.argmax(np.abs(g[bad]))])
            joints = ", ".join(sorted({f"'{self.names[r]}'" for r in bad}))
            self.notes.append(f"redundant constraint rows of {joints} contradict the others by up to "
                              f"{abs(g[worst]):.3g} m or rad at the assembled start (e.g. the pins of a rigid loop "
                              "not exactly coplanar); they are dropped and the other rows hold")

    def start_layout(self, which: str):
        """(layout, all its rows, row names) of the system plus a temporary driver per joint with
        an ``initial`` coordinate (which = "initial": held at it) or ``initial_rate`` (moving at
        it from its current value); None when no joint asks for one."""
        jindex = {id(j): i for i, j in enumerate(self.system.joints)}
        extra = [Driver(j, ConstantSpeed(j.initial_rate or 0.0 if which == "initial_rate" else 0.0,
                                         j.initial if which == "initial" else self.refs[jindex[id(j)]]),
                        name=f"{j.name} ({which})")
                 for j in self.system.joints if getattr(j, which) is not None]
        if not extra:
            return None
        start = copy.copy(self.system)
        start.drivers = list(self.system.drivers) + extra
        names = row_names(start)
        return build_layout(start, self.terms, self.stiffened), np.arange(len(names)), names

    def start_from_joints(self, R, A, Q, u):
        """Positions and velocities moved to the joints' initial coordinates and rates (their
        other velocities by the minimum-norm projection of the consistent start)."""
        layout = self.start_layout("initial")
        if layout is not None:
            R, A, Q = assemble_positions(layout[0], R, A, Q, 0.0, self.refs, layout[1], self.weights, layout[2],
                                         self.length)
            self.refs[:] = evaluate(self.L, R, A, Q, u, 0.0, np.zeros(len(self.names)), self.refs).coords[:, 0]
        layout = self.start_layout("initial_rate")
        if layout is not None:
            L0, rows, _ = layout
            B = evaluate(L0, R, A, Q, u, 0.0, np.zeros(rows.size), self.refs).B
            u = project_velocities(L0, R, A, Q, u, 0.0, self.refs, rows[independent_rows(B)], self.weights)
        return R, A, Q, u

    def failure_cause(self, stepper, sizes) -> str:
        """The stepper's failure in words: for a body that left its small-deformation range, its
        name, the time, the deflection against its size and the likely causes."""
        if stepper.large_deformation is None:
            return stepper.message
        b, deflection, t = stepper.large_deformation
        body = self.system.bodies[b]
        stiffening = [e for e in ("centrifugal_stiffening", "acceleration_stiffening", "load_stiffening")
                      if e in self.choices.get(body.name, (None, ()))[1]]
        cause = (f"buckling or a stiffening instability (included: {', '.join(stiffening)}), a resonance"
                 if stiffening else "a resonance or an unstable load path")
        return (f"body '{body.name}' left the small-deformation range of the floating frame at t = {t:.6g} s: "
                f"elastic deflection {deflection:.3g} m = {100 * deflection / sizes[b]:.0f} % of its size "
                f"{sizes[b]:.3g} m (deformation_limit {self.settings.deformation_limit:g}); likely {cause}, "
                "a too large step or a stiff contact")

    def failure_message(self, stepper, sizes, balance: EnergyBalance) -> str:
        """Why the run failed: the stepper's cause, or the integration's when the energy balance names one."""
        cause = numerical_cause(balance, self.settings)
        failure = self.failure_cause(stepper, sizes)
        if cause:  # the integration, not the scene: the stepper's advice to check the scene does not apply
            failure = failure.split("; check the scene")[0]
        named = failure if failure.startswith(f"{stepper.name}: ") else f"{stepper.name}: {failure}"
        return named + cause

    # ------------------------------------------------------------------ run
    def execute(self):
        """Integrate and return the Result (sidprep/solver/results.py)."""
        cpu0 = time.process_time()
        state = self.consistent_start()
        problem = Problem(self.L, self.free, self.kept, self.weights, self.length, self.refs, self.t_end,
                          body_sizes(self.system, self.terms), post_setup(self))
        first = SampleArrays(np.array([0.0]), state.R[None], state.A[None], state.Q[None], state.u[None],
                        state.ud[None], state.lam[None], self.refs[None].copy(), np.zeros((1, 3)))
        stepper = STEPPERS[self.settings.method](problem, state.copy(), self.settings)
        cpu_setup = time.process_time() - cpu0
        chunks = [first] if stepper.outputs is None else []  # (a compiled loop records the start itself)
        while stepper.status == "running":
            chunks.append(stepper.advance(self.t_end))
            if self.settings.progress:
                self.settings.progress(float(stepper.state.t), self.t_end, stepper.stats.steps)
        cpu_integration = time.process_time() - cpu0 - cpu_setup
        samples = SampleArrays(*(np.concatenate(column) for column in zip(*chunks)))
        outputs = None if stepper.outputs is None else SampledOutputs(
            *(np.concatenate([getattr(o, f) for o in stepper.outputs]) for f in SampledOutputs._fields))
        result = postprocess(self, samples, problem.post, outputs)
        dropped = [f"{self.names[r]} row {r - self.names.index(self.names[r])}" for r in
                   np.setdiff1d(np.arange(len(self.names)), self.kept_3d)]
        cpu_time = time.process_time() - cpu0
        st = self.settings
        balance = energy_balance(result.energy, st.energy_tol)
        stops = tuple(f.name for f in self.system.forces if getattr(f, "law", None) is not None)
        balance = replace(balance, warning=balance_warning(balance, stepper.name, st.h, st.rho_inf, st.tolerance, stops))
        failed = self.failure_message(stepper, problem.sizes, balance) if stepper.status == "failed" else None
        gone = None if failed else left_path(self.system, result)
        result.stats = RunStatistics(
            **asdict(stepper.stats), method=stepper.name, h=st.h, rho_inf=st.rho_inf if stepper.name == "genalpha" else None,
            rtol=st.tolerance, cpu_time=cpu_time, cpu_setup=cpu_setup, cpu_integration=cpu_integration,
            dropped_constraint_rows=tuple(dropped), n_coordinates=int(self.free.size),
            planar=bool(self.free.size < self.L.uoff[-1]), n_constraints=int(self.kept.size), energy_balance=balance,
            failed=failed or gone)
        if result.stats.failed:
            raise SimulationFailed(result.stats.failed + f"; the results up to t = {result.t[-1]:.6g} s are kept",
                                   result)
        return result


def simulate(system, t_end: float, settings: SolverSettings | None = None, **overrides):
    """Integrate ``system`` (model.System) from t = 0 to t_end (s) and return the Result
    (sidprep/solver/results.py).

    settings : a SolverSettings (its defaults when None); overrides : any of its fields by name,
    e.g. ``simulate(system, 1.0, h=1e-3, method="rk4", rtol=1e-6)``.
    """
    return Run(system, t_end, replace(settings or SolverSettings(), **overrides)).execute()
