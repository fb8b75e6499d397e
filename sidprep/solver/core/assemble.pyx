"""The equations of a whole system at one state, compiled: the one place where body equations,
marker kinematics, force elements and constraint rows are put together.

For the velocities u (per body [v_O inertial, omega body, qd]) and the multipliers lambda of
the constraint rows:

    M(x) u_dot - f(x, u, t) + B_F(x)^T lambda = 0,     g(x, t) = 0,   g_dot = B(x) u + b_t(t)

The translational row of each body is rotated to inertial components (T = blockdiag(A^T, E,
E); M = T^T M_K T).  B_F differs from B only by the load-stiffening parts K0F, K0M of node
markers (sid-spec 5.2).

Nothing here allocates: the path markers' mode shapes (paths.pyx) live in the scratch ``work``
of the MarkerKinematics (records.pxd), 3-vectors and frames in C arrays.
"""

from libc.stdint cimport int64_t

from sidprep.solver.core.body cimport DE, F_DAMPING, body_equations, body_potentials
from sidprep.solver.core.constraints cimport (NO_COORDINATE, joint_coordinate, joint_rows, marker_jacobians,
                                              marker_pose, stiffened_jacobian)
from sidprep.solver.core.curves cimport motion_state, path_shapes
from sidprep.solver.core.forces cimport FE_MOVING_MASS, FE_PAR_MASS, force_elements, motion_curve
from sidprep.solver.core.paths cimport (BodyPose, at, body_pose, motion_arc, path_acceleration, path_convection,
                                        path_pose, projected_arc)
from sidprep.solver.core.records cimport Evaluation, Layout, MarkerKinematics
from sidprep.solver.core.rotations cimport dot3, matvec3, tmatvec3


cdef inline double* scratch(MarkerKinematics kin) noexcept nogil:
    """The kernels' scratch: kin.work as one flat array of doubles (none without bodies)."""
    return &kin.work[0, 0] if kin.work.shape[0] * kin.work.shape[1] > 0 else NULL


cdef void stiffen(double* out, const double* jac, const double* A, const double* q, Py_ssize_t nq,
                  const double[::1] shapes, int64_t o, Py_ssize_t ld) noexcept nogil:
    """out (3, 6 + nq; rows ld apart) = jac with the load-stiffening part K0 (3, nq, nq) stored in
    shapes from offset o (o < 0: jac itself)."""
    cdef Py_ssize_t a, k
    if o < 0:
        for a in range(3):
            for k in range(6 + nq):
                out[a * ld + k] = jac[a * ld + k]
        return
    stiffened_jacobian(jac, A, q, nq, at(shapes, o), out, ld)


cdef void add_rows(double[:, ::1] B, Py_ssize_t r, Py_ssize_t col, const double* c, const double* jt,
                   const double* jr, Py_ssize_t ld, Py_ssize_t which, Py_ssize_t w) noexcept nogil:
    """B[r, col:col+w] += cT JT + cR JR for marker ``which`` (0: marker 1, 1: marker 2) of the row
    coefficients c (4, 3); jt, jr (3, w) with rows ld apart."""
    cdef double* row = &B[r, col]
    cdef double ct, cr
    cdef Py_ssize_t a, k
    for a in range(3):
        ct, cr = c[6 * which + a], c[6 * which + 3 + a]
        for k in range(w):
            row[k] += ct * jt[a * ld + k] + cr * jr[a * ld + k]


cpdef bint has_moving_masses(Layout L) noexcept nogil:
    """Whether the layout has a moving mass (model/forces.py MovingMass)."""
    cdef Py_ssize_t i
    for i in range(L.fe_int.shape[0]):
        if L.fe_int[i, 0] == FE_MOVING_MASS:
            return True
    return False


