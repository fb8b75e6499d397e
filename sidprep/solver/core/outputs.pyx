"""The outputs of a run's samples: marker positions, constraint error, energies, the power of the
stiffening terms, joint reactions and coordinates, node loads.

Every output sample is evaluated once more (``evaluate_into`` with every marker active), all
samples of a stretch in one call (``sample_outputs``).  The integration loops call it on their own
samples before they return; ``postprocess`` calls it for the steppers driven from Python.
"""

from collections import namedtuple

import numpy as np

from libc.math cimport fabs
from libc.stdint cimport int64_t

from sidprep.solver.core.assemble cimport energies, evaluate_into, moving_masses
from sidprep.solver.core.planar cimport (PlanarWork, independent_equations, out_of_plane_reactions,
                                         out_of_plane_system, planar_work)
from sidprep.solver.core.records cimport Evaluation, Layout
from sidprep.solver.core.rotations cimport tmatvec3
from sidprep.solver.core.steps cimport advance_pose, expand, has_friction

from sidprep.solver.core.records import evaluation_arrays

#: time step of the central differences of M and V along the motion, s
RATE_STEP = 1e-6
cdef double C_RATE_STEP = RATE_STEP

#: per output sample (nt): marker positions P (nt, nmk, 3) m; constraint error cerr (nt,);
#: energy (nt, 4) = kinetic, strain, gravity, spring, J; power (nt,) of the stiffening terms, W;
#: per constraint force, torque (nt, nc, 3) on body 2, inertial, force_local, torque_local in
#: marker-1 components, N and N m; coord (nt, nc, 3) = joint coordinate, rate, driver effort
#: (NaN where none); node_force, node_torque (nt, nmk, 3) applied and reaction loads at node
#: markers of flexible bodies, body components (zero at other markers)
SampledOutputs = namedtuple("SampledOutputs", ["P", "cerr", "energy", "power", "force", "torque", "force_local",
                                               "torque_local", "coord", "node_force", "node_torque"])


cdef class PostConstants:
    """What ``sample_outputs`` needs besides the layouts and the samples: the run's kept rows
    ``kept``, the 3D rows ``kept_3d`` (constraint error), the out-of-plane rows ``dropped`` and
    coordinates ``fixed`` of a planar run (empty otherwise); per constraint (joints, then drivers)
    its first row c_off (nc + 1,), its markers c_marker (nc, 2), the joint whose coordinate it
    reports c_joint (nc,; -1: none) and c_driver (nc,; 1: a driver, its effort); per marker the
    flexible body whose node load it reports node_body (nmk,; -1: none); and ``stiffening`` (1:
    the work of the stiffening terms is booked, L0 their reference layout)."""

    def __init__(self, kept, kept_3d, dropped, fixed, c_off, c_marker, c_joint, c_driver, node_body, stiffening):
        def ints(a, *shape):
            return np.ascontiguousarray(a, np.int64).reshape(shape)

        self.kept, self.kept_3d, self.dropped, self.fixed = ints(kept, -1), ints(kept_3d, -1), ints(dropped, -1), ints(fixed, -1)
        self.c_off, self.c_marker, self.c_joint = ints(c_off, -1), ints(c_marker, -1, 2), ints(c_joint, -1)
        self.c_driver, self.node_body = ints(c_driver, -1), ints(node_body, -1)
        self.stiffening = bool(stiffening)


cdef class Outputs:
    """The SampledOutputs of one stretch as typed views (outputs.pxd; made by empty_outputs)."""


cpdef Outputs empty_outputs(Py_ssize_t nt, Py_ssize_t nmk, Py_ssize_t nc):
    """The outputs of nt samples, nmk markers, nc constraints (zeros; coord NaN)."""
    cdef Outputs out = Outputs()
    out.arrays = SampledOutputs(np.zeros((nt, nmk, 3)), np.zeros(nt), np.zeros((nt, 4)), np.zeros(nt),
                                np.zeros((nt, nc, 3)), np.zeros((nt, nc, 3)), np.zeros((nt, nc, 3)),
                                np.zeros((nt, nc, 3)), np.full((nt, nc, 3), np.nan), np.zeros((nt, nmk, 3)),
                                np.zeros((nt, nmk, 3)))
    out.P, out.cerr, out.energy, out.power, out.force, out.torque, out.force_local, out.torque_local, out.coord, \
        out.node_force, out.node_torque = out.arrays
    return out


