"""From a run's samples to the Result: body histories, marker positions, joint reactions and
coordinates, energies and the effects report (each sample is evaluated once more with the
compiled equations)."""

from __future__ import annotations

import numpy as np

from sidprep.solver.effects import build_report, estimate_changes
from sidprep.solver.equations.assemble import energies, evaluate, every_marker, markers, moving_masses
from sidprep.solver.integrators.planar import out_of_plane_reactions
from sidprep.solver.results import BodyHistory, JointHistory, Result
from sidprep.solver.stiffening_work import base_layout, stiffening_power

ENERGY_KINDS = ("kinetic", "strain", "gravity", "spring", "dissipated", "external", "stiffening")


def postprocess(run, s) -> Result:
    """The Result of ``run`` (solver.run.Run) from its Samples ``s``."""
    system, L = run.system, run.L
    nt = s.t.size
    m_all = len(run.names)
    planar = run.free.size < L.uoff[-1]
    all_markers = system.markers()
    constraints = list(system.joints) + list(system.drivers)
    bodies = {}
    for i, b in enumerate(system.bodies):
        u0, u1, q0, q1 = L.uoff[i], L.uoff[i + 1], L.qoff[i], L.qoff[i + 1]
        bodies[b.name] = BodyHistory(b.name, s.R[:, i].copy(), s.A[:, i].copy(), s.u[:, u0:u0 + 3].copy(),
                                     s.u[:, u0 + 3:u0 + 6].copy(), s.Q[:, q0:q1].copy(), s.u[:, u0 + 6:u1].copy(),
                                     s.ud[:, u0:u1].copy())
    positions = {m.name: np.zeros((nt, 3)) for m in all_markers}
    joints = {c.name: JointHistory(c.name, getattr(c, "kind", "driver"), *(np.zeros((nt, 3)) for _ in range(4)),
                                   np.full(nt, np.nan), np.full(nt, np.nan), np.full(nt, np.nan)) for c in constraints}
    energy = {k: np.zeros(nt) for k in ENERGY_KINDS}
    cerr = np.zeros(nt)
    flexible = {name: i for i, name in enumerate(b.name for b in system.bodies) if name in run.choices}
    node_markers = [(k, m) for k, m in enumerate(all_markers) if m.node is not None and m.body.name in flexible]
    node_loads = {k: (m, np.zeros((nt, 3)), np.zeros((nt, 3))) for k, m in node_markers}
    offsets = np.cumsum([0] + [len(c.rows) for c in system.joints] + [1] * len(system.drivers))
    jindex = {id(j): i for i, j in enumerate(system.joints)}
    mindex = {id(m): k for k, m in enumerate(all_markers)}
    L0 = base_layout(run)
    power = np.zeros(nt)  # of the geometric-stiffening terms, W (stiffening_work.py)
    every = every_marker(L)
    for k in range(nt):
        R, A, Q, u, ud, t, refs = s.R[k], s.A[k], s.Q[k], s.u[k], s.ud[k], s.t[k], s.refs[k]
        lam = np.zeros(m_all)
        lam[run.kept] = s.lam[k]
        if planar:
            lam = out_of_plane_reactions(L, R, A, Q, u, ud, t, lam, refs, run.free, run.kept, run.kept_3d)
        M, f, g, B, BF, bt, C, coords, loads, flows = evaluate(L, R, A, Q, u, t, lam, refs)
        P, AM = markers(L, R, A, Q, u, t, every)[:2]
        cerr[k] = np.max(np.abs(g[run.kept_3d]), initial=0.0)
        for mk, m in enumerate(all_markers):
            positions[m.name][k] = P[mk]
        kinetic, strain, grav = energies(L, R, A, Q, u, M)
        _, mass_kinetic, mass_potential = moving_masses(L, R, A, Q, u, ud, t)
        kinetic, grav = kinetic + mass_kinetic, grav + mass_potential
        energy["kinetic"][k], energy["strain"][k], energy["gravity"][k] = kinetic, strain, grav
        energy["spring"][k] = flows[2]
        energy["dissipated"][k] = s.work[k, 1]
        energy["external"][k] = s.work[k, 0] + s.work[k, 2]
        if L0 is not None:
            power[k] = stiffening_power(run, L0, R, A, Q, u, t, lam, refs)
        reactions = {}
        for c_index, c in enumerate(constraints):
            r0, r1 = offsets[c_index], offsets[c_index + 1]
            lc, cc = lam[r0:r1], C[r0:r1]
            jh = joints[c.name]
            jh.force[k], jh.torque[k] = -lc @ cc[:, 2], -lc @ cc[:, 3]
            a1 = AM[mindex[id(c.marker1)]]
            jh.force_local[k], jh.torque_local[k] = a1.T @ jh.force[k], a1.T @ jh.torque[k]
            joint = getattr(c, "joint", c)
            if joint.coordinate_kind:
                jh.coordinate[k], jh.rate[k] = coords[jindex[id(joint)]]
            if joint is not c:
                jh.effort[k] = -lc[0]
            for which, mk in enumerate((c.marker1, c.marker2)):
                key = mindex[id(mk)]
                if key in node_loads:
                    old = reactions.get(key, (0.0, 0.0))
                    reactions[key] = (old[0] - lc @ cc[:, 2 * which], old[1] - lc @ cc[:, 2 * which + 1])
        for key, (m, force, torque) in node_loads.items():
            extra = reactions.get(key, (0.0, 0.0))
            at = A[flexible[m.body.name]].T
            force[k] = at @ (loads[key, :3] + extra[0])
            torque[k] = at @ (loads[key, 3:] + extra[1])
    energy["stiffening"][1:] = -np.cumsum(0.5 * np.diff(s.t) * (power[1:] + power[:-1]))
    energy["total"] = (energy["kinetic"] + energy["strain"] + energy["gravity"] + energy["spring"]
                       + energy["dissipated"] - energy["external"] + energy["stiffening"])
    estimates = {}
    for name, (b, chosen, _) in run.choices.items():
        h = bodies[name]
        history = {"t": s.t, "q": h.q, "qd": h.qd, "omega": h.omega, "rotation": h.rotation,
                   "acceleration": h.acceleration, "node_loads": [v for v in node_loads.values() if v[0].body is b],
                   "gravity": system.gravity, "settings": run.settings}
        estimates[name] = estimate_changes(b, chosen, history)
    report = build_report(run.choices, estimates, run.notes)
    return Result(s.t.copy(), bodies, joints, positions, energy, cerr, report, {})