cpdef (double, double, double) moving_masses(Layout L, MarkerKinematics kin, const double[:, ::1] R,
                                             const double[:, :, ::1] A, const double[::1] Q, const double[::1] u,
                                             const double[::1] ud, double t) noexcept nogil:
    """(drive power W, kinetic energy J, gravity potential J) of the moving masses on their
    paths (model/forces.py MovingMass): the drive that keeps s(t) does the work
    m (a - g) . (s_dot tau) on the mass (tau = dr/ds, a = J ud + convective part); its kinetic
    energy is 1/2 m |J u + s_dot tau|^2, of which the system mass matrix (m J^T J) holds
    1/2 m |J u|^2, so the rest is returned; its potential is -m g . r.  Zeros off the path.
    kin: the MarkerKinematics at the state (markers_into, or an Evaluation's)."""
    cdef double power = 0.0, kinetic = 0.0, potential = 0.0, mass, s, acc
    cdef double* work = scratch(kin)
    cdef double point[3]
    cdef double dpoint[3]
    cdef double accel[3]
    cdef double pa[3]
    cdef const double* g = &L.gravity[0]
    cdef const double* v_rel
    cdef Py_ssize_t i, k, b, nq, w, a, j
    for i in range(L.fe_int.shape[0]):
        if L.fe_int[i, 0] != FE_MOVING_MASS:
            continue
        k, mass = L.fe_int[i, 1], L.fe_par[i, FE_PAR_MASS]
        b = L.mk_body[k]
        nq = L.qoff[b + 1] - L.qoff[b]
        s = motion_arc(L, k, t)
        if not path_shapes(L, L.mk_path[k, 0], nq, s, point, work, work + 3 * nq, dpoint, work + 6 * nq):
            continue
        v_rel = &kin.VC[k, 0]
        w = L.uoff[b + 1] - L.uoff[b]
        path_acceleration(L, k, body_pose(L, b, R, A, Q), at(u, L.uoff[b]), t, work, pa)
        for a in range(3):
            acc = 0.0
            for j in range(w):
                acc += kin.JT[k, a, j] * ud[L.uoff[b] + j]
            accel[a] = acc + pa[a] - g[a]
        power += mass * dot3(accel, v_rel)
        kinetic += mass * dot3(v_rel, &kin.VEL[k, 0]) + 0.5 * mass * dot3(v_rel, v_rel)
        potential -= mass * dot3(g, &kin.P[k, 0])
    return power, kinetic, potential


cdef double row_rate(const double* c, const double* v1, const double* w1, const double* v2,
                     const double* w2) noexcept nogil:
    """Rate of a constraint row or joint coordinate with marker coefficients c (4, 3) =
    (cT1, cR1, cT2, cR2) at marker velocities v1, v2 and angular velocities w1, w2 (3,)."""
    return dot3(c, v1) + dot3(c + 3, w1) + dot3(c + 6, v2) + dot3(c + 9, w2)


cdef void path_marker(Layout L, MarkerKinematics kin, Py_ssize_t k, BodyPose body, double t,
                      double* work) noexcept nogil:
    """Path marker k (on a body at r, A, q) at time t: its P, AM, VC, WC and Jacobians (zero off
    its path: it carries no load there) written into kin; work: 18 nq doubles."""
    cdef Py_ssize_t first = L.mk_path[k, 0], partner = L.mk_path[k, 2], ld = kin.JT.shape[2], nq = body.nq
    cdef double s, s_dot = 0.0
    cdef double point[3]
    cdef double p_path[3]
    cdef double d[3]
    cdef double rot_path[9]
    cdef (const double*, Py_ssize_t, const double*, Py_ssize_t) curve
    cdef (double, double, double) motion
    cdef bint on
    if partner >= 0:
        s = projected_arc(L, first, body, &kin.P[partner, 0], work)
    else:
        curve = motion_curve(L, L.mk_path[k, 1])
        motion = motion_state(<int64_t>L.mk_motion[k, 0], &L.mk_motion[k, 1], curve, t)
        s, s_dot = motion[0], motion[1]
    on = path_pose(L, first, body, s, &L.mk_rot[k, 0, 0], False, work, &kin.P[k, 0], &kin.AM[k, 0, 0], point)
    if partner < 0:
        path_convection(L, first, body, s, s_dot, &L.mk_rot[k, 0, 0], &kin.AM[k, 0, 0], on, work + 9 * nq,
                        &kin.VC[k, 0], &kin.WC[k, 0])
    if on:
        marker_pose(body.r, body.a, body.q, nq, point, &L.mk_rot[k, 0, 0], work, work + 3 * nq, nq, p_path,
                    rot_path, d)
        marker_jacobians(body.a, d, work, work + 3 * nq, nq, nq, &kin.JT[k, 0, 0], &kin.JR[k, 0, 0], ld)