cdef double motion_energy(Layout L, const double[:, ::1] R, const double[:, :, ::1] A, const double[::1] Q,
                          const double[::1] u, const double[:, ::1] M) noexcept nogil:
    """1/2 u.M u + V (J) of layout L at a pose (M its mass matrix there): the part of the model
    energy whose rate along the motion enters P."""
    kinetic, strain, grav = energies(L, R, A, Q, u, M)
    return kinetic + strain + grav


cdef double model_power(Evaluation e, const double[::1] u, const double[::1] lam, double energy_plus,
                        double energy_minus) noexcept nogil:
    """P (stiffening_work.py module doc, W) at a state from its Evaluation e, the velocities u (n,), the
    multipliers lam (m_all,) and the motion_energy at the poses moved by +-RATE_STEP u (the
    central difference of 1/2 u.M u + V along the motion; the caller evaluates them:
    sample_outputs)."""
    cdef Py_ssize_t i, j
    cdef double applied = 0.0, constrained = 0.0, row
    for i in range(u.shape[0]):
        applied += u[i] * e.f[i]
    for i in range(e.BF.shape[0]):
        row = 0.0
        for j in range(u.shape[0]):
            row += e.BF[i, j] * u[j]
        constrained += lam[i] * row
    return applied - constrained + (energy_plus - energy_minus) / (2.0 * C_RATE_STEP)


cdef void constraint_outputs(Outputs out, Py_ssize_t k, Evaluation e, const double[::1] lam, PostConstants c,
                             double[:, ::1] react) noexcept nogil:
    """Sample k of the reactions, joint coordinates and node loads (written into out) from the
    Evaluation e (every marker's kinematics) and the multipliers lam (m_all,) of all rows; react
    (nmk, 6) receives the reactions at node markers, inertial."""
    cdef Py_ssize_t ci, r, a, which, key, m1
    cdef double force[3]
    cdef double torque[3]
    react[:, :] = 0.0
    for ci in range(c.c_driver.shape[0]):
        for a in range(3):
            force[a] = 0.0
            torque[a] = 0.0
        for r in range(c.c_off[ci], c.c_off[ci + 1]):
            for a in range(3):
                force[a] -= lam[r] * e.C[r, 2, a]
                torque[a] -= lam[r] * e.C[r, 3, a]
            for which in range(2):
                key = c.c_marker[ci, which]
                if c.node_body[key] >= 0:
                    for a in range(3):
                        react[key, a] -= lam[r] * e.C[r, 2 * which, a]
                        react[key, 3 + a] -= lam[r] * e.C[r, 2 * which + 1, a]
        m1 = c.c_marker[ci, 0]
        for a in range(3):
            out.force[k, ci, a] = force[a]
            out.torque[k, ci, a] = torque[a]
        tmatvec3(&e.kin.AM[m1, 0, 0], force, &out.force_local[k, ci, 0])
        tmatvec3(&e.kin.AM[m1, 0, 0], torque, &out.torque_local[k, ci, 0])
        if c.c_joint[ci] >= 0:
            out.coord[k, ci, 0] = e.coords[c.c_joint[ci], 0]
            out.coord[k, ci, 1] = e.coords[c.c_joint[ci], 1]
        if c.c_driver[ci]:
            out.coord[k, ci, 2] = -lam[c.c_off[ci]]


