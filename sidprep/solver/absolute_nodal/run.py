"""Integration of an absolute-nodal model: classic RK4 at a fixed step under the stepper contract
of sidprep/solver/integrators/base.py (``BeamRK4.advance``), after a check of the step against RK4's
stability limit for the highest frequency of the beams."""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from sidprep.errors import InputError
from sidprep.solver.absolute_nodal.assembly import Assembly, assemble, beam_system, initial_vector
from sidprep.solver.absolute_nodal.model import AbsoluteNodalModel
from sidprep.solver.absolute_nodal.results import beam_result
from sidprep.solver.core.absolute_nodal import BeamSystem, RK4Progress, rk4_loop
from sidprep.solver.integrators.base import CHUNK, Stepper
from sidprep.solver.integrators.settings import SolverSettings, check_run_size
from sidprep.solver.statistics import RunStatistics

#: largest h * omega_max accepted for RK4 (its stability limit on the imaginary axis is 2 sqrt 2)
RK4_STABILITY = 2.6
#: relative coordinate perturbation of the finite-difference stiffness behind the step check
STIFFNESS_FD = 1e-7


@dataclass
class BeamProblem:
    """What the stepper integrates: the compiled kernels' record (assembly.beam_system) and t_end (s)."""

    system: BeamSystem
    t_end: float


@dataclass
class BeamState:
    """Time t (s) and state y = [free positions (2 nf), free velocities (2 nf)] (m, m/s)."""

    t: float
    y: np.ndarray


@dataclass
class BeamSamples:
    """Output samples of one stretch: times t (k,) s, states Y (k, 4 nf)."""

    t: np.ndarray
    Y: np.ndarray


class BeamRK4(Stepper):
    """Classic RK4 at the fixed step settings.h (core.absolute_nodal.rk4_loop), samples every output_dt."""

    name = "rk4"

    def __init__(self, problem: BeamProblem, state: BeamState, settings: SolverSettings):
        super().__init__(problem, state, settings)
        self.progress = RK4Progress(state.t, state.y, settings.output_dt or 0.0, 0)

    def advance(self, t_stop: float) -> BeamSamples:
        st, p = self.settings, self.progress
        ts, Ys = rk4_loop(self.problem.system, p, t_stop, st.h, st.output_dt or 0.0, CHUNK)
        self.state = BeamState(p.t, np.array(p.y))
        self.stats = replace(self.stats, steps=int(p.steps), rhs_evaluations=4 * int(p.steps), h_min=st.h, h_max=st.h)
        if p.t >= self.problem.t_end - 1e-12 * max(1.0, self.problem.t_end):
            self.status = "finished"
        return BeamSamples(ts, Ys)


def highest_frequency(asm: Assembly) -> float:
    """omega_max (rad/s) of the system linearised about its initial shape: the largest
    generalized eigenvalue of (K, M) on the free coordinates, K by central differences of the
    elastic forces (beam_elastic)."""
    import scipy.linalg  # deferred: 0.22 CPU-s of import, needed only for the step check

    free = [2 * i + c for i in asm.free for c in (0, 1)]
    scale = STIFFNESS_FD * max(float(np.max(asm.beam_e)), 1e-300)
    system = beam_system(asm)

    def force(X):
        Q = np.zeros_like(X)
        for j in range(len(asm.beam_n)):
            system.beam_elastic(X, j, Q)
        return Q.ravel()[free]

    K = np.zeros((len(free), len(free)))
    for col, k in enumerate(free):
        X = asm.X0.copy().ravel()
        X[k] += scale
        fp = force(X.reshape(-1, 2))
        X[k] -= 2 * scale
        K[:, col] = -(fp - force(X.reshape(-1, 2))) / (2 * scale)
    M = np.kron(asm.Ms[np.ix_(asm.free, asm.free)], np.eye(2))
    lam = scipy.linalg.eigh(0.5 * (K + K.T), M, eigvals_only=True)
    return float(np.sqrt(max(lam[-1], 0.0)))




def integrate(asm: Assembly, t_end: float, settings: SolverSettings) -> tuple[np.ndarray, np.ndarray, float]:
    """RK4 of eq. 10 from t = 0 to t_end (s): sample times (s), states (nt, 4 nf) and CPU time (s)."""
    if settings.method != "rk4":
        raise InputError(f"absolute-nodal beams integrate with method = \"rk4\", not {settings.method!r}; "
                         "set method = \"rk4\" or leave it out")
    check_run_size(t_end, settings.h, settings.output_dt, True)
    n_steps = int(round(t_end / settings.h))
    if n_steps < 1 or abs(n_steps * settings.h - t_end) > 1e-9 * t_end:
        raise InputError(f"t_end = {t_end} s is not a whole number of steps of {settings.h} s; "
                         "choose t_end as a multiple of the step")
    omega = highest_frequency(asm)
    if settings.h * omega > RK4_STABILITY:
        raise InputError(f"step {settings.h:g} s is beyond RK4's stability limit for the highest frequency of the "
                         f"beams ({omega:.4g} rad/s); use step <= {RK4_STABILITY / omega:.3g} s or fewer elements / "
                         "a smaller EA")
    y0 = initial_vector(asm)
    problem = BeamProblem(beam_system(asm), t_end)
    cpu = time.process_time()
    stepper = BeamRK4(problem, BeamState(0.0, y0), settings)
    chunks = [BeamSamples(np.zeros(1), y0[None])]
    while stepper.status == "running":
        chunks.append(stepper.advance(t_end))
    cpu = time.process_time() - cpu
    t, Y = np.concatenate([c.t for c in chunks]), np.concatenate([c.Y for c in chunks])
    if not np.all(np.isfinite(Y)):
        bad = t[np.argmax(~np.all(np.isfinite(Y), axis=1))]
        raise InputError(f"the motion became non-finite at t = {bad:g} s (deformations too large for the small-strain "
                         "beams, or an unstable driver); use a smaller step or check the model")
    return t, Y, cpu


def simulate_absolute_nodal(model: AbsoluteNodalModel, t_end: float, settings: SolverSettings):
    """Simulate ``model`` to t_end (s) -> ``solver.results.Result`` (write it with solver.results.write_results)."""
    asm = assemble(model)
    t, Y, cpu = integrate(asm, t_end, settings)
    stats = RunStatistics(method="rk4", cpu_time=cpu, steps=int(round(t_end / settings.h)), rejected=0,
                          h_min=settings.h, h_max=settings.h, formulation="absolute nodal (Kisu Lee)",
                          nodes=int(len(asm.X0)), dof=int(2 * len(asm.free)))
    return beam_result(model, asm, t, Y, stats)