cpdef void markers_into(Layout L, MarkerKinematics kin, const double[:, ::1] R, const double[:, :, ::1] A,
                        const double[::1] Q, const double[::1] u, double t) noexcept nogil:
    """Kinematics at time t (s; path markers move) of the markers with L.mk_active (nmk,) != 0
    (those that joints and forces use; every marker of ``Layout.with_every_marker()``), written
    into the MarkerKinematics kin (records.marker_kinematics(L); zero for the other markers):
    P (nmk, 3), AM (nmk, 3, 3), VEL, OMG (nmk, 3) inertial velocities of the material point (the
    body's motion), the Jacobians JT, JR and the load Jacobians JTF, JRF (nmk, 3, w_max),
    zero-padded (JTF, JRF are JT, JR when no marker is load-stiffened), and VC, WC (nmk, 3) the
    convective velocity and angular velocity of markers moved along their path by a motion s(t)
    (path_convection; zero for all others): the marker moves at VEL + VC, its frame at OMG + WC."""
    cdef Py_ssize_t nmk = L.mk_body.shape[0], ld = kin.JT.shape[2], sweep, k, b, nq, o, w, a, j, ub
    cdef bint stiffened = kin.stiffened
    cdef double[:, ::1] P = kin.P, VEL = kin.VEL, OMG = kin.OMG
    cdef double[:, :, ::1] JT = kin.JT, JR = kin.JR
    cdef double* work = scratch(kin)
    cdef const double* q
    cdef double vel, omg
    cdef double d[3]
    kin.P[:, :] = 0.0
    kin.AM[:, :, :] = 0.0
    kin.VEL[:, :] = 0.0
    kin.OMG[:, :] = 0.0
    kin.VC[:, :] = 0.0
    kin.WC[:, :] = 0.0
    kin.JT[:, :, :] = 0.0
    kin.JR[:, :, :] = 0.0
    kin.JTF[:, :, :] = 0.0  # (JT, JR themselves unless load-stiffened)
    kin.JRF[:, :, :] = 0.0
    for sweep in range(2 * nmk):  # markers that follow a partner on their path (OnPath) after the others
        k = sweep % nmk
        if not L.mk_active[k] or (L.mk_path[k, 2] >= 0) != (sweep >= nmk):
            continue
        b = L.mk_body[k]
        if b < 0:
            for a in range(3):
                P[k, a] = L.mk_pos[k, a]
                for j in range(3):
                    kin.AM[k, a, j] = L.mk_rot[k, a, j]
            continue
        nq = L.qoff[b + 1] - L.qoff[b]
        q = at(Q, L.qoff[b])
        if L.mk_path[k, 0] >= 0:  # moving along a path: its point, frame and shapes at s(t)
            path_marker(L, kin, k, body_pose(L, b, R, A, Q), t, work)
        else:
            o = L.mk_shape[k]
            marker_pose(&R[b, 0], &A[b, 0, 0], q, nq, &L.mk_pos[k, 0], &L.mk_rot[k, 0, 0], at(L.shapes, o),
                        at(L.shapes, o + 3 * nq), nq, &P[k, 0], &kin.AM[k, 0, 0], d)
            marker_jacobians(&A[b, 0, 0], d, at(L.shapes, o), at(L.shapes, o + 3 * nq), nq, nq, &JT[k, 0, 0],
                             &JR[k, 0, 0], ld)
        w = L.uoff[b + 1] - L.uoff[b]
        ub = L.uoff[b]
        for a in range(3):  # VEL = JT u_b, OMG = JR u_b
            vel = 0.0
            omg = 0.0
            for j in range(w):
                vel += JT[k, a, j] * u[ub + j]
                omg += JR[k, a, j] * u[ub + j]
            VEL[k, a] = vel
            OMG[k, a] = omg
        if stiffened:
            stiffen(&kin.JTF[k, 0, 0], &JT[k, 0, 0], &A[b, 0, 0], q, nq, L.shapes, L.mk_k0[k, 0], ld)
            stiffen(&kin.JRF[k, 0, 0], &JR[k, 0, 0], &A[b, 0, 0], q, nq, L.shapes, L.mk_k0[k, 1], ld)