cpdef object sample_outputs(Layout L, Layout L0, object s, PostConstants c):
    """The SampledOutputs of the samples s (base.SampleBuffers, nt rows) of a run with layout L
    (every marker active: every_marker), L0 the reference layout of the stiffening work
    (stiffening_work.base_layout; L when c.stiffening is 0) and the PostConstants c.  One workspace
    per layout (records.evaluation_arrays): e at the sample, es, es0 for the stiffening work's
    evaluations (five per sample: at +-RATE_STEP with L and with L0, and L0's at the sample; L's
    at the sample is e)."""
    cdef const double[::1] st = s.t
    cdef const double[:, :, ::1] sR = s.R
    cdef const double[:, :, :, ::1] sA = s.A
    cdef const double[:, ::1] sQ = s.Q, su = s.u, sud = s.ud, slam = s.lam, srefs = s.refs
    cdef Py_ssize_t nt = st.shape[0], nmk = L.mk_body.shape[0], k, mk, a, j, r, i, which, b
    cdef Outputs out = empty_outputs(nt, nmk, c.c_driver.shape[0])
    cdef Evaluation e = evaluation_arrays(L)
    cdef Evaluation es = evaluation_arrays(L) if c.stiffening else e
    cdef Evaluation es0 = evaluation_arrays(L0) if c.stiffening else e
    cdef Evaluation ew
    cdef Layout Lw
    cdef double[::1] lam = np.zeros(e.g.shape[0])
    cdef double[:, ::1] react = np.zeros((nmk, 6))
    cdef double[:, ::1] Rs = np.zeros((sR.shape[1], 3))
    cdef double[:, :, ::1] As = np.zeros((sR.shape[1], 3, 3))
    cdef double[::1] Qs = np.zeros(sQ.shape[1]), dx = np.zeros(su.shape[1])
    cdef PlanarWork w = planar_work(c.fixed.shape[0], c.dropped.shape[0])
    cdef bint friction = has_friction(L)
    cdef double t, kinetic, strain, grav, mass_kinetic, mass_potential, sign, p
    cdef double side[2]
    cdef double load[3]
    cdef const double[:, ::1] R
    cdef const double[:, :, ::1] A
    cdef const double[::1] Q, u, ud, refs
    for k in range(nt):
        R, A, Q, u, ud, t, refs = sR[k], sA[k], sQ[k], su[k], sud[k], st[k], srefs[k]
        expand(slam[k], c.kept, lam)
        evaluate_into(L, e, R, A, Q, u, t, lam, refs)
        if c.fixed.shape[0]:
            if k == 0:  # the independent out-of-plane equations, once per call (a stretch of samples)
                out_of_plane_system(e, ud, lam, c.kept, c.dropped, c.fixed, w.a, w.load)
                w.r = independent_equations(w.a, w.rows)
            out_of_plane_reactions(e, ud, lam, c.kept, c.dropped, c.fixed, w)
            if friction:  # only friction reads the multipliers: the others' evaluation stands
                evaluate_into(L, e, R, A, Q, u, t, lam, refs)
        for mk in range(nmk):
            for a in range(3):
                out.P[k, mk, a] = e.kin.P[mk, a]
        for j in range(c.kept_3d.shape[0]):
            out.cerr[k] = max(out.cerr[k], fabs(e.g[c.kept_3d[j]]))
        kinetic, strain, grav = energies(L, R, A, Q, u, e.M)
        _, mass_kinetic, mass_potential = moving_masses(L, e.kin, R, A, Q, u, ud, t)
        out.energy[k, 0], out.energy[k, 1] = kinetic + mass_kinetic, strain
        out.energy[k, 2], out.energy[k, 3] = grav + mass_potential, e.flows[2]
        if c.stiffening:  # model power of L minus that of L0 (stiffening_work.py)
            for which in range(2):
                Lw = L if which == 0 else L0
                ew = es if which == 0 else es0
                for i in range(2):
                    sign = 1.0 - 2.0 * i
                    for j in range(dx.shape[0]):
                        dx[j] = sign * C_RATE_STEP * u[j]
                    advance_pose(Lw, R, A, Q, dx, False, Rs, As, Qs)
                    evaluate_into(Lw, ew, Rs, As, Qs, u, t + sign * C_RATE_STEP, lam, refs)
                    side[i] = motion_energy(Lw, Rs, As, Qs, u, ew.M)
                if which == 0:  # at the sample with L: the sample's own evaluation e
                    ew = e
                else:
                    evaluate_into(Lw, ew, R, A, Q, u, t, lam, refs)
                p = model_power(ew, u, lam, side[0], side[1])
                out.power[k] += p if which == 0 else -p
        constraint_outputs(out, k, e, lam, c, react)
        for mk in range(nmk):
            b = c.node_body[mk]
            if b >= 0:
                for a in range(3):
                    load[a] = e.loads[mk, a] + react[mk, a]
                tmatvec3(&A[b, 0, 0], load, &out.node_force[k, mk, 0])
                for a in range(3):
                    load[a] = e.loads[mk, 3 + a] + react[mk, 3 + a]
                tmatvec3(&A[b, 0, 0], load, &out.node_torque[k, mk, 0])
    return out.arrays
