"""From the sampled states of an absolute-nodal run to a ``solver.results.Result``: a body per beam
(its chord frame at the first node; q = [flexural displacement -theta_n L, flexural slope
theta_n - theta_1] as in the paper's Figs. 9-12), a marker per point, a revolute "joint" per
support (coordinate = the beam's chord angle phi) and per shared point (phi_2 - phi_1), energies
kinetic / strain / gravity / external (driver work) / total."""

from __future__ import annotations

import numpy as np

from sidprep.solver.absolute_nodal.assembly import Assembly, assemble, beam_system, initial_vector, unpack
from sidprep.solver.absolute_nodal.model import AbsoluteNodalModel
from sidprep.solver.core.absolute_nodal import BeamSystem, driver_angle, wrapped_angle
from sidprep.solver.effects import EffectsReport
from sidprep.solver.results import BodyHistory, JointHistory, Result
from sidprep.solver.statistics import RunStatistics


def _samples(asm: Assembly, system: BeamSystem, t: np.ndarray, Y: np.ndarray):
    """Per sample: positions X, velocities V, accelerations A (nt, N, 2), multipliers (nt, nd), strain (nt,)."""
    X, V = unpack(asm, Y)
    A = np.zeros_like(X)
    lam = np.zeros((len(t), asm.drv.shape[0]))
    strain = np.zeros(len(t))
    for s in range(len(t)):
        A[s], lam[s], strain[s] = system.accelerations(t[s], Y[s])
    return X, V, A, lam, strain


def initial_result(model: AbsoluteNodalModel):
    """The ``Result`` of the initial state alone (one sample, no integration): its signal names
    are those of every run of ``model`` (``sidprep simulate --list-signals``)."""
    asm = assemble(model)
    return beam_result(model, asm, np.zeros(1), initial_vector(asm)[None, :],
                       RunStatistics(method="rk4", cpu_time=0.0, steps=0, rejected=0))


def beam_result(model: AbsoluteNodalModel, asm: Assembly, t: np.ndarray, Y: np.ndarray,
                stats: RunStatistics):
    """Signals, energies and reactions of the sampled states Y (nt, 4 nf) at times t."""
    system = beam_system(asm)
    X, V, A, lam, strain = _samples(asm, system, t, Y)
    nt = len(t)
    kinetic = 0.5 * np.einsum("sic,ij,sjc->s", V, asm.Ms, V)
    gravity = -np.einsum("sic,ic->s", X, asm.fg) + asm.gravity_offset
    power = np.zeros(nt)
    for r in range(asm.drv.shape[0]):
        psid = np.array([driver_angle(ti, *asm.drv[r, 2:])[1] for ti in t])
        power += lam[:, r] * psid
    external = np.concatenate([[0.0], np.cumsum(0.5 * (power[1:] + power[:-1]) * np.diff(t))])
    external += -np.einsum("sic,ic->s", X - asm.X0, asm.f0 - asm.fg)          # work of the constant nodal forces
    energy = {"kinetic": kinetic, "strain": strain, "gravity": gravity, "external": external,
              "total": kinetic + strain + gravity - external}
    bodies, phis, phids = {}, {}, {}
    for j, b in enumerate(model.beams):
        nodes = asm.beam_nodes[j, :asm.beam_n[j]]
        kin = [system.beam_kinematics(X[s], V[s], A[s], j) for s in range(nt)]
        phi = np.unwrap([k[0] for k in kin])
        phid = np.array([k[1] for k in kin])
        phidd = np.array([k[2] for k in kin])
        th = np.array([k[3] for k in kin])
        thd = np.array([k[4] for k in kin])
        thdd = np.array([k[5] for k in kin])
        phis[b.name], phids[b.name] = phi, phid
        zero = np.zeros(nt)
        c, s_ = np.cos(phi), np.sin(phi)
        rot = np.zeros((nt, 3, 3))
        rot[:, 0, 0], rot[:, 0, 1], rot[:, 1, 0], rot[:, 1, 1], rot[:, 2, 2] = c, -s_, s_, c, 1.0
        flex = lambda a: np.column_stack([-a[:, -1] * b.length, a[:, -1] - a[:, 0]])  # noqa: E731 (paper Figs. 9-12)
        x0 = X[:, nodes[0]]
        bodies[b.name] = BodyHistory(
            b.name, position=np.column_stack([x0, zero]), rotation=rot,
            velocity=np.column_stack([V[:, nodes[0]], zero]), omega=np.column_stack([zero, zero, phid]),
            q=flex(th), qd=flex(thd),
            acceleration=np.column_stack([A[:, nodes[0]], zero, zero, zero, phidd, flex(thdd)]))
    markers = {p: np.column_stack([X[:, i], np.zeros(nt)]) for p, i in asm.points.items()}
    joints = {}
    nan3 = np.full((nt, 3), np.nan)
    reaction = np.einsum("ij,sjc->sic", asm.Ms, A) - asm.f0[None]
    for j, b in enumerate(model.beams):                 # elastic forces on the supports
        for s in range(nt):
            Q = np.zeros_like(asm.X0)
            system.beam_elastic(X[s], j, Q)
            reaction[s] -= Q
    effort = {d.support: lam[:, r] for r, d in enumerate(model.drivers)}
    for sup in model.supports:
        beam = next(b for b in model.beams if sup.point in b.points)
        F = np.column_stack([reaction[:, asm.points[sup.point]], np.zeros(nt)])
        joints[sup.name] = JointHistory(sup.name, "revolute", force=F, torque=np.zeros((nt, 3)), force_local=F,
                                        torque_local=np.zeros((nt, 3)), coordinate=phis[beam.name],
                                        rate=phids[beam.name], effort=effort.get(sup.name, np.full(nt, np.nan)))
    pinned = {s.point for s in model.supports}
    for p in asm.points:
        on = [b.name for b in model.beams if p in b.points]
        if len(on) >= 2 and p not in pinned:
            joints[p] = JointHistory(p, "revolute", force=nan3, torque=nan3, force_local=nan3, torque_local=nan3,
                                     coordinate=phis[on[1]] - phis[on[0]], rate=phids[on[1]] - phids[on[0]],
                                     effort=np.full(nt, np.nan))
    derr = np.zeros(nt)
    for r, d in enumerate(model.drivers):
        j = int(asm.drv[r, 0])
        at_end = asm.drv[r, 1] > 0.5
        for s in range(nt):
            val = system.driver_value(X[s], V[s], A[s], j, at_end)[0]
            derr[s] = max(derr[s], abs(wrapped_angle(val - driver_angle(t[s], *asm.drv[r, 2:])[0])))
    notes = ("absolute nodal beams: every effect of the formulation is included (no effect selection); "
             "force of beam-beam revolutes not computed (NaN)",)
    return Result(t=t, bodies=bodies, joints=joints, markers=markers, energy=energy, constraint_error=derr,
                  effects=EffectsReport(bodies={}, notes=notes), stats=stats)