cdef void body_into(Layout L, Py_ssize_t i, const double* a, const double[::1] Q, const double[::1] u,
                    double[:, ::1] M, double[::1] f) noexcept nogil:
    """Body i's M_K and h_K (body_equations) written into its blocks of M and f, the
    translational row and column turned to inertial components by its frame a (3, 3)."""
    cdef Py_ssize_t s = L.uoff[i], w = L.uoff[i + 1] - L.uoff[i], nq = w - 6, c, r
    cdef double gk[3]
    cdef double col[3]
    cdef double h[3]
    tmatvec3(a, &L.gravity[0], gk)
    body_equations(at(L.body_F, 0), &L.body_off[i, 0], &L.body_flags[i, 0], L.body_mass[i], nq, at(Q, L.qoff[i]),
                   at(u, s + 6), at(u, s + 3), gk, &M[s, s], M.shape[1], &f[s])
    for c in range(3, w):  # [[m E, top], [top^T, ...]], top = A M_K[:3, 3:]
        for r in range(3):
            col[r] = M[s + r, s + c]
        matvec3(a, col, col)
        for r in range(3):
            M[s + r, s + c] = col[r]
            M[s + c, s + r] = col[r]
    matvec3(a, &f[s], h)
    for r in range(3):
        f[s + r] = h[r]


cdef void moving_mass_terms(Layout L, MarkerKinematics kin, const double[:, ::1] R, const double[:, :, ::1] A,
                            const double[::1] Q, const double[::1] u, double t, double[:, ::1] M,
                            double[:, ::1] loads) noexcept nogil:
    """The moving masses (model/forces.py MovingMass): m J^T J into M, m (g - a_convective) into
    their markers' loads."""
    cdef Py_ssize_t i, k, b, s0, w, r, c, a
    cdef double mass, acc
    cdef double pa[3]
    cdef double[:, :, ::1] JT = kin.JT
    for i in range(L.fe_int.shape[0]):
        if L.fe_int[i, 0] == FE_MOVING_MASS:
            k, mass = L.fe_int[i, 1], L.fe_par[i, FE_PAR_MASS]
            b = L.mk_body[k]
            s0, w = L.uoff[b], L.uoff[b + 1] - L.uoff[b]
            for r in range(w):
                for c in range(w):
                    acc = 0.0
                    for a in range(3):
                        acc += JT[k, a, r] * JT[k, a, c]
                    M[s0 + r, s0 + c] += mass * acc
            path_acceleration(L, k, body_pose(L, b, R, A, Q), at(u, L.uoff[b]), t, scratch(kin), pa)
            for a in range(3):
                loads[k, a] += mass * (L.gravity[a] - pa[a])


cdef void joint_coordinates(Layout L, Evaluation W, MarkerKinematics kin, const double[::1] refs) noexcept nogil:
    """W.coords (nj, 2) joint coordinates and rates, W.crows (nj, 4, 3) their velocity rows and
    W.convective (nj,) the parts of the rates due to path markers' motions (kin: W.kin)."""
    cdef double[:, ::1] P = kin.P, VEL = kin.VEL, OMG = kin.OMG, VC = kin.VC, WC = kin.WC
    cdef double[:, :, ::1] AM = kin.AM
    cdef Py_ssize_t j, k1, k2
    cdef double* c
    W.coords[:, :] = 0.0
    W.crows[:, :, :] = 0.0
    W.convective[:] = 0.0
    for j in range(L.joint_mk.shape[0]):
        if L.joint_kind[j] != NO_COORDINATE:
            k1, k2 = L.joint_mk[j, 0], L.joint_mk[j, 1]
            c = &W.crows[j, 0, 0]
            W.coords[j, 0] = joint_coordinate(L.joint_kind[j], &P[k1, 0], &AM[k1, 0, 0], &P[k2, 0], &AM[k2, 0, 0],
                                              refs[j], c)
            W.convective[j] = row_rate(c, &VC[k1, 0], &WC[k1, 0], &VC[k2, 0], &WC[k2, 0])
            W.coords[j, 1] = row_rate(c, &VEL[k1, 0], &OMG[k1, 0], &VEL[k2, 0], &OMG[k2, 0]) + W.convective[j]


