"""The outputs of a run's samples, compiled: marker positions, constraint error, energies, the
power of the stiffening terms, joint reactions and coordinates, node loads.

Every output sample is evaluated once more with the compiled equations (``evaluate_into`` with
every marker active), all samples of a stretch in one compiled loop (``sample_outputs``).  The
compiled integration loops call it on their own samples before they return (one compiled entry
runs the steps and their outputs, so a process loads the evaluation's call tree once:
docs/performance.md, "Allocation-free step"); ``postprocess`` calls it for the steppers driven from
Python.
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np

from sidprep.solver.equations.assemble import energies, evaluate_into, evaluation_arrays, moving_masses
from sidprep.solver.equations.rotations import dot, jit, matvec, put, tmatvec
from sidprep.solver.integrators.base import advance_pose, expand, has_friction
from sidprep.solver.integrators.planar import independent_equations, out_of_plane_reactions, out_of_plane_system

#: time step of the central differences of M and V along the motion, s
RATE_STEP = 1e-6


@jit
def motion_energy(L, R, A, Q, u, M):  # pragma: no cover - compiled
    """1/2 u.M u + V (J) of layout L at a pose (M its mass matrix there): the part of the model
    energy whose rate along the motion enters P."""
    kinetic, strain, grav = energies(L, R, A, Q, u, M)
    return kinetic + strain + grav


@jit
def model_power(e, u, lam, energy_plus, energy_minus):  # pragma: no cover - compiled
    """P (stiffening_work.py module doc, W) at a state from its Evaluation e, the velocities u (n,), the
    multipliers lam (m_all,) and the motion_energy at the poses moved by +-RATE_STEP u (the
    central difference of 1/2 u.M u + V along the motion; the caller evaluates them:
    sample_outputs)."""
    return dot(u, e.f) - dot(lam, matvec(e.BF, u)) + (energy_plus - energy_minus) / (2.0 * RATE_STEP)


#: what ``sample_outputs`` needs besides the layouts and the samples: the run's kept rows
#: ``kept``, the 3D rows ``kept_3d`` (constraint error), the out-of-plane rows ``dropped`` and
#: coordinates ``fixed`` of a planar run (empty otherwise); per constraint (joints, then
#: drivers) its first row c_off (nc + 1,), its markers c_marker (nc, 2), the joint whose
#: coordinate it reports c_joint (nc,; -1: none) and c_driver (nc,; 1: a driver, its effort);
#: per marker the flexible body whose node load it reports node_body (nmk,; -1: none); and
#: ``stiffening`` (1: the work of the stiffening terms is booked, L0 their reference layout)
PostConstants = namedtuple("PostConstants", ["kept", "kept_3d", "dropped", "fixed", "c_off", "c_marker", "c_joint",
                                             "c_driver", "node_body", "stiffening"])
#: per output sample (nt): marker positions P (nt, nmk, 3) m; constraint error cerr (nt,);
#: energy (nt, 4) = kinetic, strain, gravity, spring, J; power (nt,) of the stiffening terms, W;
#: per constraint force, torque (nt, nc, 3) on body 2, inertial, force_local, torque_local in
#: marker-1 components, N and N m; coord (nt, nc, 3) = joint coordinate, rate, driver effort
#: (NaN where none); node_force, node_torque (nt, nmk, 3) applied and reaction loads at node
#: markers of flexible bodies, body components (zero at other markers)
SampledOutputs = namedtuple("SampledOutputs", ["P", "cerr", "energy", "power", "force", "torque", "force_local",
                                               "torque_local", "coord", "node_force", "node_torque"])


@jit
def empty_outputs(nt, nmk, nc):  # pragma: no cover - compiled
    """SampledOutputs of nt samples, nmk markers, nc constraints (zeros; coord NaN)."""
    return SampledOutputs(np.zeros((nt, nmk, 3)), np.zeros(nt), np.zeros((nt, 4)), np.zeros(nt),
                          np.zeros((nt, nc, 3)), np.zeros((nt, nc, 3)), np.zeros((nt, nc, 3)), np.zeros((nt, nc, 3)),
                          np.full((nt, nc, 3), np.nan), np.zeros((nt, nmk, 3)), np.zeros((nt, nmk, 3)))


@jit
def constraint_outputs(out, k, e, lam, c):  # pragma: no cover - compiled
    """Sample k of the reactions, joint coordinates and node loads (SampledOutputs out) from the
    Evaluation e (every marker's kinematics) and the multipliers lam (m_all,) of all rows."""
    C, AM = e.C, e.kin.AM
    nmk = AM.shape[0]
    react = np.zeros((nmk, 6))  # reactions at node markers, inertial
    for ci in range(c.c_driver.shape[0]):
        force, torque = np.zeros(3), np.zeros(3)
        for r in range(c.c_off[ci], c.c_off[ci + 1]):
            for a in range(3):
                force[a] -= lam[r] * C[r, 2, a]
                torque[a] -= lam[r] * C[r, 3, a]
            for which in range(2):
                key = c.c_marker[ci, which]
                if c.node_body[key] >= 0:
                    for a in range(3):
                        react[key, a] -= lam[r] * C[r, 2 * which, a]
                        react[key, 3 + a] -= lam[r] * C[r, 2 * which + 1, a]
        a1 = AM[c.c_marker[ci, 0]]
        put(out.force[k, ci], 0, force)
        put(out.torque[k, ci], 0, torque)
        put(out.force_local[k, ci], 0, tmatvec(a1, force))
        put(out.torque_local[k, ci], 0, tmatvec(a1, torque))
        if c.c_joint[ci] >= 0:
            out.coord[k, ci, 0], out.coord[k, ci, 1] = e.coords[c.c_joint[ci], 0], e.coords[c.c_joint[ci], 1]
        if c.c_driver[ci]:
            out.coord[k, ci, 2] = -lam[c.c_off[ci]]
    return react


@jit
def sample_outputs(L, L0, s, c):  # pragma: no cover - compiled
    """The SampledOutputs of the samples s (base.SampleBuffers, nt rows) of a run with layout L
    (every marker active: every_marker), L0 the reference layout of the stiffening work
    (stiffening_work.base_layout; L when c.stiffening is 0) and the PostConstants c.  (evaluate_into
    is called here, not through helpers: every compiled function that calls it compiles its
    whole call tree once more; docs/performance.md.)  One workspace per layout for the run
    (assemble.evaluation_arrays): e at the sample, es for the stiffening work's evaluations (five
    per sample: at +-RATE_STEP with L and with L0, and L0's at the sample; L's at the sample is e)."""
    nt, nmk = s.t.shape[0], L.mk_body.shape[0]
    out = empty_outputs(nt, nmk, c.c_driver.shape[0])
    e = evaluation_arrays(L)
    es = evaluation_arrays(L) if c.stiffening else e
    es0 = evaluation_arrays(L0) if c.stiffening else e
    lam_all = np.zeros(e.g.shape[0])
    rows = np.zeros(0, np.int64)
    friction = has_friction(L)
    for k in range(nt):
        R, A, Q, u, ud, t, refs = s.R[k], s.A[k], s.Q[k], s.u[k], s.ud[k], s.t[k], s.refs[k]
        lam = expand(s.lam[k], c.kept, lam_all)
        evaluate_into(L, e, R, A, Q, u, t, lam, refs)
        if c.fixed.shape[0]:
            if k == 0:  # the independent out-of-plane equations, once per call (a stretch of samples)
                rows = independent_equations(out_of_plane_system(e, ud, lam, c.kept, c.dropped, c.fixed)[0])
            lam = out_of_plane_reactions(e, ud, lam, c.kept, c.dropped, c.fixed, rows)
            if friction:  # only friction reads the multipliers: the others' evaluation stands
                evaluate_into(L, e, R, A, Q, u, t, lam, refs)
        for mk in range(nmk):
            put(out.P[k, mk], 0, e.kin.P[mk])
        for r in c.kept_3d:
            out.cerr[k] = max(out.cerr[k], abs(e.g[r]))
        kinetic, strain, grav = energies(L, R, A, Q, u, e.M)
        _, mass_kinetic, mass_potential = moving_masses(L, e.kin, R, A, Q, u, ud, t)
        out.energy[k, 0], out.energy[k, 1] = kinetic + mass_kinetic, strain
        out.energy[k, 2], out.energy[k, 3] = grav + mass_potential, e.flows[2]
        if c.stiffening:  # model power of L minus that of L0 (stiffening_work.py)
            for which in range(2):
                Lw = L if which == 0 else L0
                ew = es if which == 0 else es0
                side = np.zeros(2)
                for i in range(2):
                    sign = 1.0 - 2.0 * i
                    Rs, As, Qs = advance_pose(Lw, R, A, Q, sign * RATE_STEP * u)
                    evaluate_into(Lw, ew, Rs, As, Qs, u, t + sign * RATE_STEP, lam, refs)
                    side[i] = motion_energy(Lw, Rs, As, Qs, u, ew.M)
                if which == 0:  # at the sample with L: the sample's own evaluation e
                    ew = e
                else:
                    evaluate_into(Lw, ew, R, A, Q, u, t, lam, refs)
                p = model_power(ew, u, lam, side[0], side[1])
                out.power[k] += p if which == 0 else -p
        react = constraint_outputs(out, k, e, lam, c)
        for mk in range(nmk):
            b = c.node_body[mk]
            if b >= 0:
                put(out.node_force[k, mk], 0, tmatvec(A[b], e.loads[mk, :3] + react[mk, :3]))
                put(out.node_torque[k, mk], 0, tmatvec(A[b], e.loads[mk, 3:] + react[mk, 3:]))
    return out


#: what a compiled loop needs to compute the outputs of its samples: the run's layout with every
#: marker active L (assemble.every_marker), the reference layout of the stiffening work L0
#: (stiffening_work.base_layout with every marker active; L when no stiffening effect is on) and
#: the PostConstants c
PostSetup = namedtuple("PostSetup", ["L", "L0", "c"])
