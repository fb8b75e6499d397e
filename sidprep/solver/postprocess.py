"""From a run's samples to the Result: body histories, marker positions, joint reactions and
coordinates, energies and the effects report.

The outputs of every sample (SampledOutputs: marker positions, reactions, energies, ...) come
from the compiled ``core.outputs.sample_outputs``: the compiled loops call it on their own
samples (one compiled entry for the steps and their outputs); for a stepper driven from Python
it is called here, all samples at once (from Python one call of ``evaluate`` costs ~150 us of
dispatch against ~20 us inside compiled code).  ``postprocess`` hands the arrays out per body,
marker and joint.
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np

from sidprep.solver.effects import build_report, estimate_changes
from sidprep.solver.core.outputs import PostConstants, sample_outputs
from sidprep.solver.core.records import layout_record
from sidprep.solver.core.steps import SampleArrays
from sidprep.solver.results import BodyHistory, JointHistory, Result
from sidprep.solver.energy import work_integral
from sidprep.solver.stiffening_work import base_layout

ENERGY_KINDS = ("kinetic", "strain", "gravity", "spring", "dissipated", "external", "stiffening")

#: what a compiled loop needs to compute the outputs of its samples: the run's layout with every
#: marker active L, the reference layout of the stiffening work L0 (stiffening_work.base_layout
#: with every marker active; L when no stiffening effect is on), both core Layout records, and the
#: core PostConstants c
PostSetup = namedtuple("PostSetup", ["L", "L0", "c"])


def joint_marker_names(constraint) -> tuple[str, str]:
    """Names of the markers a joint connects (for a driver: those of its joint)."""
    joint = getattr(constraint, "joint", constraint)
    return joint.marker1.name, joint.marker2.name


def post_constants(run, stiffening: bool) -> PostConstants:
    """The PostConstants of ``run`` (solver.run.Run)."""
    system, L = run.system, run.L
    all_markers = system.markers()
    mindex = {id(m): k for k, m in enumerate(all_markers)}
    jindex = {id(j): i for i, j in enumerate(system.joints)}
    constraints = list(system.joints) + list(system.drivers)
    joint_of = [getattr(c, "joint", c) for c in constraints]
    flexible = {b.name: i for i, b in enumerate(system.bodies) if b.name in run.choices}
    fixed = (np.setdiff1d(np.arange(int(L.uoff[-1])), run.free) if run.free.size < L.uoff[-1]
             else np.zeros(0, np.int64))
    return PostConstants(
        np.asarray(run.kept, np.int64), np.asarray(run.kept_3d, np.int64),
        np.setdiff1d(run.kept_3d, run.kept).astype(np.int64), fixed.astype(np.int64),
        np.cumsum([0] + [len(c.rows) for c in system.joints] + [1] * len(system.drivers)).astype(np.int64),
        np.array([[mindex[id(c.marker1)], mindex[id(c.marker2)]] for c in constraints], np.int64).reshape(-1, 2),
        np.array([jindex[id(j)] if j.coordinate_kind else -1 for j in joint_of], np.int64),
        np.array([j is not c for j, c in zip(joint_of, constraints)], np.int64),
        np.array([flexible[m.body.name] if m.node is not None and m.body.name in flexible else -1
                  for m in all_markers], np.int64),
        int(stiffening))


def post_setup(run) -> PostSetup:
    """The PostSetup of ``run`` (solver.run.Run): its layouts with every marker active (core Layout
    records) and its PostConstants."""
    L0 = base_layout(run)
    L = layout_record(run.L).with_every_marker()
    return PostSetup(L, L if L0 is None else layout_record(L0).with_every_marker(), post_constants(run, L0 is not None))


def postprocess(run, s, setup, out=None) -> Result:
    """The Result of ``run`` (solver.run.Run) from its SampleArrays ``s``, its PostSetup ``setup`` and
    the SampledOutputs ``out`` of the samples (computed here when None)."""
    system, L = run.system, run.L
    c = setup.c
    if out is None:
        samples = SampleArrays(*(np.ascontiguousarray(column) for column in s))
        out = sample_outputs(setup.L, setup.L0, samples, c)
    bodies = {}
    for i, b in enumerate(system.bodies):
        u0, u1, q0, q1 = L.uoff[i], L.uoff[i + 1], L.qoff[i], L.qoff[i + 1]
        bodies[b.name] = BodyHistory(b.name, s.R[:, i].copy(), s.A[:, i].copy(), s.u[:, u0:u0 + 3].copy(),
                                     s.u[:, u0 + 3:u0 + 6].copy(), s.Q[:, q0:q1].copy(), s.u[:, u0 + 6:u1].copy(),
                                     s.ud[:, u0:u1].copy())
    all_markers = system.markers()
    positions = {m.name: out.P[:, k].copy() for k, m in enumerate(all_markers)}
    constraints = list(system.joints) + list(system.drivers)
    joints = {ch.name: JointHistory(ch.name, getattr(ch, "kind", "driver"), out.force[:, ci].copy(),
                                    out.torque[:, ci].copy(), out.force_local[:, ci].copy(),
                                    out.torque_local[:, ci].copy(), out.coord[:, ci, 0].copy(),
                                    out.coord[:, ci, 1].copy(), out.coord[:, ci, 2].copy(), joint_marker_names(ch))
              for ci, ch in enumerate(constraints)}
    energy = {kind: out.energy[:, i].copy() for i, kind in enumerate(ENERGY_KINDS[:4])}
    energy["dissipated"] = s.work[:, 1].copy()
    energy["external"] = s.work[:, 0] + s.work[:, 2]
    energy["stiffening"] = -work_integral(s.t, out.power)
    energy["total"] = (energy["kinetic"] + energy["strain"] + energy["gravity"] + energy["spring"]
                       + energy["dissipated"] - energy["external"] + energy["stiffening"])
    node_loads = {k: (m, out.node_force[:, k].copy(), out.node_torque[:, k].copy())
                  for k, m in enumerate(all_markers) if c.node_body[k] >= 0}
    estimates = {}
    for name, (b, chosen, _) in run.choices.items():
        h = bodies[name]
        history = {"t": s.t, "q": h.q, "qd": h.qd, "omega": h.omega, "rotation": h.rotation,
                   "acceleration": h.acceleration, "node_loads": [v for v in node_loads.values() if v[0].body is b],
                   "gravity": system.gravity, "settings": run.settings}
        estimates[name] = estimate_changes(b, chosen, history)
    report = build_report(run.choices, estimates, run.notes)
    return Result(s.t.copy(), bodies, joints, positions, energy, out.cerr, report)