cdef void constraint_rows(Layout L, Evaluation W, MarkerKinematics kin, double t) noexcept nogil:
    """g, b_t (m,), B, B_F (m, n) and C (m, 4, 3) of every joint's rows, then every driver's (kin: W.kin)."""
    cdef Py_ssize_t nj = L.joint_mk.shape[0], nrj = L.joint_off[nj], m_all = nrj + L.drv_joint.shape[0]
    cdef Py_ssize_t ld = kin.JT.shape[2], j, k1, k2, r0, r1, r, d, which, k, b, w
    cdef bint stiffened = kin.stiffened
    cdef double[:, ::1] P = kin.P, VC = kin.VC, WC = kin.WC
    cdef double[:, :, ::1] AM = kin.AM, C = W.C
    cdef double[::1] g = W.g, bt = W.bt
    cdef (const double*, Py_ssize_t, const double*, Py_ssize_t) curve
    cdef (double, double, double) motion
    g[:] = 0.0
    bt[:] = 0.0
    W.B[:, :] = 0.0
    W.BF[:, :] = 0.0  # (B itself unless load-stiffened: the load Jacobians differ from JT, JR only then)
    C[:, :, :] = 0.0
    for j in range(nj):
        k1, k2 = L.joint_mk[j, 0], L.joint_mk[j, 1]
        r0, r1 = L.joint_off[j], L.joint_off[j + 1]
        if r1 > r0:
            joint_rows(&L.jrows[r0, 0], r1 - r0, &P[k1, 0], &AM[k1, 0, 0], &P[k2, 0], &AM[k2, 0, 0], &g[r0],
                       &C[r0, 0, 0])
        for r in range(r0, r1):  # rheonomic rows of markers moving along a path
            bt[r] = row_rate(&C[r, 0, 0], &VC[k1, 0], &WC[k1, 0], &VC[k2, 0], &WC[k2, 0])
    for d in range(L.drv_joint.shape[0]):
        j = L.drv_joint[d]
        curve = motion_curve(L, L.drv_curve[d])
        motion = motion_state(L.drv_kind[d], &L.drv_par[d, 0], curve, t)
        g[nrj + d] = W.coords[j, 0] - motion[0]
        bt[nrj + d] = W.convective[j] - motion[1]
        C[nrj + d, :, :] = W.crows[j, :, :]
    j = 0
    for r in range(m_all):
        if r >= nrj:
            j = L.drv_joint[r - nrj]
        else:
            while L.joint_off[j + 1] <= r:
                j += 1
        for which in range(2):
            k = L.joint_mk[j, which]
            b = L.mk_body[k]
            if b >= 0:
                w = L.uoff[b + 1] - L.uoff[b]
                add_rows(W.B, r, L.uoff[b], &C[r, 0, 0], &kin.JT[k, 0, 0], &kin.JR[k, 0, 0], ld, which, w)
                if stiffened:
                    add_rows(W.BF, r, L.uoff[b], &C[r, 0, 0], &kin.JTF[k, 0, 0], &kin.JRF[k, 0, 0], ld, which, w)


