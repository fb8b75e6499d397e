"""The generalised-alpha stepper: a run's Lie-group generalised-alpha integration (Arnold & Bruls
2007; Bruls, Cardona & Arnold 2012) on the compiled loop ``ga_loop`` of core/genalpha.pyx, whose
module doc states the method, its Newton iteration, contacts, dense output and error control."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from sidprep.solver.core import genalpha as core
from sidprep.solver.core.records import layout_record
from sidprep.solver.core.steps import FINISHED, LARGE_DEFORMATION, MAX_STEPS, NEWTON_FAILED
from sidprep.solver.core.steps import SampleArrays
from sidprep.solver.integrators.base import CHUNK, Stepper


def genalpha_parameters(rho_inf: float) -> tuple[float, float, float, float]:
    """(alpha_m, alpha_f, gamma, beta) of Chung & Hulbert (1993) for spectral radius rho_inf."""
    if not 0.0 <= rho_inf <= 1.0:
        raise ValueError(f"rho_inf must be in [0, 1], got {rho_inf}")
    am = (2 * rho_inf - 1) / (rho_inf + 1)
    af = rho_inf / (rho_inf + 1)
    gamma = 0.5 + af - am
    return am, af, gamma, 0.25 * (gamma + 0.5) ** 2


def body_frame_free(free: np.ndarray, uoff: np.ndarray) -> np.ndarray:
    """The integrated coordinates in body-frame velocities: in a planar run (one free rotation
    axis k per body, the plane normal) the free translations are the K components other than k;
    otherwise ``free`` unchanged (core/se3.pyx: the SE(3) coordinates)."""
    keep = set(int(i) for i in free)
    out = []
    for b in range(len(uoff) - 1):
        s, e = int(uoff[b]), int(uoff[b + 1])
        rot = [a for a in range(3) if s + 3 + a in keep]
        trans = [a for a in range(3) if a not in rot] if len(rot) == 1 else [a for a in range(3) if s + a in keep]
        out += [s + a for a in trans] + [s + 3 + a for a in rot] + [i for i in range(s + 6, e) if i in keep]
    return np.array(sorted(out), dtype=free.dtype)


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
        self.loop = core.GaRun(L, constants, problem.refs, settings.max_steps, problem.post, settings.h)
        self.loop.t = state.t
        # the loop's state (its own arrays; a in the coordinates of core/se3.pyx: ga_loop starts it at ud)
        self.x = core.GaState(*(np.array(v, dtype=float) for v in (state.R, state.A, state.Q, state.u, state.ud)),
                              np.full(state.u.size, np.nan), np.array(state.lam, dtype=float))
        self.outputs = []

    def advance(self, t_stop: float) -> SampleArrays:
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
        self.stats = replace(self.stats, steps=int(record.steps), rejected=int(record.rejected),
                             newton_iterations=int(record.newton_iterations), jacobians=int(record.jacobians),
                             h_min=float(record.h_min), h_max=float(record.h_max))
        return samples