cpdef void evaluate_into(Layout L, Evaluation W, const double[:, ::1] R, const double[:, :, ::1] A,
                         const double[::1] Q, const double[::1] u, double t, const double[::1] lam,
                         const double[::1] refs) noexcept nogil:
    """The system at a state (module doc), written into the Evaluation W (records.evaluation_arrays(L),
    made once per run; everything in it is overwritten).

    R (nb, 3), A (nb, 3, 3), Q (sum nq,), u (n,), t s, lam (m,) multipliers of all rows
    (friction), refs (nj,) angle-unwrapping references.  Fills M (n, n), f (n,), g (m,),
    B (m, n), B_F (m, n), b_t (m,), C (m, 4, 3) the rows' marker coefficients (cT1, cR1, cT2,
    cR2), coords (nj, 2) joint coordinates and rates, loads (nmk, 6) applied marker loads
    (inertial) and flows (4,) = [power in by loads, power dissipated, spring energy, power in by
    the drives of force elements on moving markers] (the drives' power through constraint rows is
    constraint_power, taken with the step's converged multipliers) and kin, the MarkerKinematics
    of the markers with L.mk_active != 0 (a layout with every marker active gives them all).
    """
    cdef double[:, ::1] M = W.M, loads = W.loads
    cdef double[::1] f = W.f, flows = W.flows
    cdef double[:, :, ::1] JTF = W.kin.JTF, JRF = W.kin.JRF
    cdef Py_ssize_t nb = R.shape[0], i, k, b, a, j, nq, o, s
    cdef double force, torque, acc, dissipated
    M[:, :] = 0.0
    f[:] = 0.0
    for i in range(nb):
        body_into(L, i, &A[i, 0, 0], Q, u, M, f)
    markers_into(L, W.kin, R, A, Q, u, t)
    joint_coordinates(L, W, W.kin, refs)
    loads[:, :] = 0.0
    flows[:] = 0.0
    force_elements(L, t, W.kin, W.coords, W.crows, W.convective, lam, loads, flows)
    moving_mass_terms(L, W.kin, R, A, Q, u, t, M, loads)
    for i in range(nb):
        if L.body_flags[i, F_DAMPING]:  # modal damping dissipates qd^T De qd
            s = L.uoff[i] + 6
            nq = L.uoff[i + 1] - s
            o = L.body_off[i, DE]
            dissipated = 0.0
            for j in range(nq):
                acc = 0.0
                for k in range(nq):
                    acc += L.body_F[o + j * nq + k] * u[s + k]
                dissipated += u[s + j] * acc
            flows[1] += dissipated
    for k in range(L.mk_body.shape[0]):
        b = L.mk_body[k]
        if b >= 0 and L.mk_active[k]:
            for i in range(L.uoff[b + 1] - L.uoff[b]):  # f += JTF^T F + JRF^T T, in scalars
                force = 0.0
                torque = 0.0
                for a in range(3):
                    force += JTF[k, a, i] * loads[k, a]
                    torque += JRF[k, a, i] * loads[k, 3 + a]
                f[L.uoff[b] + i] += force
                f[L.uoff[b] + i] += torque
    constraint_rows(L, W, W.kin, t)


cpdef double constraint_power(Layout L, const double[:, ::1] B, const double[::1] bt, const double[::1] u,
                              const double[::1] lam) noexcept nogil:
    """Power (W) the rheonomic rows put into the bodies, -sum lambda_r (B u)_r over the drivers'
    rows and the rows with b_t != 0 (joints on markers moving along a path): the work of the
    drives.  B (m_all, n), bt (m_all,) from evaluate_into, u (n,), lam (m_all,)."""
    cdef Py_ssize_t nrj = L.joint_off[L.joint_off.shape[0] - 1], r, c
    cdef double power = 0.0, acc
    for r in range(B.shape[0]):
        if r >= nrj or bt[r] != 0.0:
            acc = 0.0
            for c in range(B.shape[1]):
                acc += B[r, c] * u[c]
            power -= lam[r] * acc
    return power


cpdef (double, double, double) energies(Layout L, const double[:, ::1] R, const double[:, :, ::1] A,
                                        const double[::1] Q, const double[::1] u,
                                        const double[:, ::1] M) noexcept nogil:
    """(kinetic, strain, gravity potential) of all bodies, J; M (n, n) the system mass matrix."""
    cdef double kinetic = 0.0, strain = 0.0, grav = 0.0, acc
    cdef (double, double) potentials
    cdef Py_ssize_t i, j
    for i in range(u.shape[0]):
        acc = 0.0
        for j in range(u.shape[0]):
            acc += M[i, j] * u[j]
        kinetic += u[i] * acc
    for i in range(R.shape[0]):
        potentials = body_potentials(at(L.body_F, 0), &L.body_off[i, 0], &L.body_flags[i, 0], L.body_mass[i],
                                     L.qoff[i + 1] - L.qoff[i], &R[i, 0], &A[i, 0, 0], at(Q, L.qoff[i]),
                                     &L.gravity[0])
        strain += potentials[0]
        grav += potentials[1]
    return 0.5 * kinetic, strain, grav
