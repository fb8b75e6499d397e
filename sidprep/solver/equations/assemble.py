"""The equations of a whole system at one state, compiled: the one place where body equations,
marker kinematics, force elements and constraint rows are put together.

For the velocities u (per body [v_O inertial, omega body, qd]) and the multipliers lambda of
the constraint rows:

    M(x) u_dot - f(x, u, t) + B_F(x)^T lambda = 0,     g(x, t) = 0,   g_dot = B(x) u + b_t(t)

The translational row of each body is rotated to inertial components (T = blockdiag(A^T, E,
E); M = T^T M_K T).  B_F differs from B only by the load-stiffening parts K0F, K0M of node
markers (sid-spec 5.2).
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np

from sidprep.solver.equations.body import DE, F_DAMPING, body_equations, body_potentials
from sidprep.solver.equations.constraints import (NO_COORDINATE, joint_coordinate, joint_rows, marker_jacobians,
                                                  marker_pose, stiffened_jacobian)
from sidprep.solver.equations.curves import motion_state, path_shapes
from sidprep.solver.equations.forces import FE_MOVING_MASS, force_elements, motion_curve
from sidprep.solver.equations.rotations import add, align, dot, exp_so3, jit, matmul, matvec, put, put2, tmatvec

#: time step of the second central difference giving a path point's convective acceleration, s
PATH_GAMMA_STEP = 1e-5
#: arc-length step of the central difference giving a path's tangent, m
PATH_TANGENT_STEP = 1e-6
#: Newton steps projecting a point onto a path (from the nearest sample; quadratic convergence)
PROJECTION_ITERATIONS = 3

#: kinematics of the markers (``markers_into``): positions P (nmk, 3), frames AM (nmk, 3, 3), material
#: velocities VEL and angular velocities OMG (nmk, 3), Jacobians JT, JR and load Jacobians JTF,
#: JRF (nmk, 3, w_max), convective velocities VC and angular velocities WC (nmk, 3) of path markers
MarkerKinematics = namedtuple("MarkerKinematics", ["P", "AM", "VEL", "OMG", "JT", "JR", "JTF", "JRF", "VC", "WC"])
#: the system at a state (``evaluate_into``), also the per-run workspace it writes into
#: (``evaluation_arrays``): M (n, n), f (n,), g, b_t (m,), B, B_F (m, n; B itself unless a
#: marker is load-stiffened), C (m, 4, 3), coords (nj, 2), loads (nmk, 6), flows (4,), kin, the
#: MarkerKinematics of the active markers, and the joint coordinates' velocity rows crows
#: (nj, 4, 3) and the parts of their rates due to path markers' motions convective (nj,)
Evaluation = namedtuple("Evaluation", ["M", "f", "g", "B", "BF", "bt", "C", "coords", "loads", "flows", "kin",
                                       "crows", "convective"])


@jit
def stiffen(jac, A, q, shapes, o):  # pragma: no cover - compiled
    """jac with the load-stiffening part K0 stored in shapes from offset o (o < 0: none)."""
    if o < 0:
        return jac
    nq = q.shape[0]
    return stiffened_jacobian(jac, A, q, shapes[o:o + 3 * nq * nq].reshape((3, nq, nq)))


@jit
def add_rows(B, r, col, c, jt, jr, which, w):  # pragma: no cover - compiled
    """B[r, col:col+width] += cT JT + cR JR for marker ``which`` (0: marker 1, 1: marker 2) of
    the row coefficients c (4, 3)."""
    for a in range(3):
        for k in range(w):
            B[r, col + k] += c[2 * which, a] * jt[a, k] + c[2 * which + 1, a] * jr[a, k]


@jit
def path_point(curve_x, curve_c, curve_meta, first, r, a, q, s):  # pragma: no cover - compiled
    """Inertial position (3,) of the point at arc length s of a path of a body at (r, a, q)."""
    point, phi = path_shapes(curve_x, curve_c, curve_meta, first, q.shape[0], s)[:2]
    return r + matvec(a, point + matvec(phi, q))


@jit
def projected_arc(curve_x, curve_c, curve_meta, first, r, a, q, target):  # pragma: no cover - compiled
    """Arc length s (m) of the point of a path (of a body at r, a, q) nearest to ``target``
    (3,): the undeformed sample nearest to it in the body frame, then Newton on
    tau(s) . (target - point(s)) = 0 on the deformed path."""
    meta = curve_meta[first]
    x = curve_x[meta[0]:meta[0] + meta[1]]
    local = tmatvec(a, target - r)
    best, s = np.inf, x[0]
    for i in range(x.shape[0] - 1):  # the sample points are the cubic pieces' constant terms
        d2 = 0.0
        for comp in range(3):
            m = curve_meta[first + comp]
            d2 += (local[comp] - curve_c[m[2] + 3 * (m[1] - 1) + i]) ** 2
        if d2 < best:
            best, s = d2, x[i]
    h = PATH_TANGENT_STEP
    for _ in range(PROJECTION_ITERATIONS):
        point = path_point(curve_x, curve_c, curve_meta, first, r, a, q, s)
        tangent = (path_point(curve_x, curve_c, curve_meta, first, r, a, q, s + h)
                   - path_point(curve_x, curve_c, curve_meta, first, r, a, q, s - h)) / (2.0 * h)
        s += dot(tangent, target - point) / dot(tangent, tangent)
    return s


@jit
def path_position(L, k, r, a, q, u, t, tau):  # pragma: no cover - compiled
    """Inertial position (3,) of path marker k's point after ``tau`` s along the motion of its
    body (at r, a, q) at constant velocities u = [v_O, omega, qd] and of its arc length s(t + tau)."""
    nq = q.shape[0]
    cx, cc = motion_curve(L.curve_x, L.curve_c, L.curve_meta, L.mk_path[k, 1])
    s = motion_state(int(L.mk_motion[k, 0]), L.mk_motion[k, 1:], cx, cc, t + tau)[0]
    return path_point(L.curve_x, L.curve_c, L.curve_meta, L.mk_path[k, 0], r + tau * u[0:3],
                      matmul(a, exp_so3(tau * u[3:6])), q + tau * u[6:6 + nq], s)


@jit
def path_acceleration(L, k, R, A, Q, u, t):  # pragma: no cover - compiled
    """Acceleration (3,) of path marker k's point at zero accelerations of its body (the
    convective part: s_ddot, s_dot^2, 2 s_dot Phi' qd, rotation), by the second central
    difference of its position along the motion (step PATH_GAMMA_STEP s)."""
    b = L.mk_body[k]
    q = Q[L.qoff[b]:L.qoff[b + 1]].copy()
    ub = u[L.uoff[b]:L.uoff[b + 1]].copy()
    e = PATH_GAMMA_STEP
    plus = path_position(L, k, R[b], A[b], q, ub, t, e)
    mid = path_position(L, k, R[b], A[b], q, ub, t, 0.0)
    minus = path_position(L, k, R[b], A[b], q, ub, t, -e)
    return (plus - 2.0 * mid + minus) / (e * e)


@jit
def has_moving_masses(L):  # pragma: no cover - compiled
    """Whether the layout has a moving mass (model/forces.py MovingMass)."""
    for i in range(L.fe_int.shape[0]):
        if L.fe_int[i, 0] == FE_MOVING_MASS:
            return True
    return False


@jit
def moving_masses(L, kin, R, A, Q, u, ud, t):  # pragma: no cover - compiled
    """(drive power W, kinetic energy J, gravity potential J) of the moving masses on their
    paths (model/forces.py MovingMass): the drive that keeps s(t) does the work
    m (a - g) . (s_dot tau) on the mass (tau = dr/ds, a = J ud + convective part); its kinetic
    energy is 1/2 m |J u + s_dot tau|^2, of which the system mass matrix (m J^T J) holds
    1/2 m |J u|^2, so the rest is returned; its potential is -m g . r.  Zeros off the path.
    kin: the MarkerKinematics at the state (markers, or an Evaluation's; the caller computes
    them, so that this function does not compile the markers' call tree once more)."""
    power = kinetic = potential = 0.0
    P, VEL, JT, VC = kin.P, kin.VEL, kin.JT, kin.VC
    for i in range(L.fe_int.shape[0]):
        if L.fe_int[i, 0] != FE_MOVING_MASS:
            continue
        k, mass = L.fe_int[i, 1], L.fe_par[i, 0]
        b = L.mk_body[k]
        cx, cc = motion_curve(L.curve_x, L.curve_c, L.curve_meta, L.mk_path[k, 1])
        s = motion_state(int(L.mk_motion[k, 0]), L.mk_motion[k, 1:], cx, cc, t)[0]
        if not path_shapes(L.curve_x, L.curve_c, L.curve_meta, L.mk_path[k, 0], L.qoff[b + 1] - L.qoff[b], s)[3]:
            continue
        v_rel = VC[k]
        w = L.uoff[b + 1] - L.uoff[b]
        accel = matvec(JT[k, :, :w], ud[L.uoff[b]:L.uoff[b + 1]]) + path_acceleration(L, k, R, A, Q, u, t)
        power += mass * dot(accel - L.gravity, v_rel)
        kinetic += mass * dot(v_rel, VEL[k]) + 0.5 * mass * dot(v_rel, v_rel)
        potential -= mass * dot(L.gravity, P[k])
    return power, kinetic, potential


@jit
def row_rate(c, v1, w1, v2, w2):  # pragma: no cover - compiled
    """Rate of a constraint row or joint coordinate with marker coefficients c (4, 3) =
    (cT1, cR1, cT2, cR2) at marker velocities v1, v2 and angular velocities w1, w2 (3,)."""
    return dot(c[0], v1) + dot(c[1], w1) + dot(c[2], v2) + dot(c[3], w2)


@jit
def path_pose(curve_x, curve_c, curve_meta, first, r, a, q, s, rotation, extend):  # pragma: no cover - compiled
    """Position p (3,) and frame A_m (3, 3) (inertial) of a marker at arc length s on a path of
    a body at (r, a, q), the path's undeformed point x(s) (3,, K), its Phi, Psi (3, nq) there and
    whether s is on the path (beyond the ends Phi = Psi = 0: the marker rides the straight
    extension rigidly; ``extend``: the end pieces' shapes go on, for derivatives at the ends):
    p = r + A (x(s) + Phi q); the frame is the
    marker rotation R_m turned from the undeformed tangent t0 to the deformed t = x' + Phi' q
    (the smallest rotation) and about t by the twist t0 . (Psi q):

        A_m = A exp(t0.(Psi q) t~) align(t0, t) R_m."""
    point, phi, psi, on, dpoint, dphi = path_shapes(curve_x, curve_c, curve_meta, first, q.shape[0], s)
    if not (on or extend):
        phi, psi, dphi = np.zeros_like(phi), np.zeros_like(psi), np.zeros_like(dphi)
    t0 = dpoint / np.sqrt(dot(dpoint, dpoint))
    tangent = dpoint + matvec(dphi, q)
    t1 = tangent / np.sqrt(dot(tangent, tangent))
    twist = exp_so3(dot(t0, matvec(psi, q)) * t1)
    rot = matmul(a, matmul(twist, matmul(align(t0, t1), rotation)))
    return r + matvec(a, point + matvec(phi, q)), rot, point, phi, psi, on


@jit
def path_convection(curve_x, curve_c, curve_meta, first, r, a, q, s, s_dot, rotation, frame, on):  # pragma: no cover
    """Velocity (3,) and angular velocity (3,) (inertial) of a path marker at arc length s
    moving at s_dot (m/s) over its body held still, frame (3, 3) its A_m there: s_dot dp/ds and
    s_dot vee(dA_m/ds A_m^T) (path_pose; central differences, step PATH_TANGENT_STEP m; at the
    path's ends (``on``) with the end pieces' shapes on both sides)."""
    h = PATH_TANGENT_STEP
    p_plus, a_plus = path_pose(curve_x, curve_c, curve_meta, first, r, a, q, s + h, rotation, on)[:2]
    p_minus, a_minus = path_pose(curve_x, curve_c, curve_meta, first, r, a, q, s - h, rotation, on)[:2]
    w = matmul(a_plus - a_minus, frame.T)
    scale = s_dot / (2.0 * h)
    omega = np.array([0.5 * (w[2, 1] - w[1, 2]), 0.5 * (w[0, 2] - w[2, 0]), 0.5 * (w[1, 0] - w[0, 1])])
    return scale * (p_plus - p_minus), scale * omega


@jit
def load_stiffened(mk_k0):  # pragma: no cover - compiled
    """Whether a marker is load-stiffened (K0F / K0M; mk_k0 (nmk, 2) of the layout): B_F, JTF,
    JRF differ from B, JT, JR only then.  (Takes the one array: passing the layout costs
    reference counts of all its arrays.)"""
    for k in range(mk_k0.shape[0]):
        if mk_k0[k, 0] >= 0 or mk_k0[k, 1] >= 0:
            return True
    return False


@jit
def marker_arrays(L):  # pragma: no cover - compiled
    """A MarkerKinematics workspace for the markers of layout L (zeros; JTF, JRF are JT, JR
    unless load-stiffened): the Jacobians are zero-padded to the widest body, w_max = max 6 + nq."""
    nmk = L.mk_body.shape[0]
    wmax = 0
    for b in range(L.uoff.shape[0] - 1):
        wmax = max(wmax, L.uoff[b + 1] - L.uoff[b])
    JT = np.zeros((nmk, 3, wmax))
    JR = np.zeros((nmk, 3, wmax))
    stiffened = load_stiffened(L.mk_k0)
    JTF = np.zeros((nmk, 3, wmax)) if stiffened else JT
    JRF = np.zeros((nmk, 3, wmax)) if stiffened else JR
    return MarkerKinematics(np.zeros((nmk, 3)), np.zeros((nmk, 3, 3)), np.zeros((nmk, 3)), np.zeros((nmk, 3)), JT, JR,
                            JTF, JRF, np.zeros((nmk, 3)), np.zeros((nmk, 3)))


@jit
def evaluation_arrays(L):  # pragma: no cover - compiled
    """The per-run workspace of ``evaluate_into`` for layout L: an Evaluation of zeros (B_F is B
    unless a marker is load-stiffened), made once per run (an evaluation writes into it)."""
    n = L.uoff[-1]
    m_all = L.joint_off[-1] + L.drv_joint.shape[0]
    nj, nmk = L.joint_mk.shape[0], L.mk_body.shape[0]
    B = np.zeros((m_all, n))
    BF = np.zeros((m_all, n)) if load_stiffened(L.mk_k0) else B
    return Evaluation(np.zeros((n, n)), np.zeros(n), np.zeros(m_all), B, BF, np.zeros(m_all), np.zeros((m_all, 4, 3)),
                      np.zeros((nj, 2)), np.zeros((nmk, 6)), np.zeros(4), marker_arrays(L), np.zeros((nj, 4, 3)),
                      np.zeros(nj))


@jit
def markers_into(L, kin, R, A, Q, u, t):  # pragma: no cover - compiled
    """Kinematics at time t (s; path markers move) of the markers with L.mk_active (nmk,) != 0
    (those that joints and forces use; every marker in the layout of ``every_marker``), written
    into the MarkerKinematics kin (marker_arrays(L); zero for the other markers):
    P (nmk, 3), AM (nmk, 3, 3), VEL, OMG (nmk, 3) inertial velocities of the material point (the
    body's motion), the Jacobians JT, JR and the load Jacobians JTF, JRF (nmk, 3, w_max),
    zero-padded (JTF, JRF are JT, JR when no marker is load-stiffened), and VC, WC (nmk, 3) the
    convective velocity and angular velocity of markers moved along their path by a motion s(t)
    (path_convection; zero for all others): the marker moves at VEL + VC, its frame at OMG + WC.

    (The layout L is not passed to helpers inside loops: every call with the 27-array tuple
    costs about a microsecond of reference counting.)"""
    nmk = L.mk_body.shape[0]
    uoff, qoff = L.uoff, L.qoff
    stiffened = load_stiffened(L.mk_k0)
    P, AM, VEL, OMG, JT, JR, JTF, JRF, VC, WC = kin
    P.fill(0.0)
    AM.fill(0.0)
    VEL.fill(0.0)
    OMG.fill(0.0)
    VC.fill(0.0)
    WC.fill(0.0)
    JT.fill(0.0)
    JR.fill(0.0)
    JTF.fill(0.0)  # (JT, JR themselves unless load-stiffened)
    JRF.fill(0.0)
    shapes = L.shapes
    p_path, rot_path, d = np.empty(3), np.empty((3, 3)), np.empty(3)  # scratch of the markers below
    for sweep in range(2 * nmk):  # markers that follow a partner on their path (OnPath) after the others
        k = sweep % nmk
        if not L.mk_active[k] or (L.mk_path[k, 2] >= 0) != (sweep >= nmk):
            continue
        b = L.mk_body[k]
        if b < 0:
            put(P[k], 0, L.mk_pos[k])
            put2(AM[k], 0, 0, L.mk_rot[k])
            continue
        nq = qoff[b + 1] - qoff[b]
        o = L.mk_shape[k]
        q = Q[qoff[b]:qoff[b + 1]].copy()
        first = L.mk_path[k, 0]
        if first >= 0:  # moving along a path: its point, frame and shapes at s(t)
            if L.mk_path[k, 2] >= 0:
                s = projected_arc(L.curve_x, L.curve_c, L.curve_meta, first, R[b], A[b], q, P[L.mk_path[k, 2]])
            else:
                cx, cc = motion_curve(L.curve_x, L.curve_c, L.curve_meta, L.mk_path[k, 1])
                s, s_dot, _ = motion_state(int(L.mk_motion[k, 0]), L.mk_motion[k, 1:], cx, cc, t)
            p, rot, point, phi, psi, on = path_pose(L.curve_x, L.curve_c, L.curve_meta, first, R[b], A[b], q, s,
                                                    L.mk_rot[k], False)
            put(P[k], 0, p)
            put2(AM[k], 0, 0, rot)
            if L.mk_path[k, 2] < 0:
                vc, wc = path_convection(L.curve_x, L.curve_c, L.curve_meta, first, R[b], A[b], q, s, s_dot,
                                         L.mk_rot[k], rot, on)
                put(VC[k], 0, vc)
                put(WC[k], 0, wc)
            if on:  # off its path it carries no load: zero Jacobians
                marker_pose(R[b], A[b], q, point, L.mk_rot[k], phi, psi, p_path, rot_path, d)
                marker_jacobians(A[b], d, phi, psi, JT[k], JR[k])
        else:
            phi = shapes[o:o + 3 * nq].reshape((3, nq))
            psi = shapes[o + 3 * nq:o + 6 * nq].reshape((3, nq))
            marker_pose(R[b], A[b], q, L.mk_pos[k], L.mk_rot[k], phi, psi, P[k], AM[k], d)
            marker_jacobians(A[b], d, phi, psi, JT[k], JR[k])
        w = uoff[b + 1] - uoff[b]
        for a in range(3):  # VEL = JT u_b, OMG = JR u_b
            vel = 0.0
            omg = 0.0
            for j in range(w):
                vel += JT[k, a, j] * u[uoff[b] + j]
                omg += JR[k, a, j] * u[uoff[b] + j]
            VEL[k, a] = vel
            OMG[k, a] = omg
        if stiffened:
            put2(JTF[k], 0, 0, stiffen(JT[k, :, :w], A[b], q, shapes, L.mk_k0[k, 0]))
            put2(JRF[k], 0, 0, stiffen(JR[k, :, :w], A[b], q, shapes, L.mk_k0[k, 1]))


def every_marker(L):
    """The layout L with every marker active: its Evaluation's ``kin`` holds all markers."""
    return L._replace(mk_active=np.ones(L.mk_body.shape[0], dtype=np.int64))


@jit
def evaluate_into(L, W, R, A, Q, u, t, lam, refs):  # pragma: no cover - compiled
    """The system at a state (module doc), written into the Evaluation W (evaluation_arrays(L),
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
    nb = R.shape[0]
    M, f = W.M, W.f
    M.fill(0.0)
    f.fill(0.0)
    uoff, qoff = L.uoff, L.qoff
    for i in range(nb):
        q = Q[qoff[i]:qoff[i + 1]]
        qd = u[uoff[i] + 6:uoff[i + 1]]
        w = u[uoff[i] + 3:uoff[i] + 6]
        gk = tmatvec(A[i], L.gravity)
        mk, h = body_equations(L.body_F, L.body_off[i], L.body_flags[i], L.body_mass[i], q, qd, w, gk)
        s = L.uoff[i]
        top = matmul(A[i], mk[:3, 3:])
        put2(mk, 0, 3, top)
        put2(mk, 3, 0, top.T)
        put2(M, s, s, mk)
        add(f, s, matvec(A[i], h[:3]))
        add(f, s + 3, h[3:])
    kin = W.kin
    markers_into(L, kin, R, A, Q, u, t)
    P, AM, VEL, OMG, JT, JR, JTF, JRF, VC, WC = kin
    nmk = P.shape[0]
    nj = L.joint_mk.shape[0]
    coords, crows, convective = W.coords, W.crows, W.convective
    coords.fill(0.0)
    crows.fill(0.0)
    convective.fill(0.0)
    for j in range(nj):
        if L.joint_kind[j] != NO_COORDINATE:
            k1, k2 = L.joint_mk[j, 0], L.joint_mk[j, 1]
            value, c = joint_coordinate(L.joint_kind[j], P[k1], AM[k1], P[k2], AM[k2], refs[j])
            convective[j] = row_rate(c, VC[k1], WC[k1], VC[k2], WC[k2])
            coords[j, 0] = value
            coords[j, 1] = row_rate(c, VEL[k1], OMG[k1], VEL[k2], OMG[k2]) + convective[j]
            put2(crows[j], 0, 0, c)
    loads, flows = W.loads, W.flows
    loads.fill(0.0)
    flows.fill(0.0)
    force_elements(L, t, kin, coords, crows, convective, lam, loads, flows)
    for i in range(L.fe_int.shape[0]):  # moving masses: m J^T J in M, m (g - a_convective) at the point
        if L.fe_int[i, 0] == FE_MOVING_MASS:
            k, mass = L.fe_int[i, 1], L.fe_par[i, 0]
            b = L.mk_body[k]
            s0, w = uoff[b], uoff[b + 1] - uoff[b]
            jt = JT[k, :, :w]
            for r in range(w):
                for c in range(w):
                    acc = 0.0
                    for a in range(3):
                        acc += jt[a, r] * jt[a, c]
                    M[s0 + r, s0 + c] += mass * acc
            add(loads[k], 0, mass * (L.gravity - path_acceleration(L, k, R, A, Q, u, t)))
    for i in range(nb):
        if L.body_flags[i, F_DAMPING]:  # modal damping dissipates qd^T De qd
            qd = u[uoff[i] + 6:uoff[i + 1]]
            nq = qd.shape[0]
            o = L.body_off[i, DE]
            flows[1] += dot(qd, matvec(L.body_F[o:o + nq * nq].reshape((nq, nq)), qd))
    for k in range(nmk):
        b = L.mk_body[k]
        if b >= 0 and L.mk_active[k]:
            for i in range(uoff[b + 1] - uoff[b]):  # f += JTF^T F + JRF^T T, in scalars
                force = 0.0
                torque = 0.0
                for a in range(3):
                    force += JTF[k, a, i] * loads[k, a]
                    torque += JRF[k, a, i] * loads[k, 3 + a]
                f[uoff[b] + i] += force
                f[uoff[b] + i] += torque
    nrj = L.joint_off[-1]
    m_all = nrj + L.drv_joint.shape[0]
    g, bt, B, BF, C = W.g, W.bt, W.B, W.BF, W.C
    g.fill(0.0)
    bt.fill(0.0)
    B.fill(0.0)
    BF.fill(0.0)  # (B itself unless load-stiffened: the load Jacobians differ from JT, JR only then)
    C.fill(0.0)
    stiffened = load_stiffened(L.mk_k0)
    for j in range(nj):
        k1, k2 = L.joint_mk[j, 0], L.joint_mk[j, 1]
        r0, r1 = L.joint_off[j], L.joint_off[j + 1]
        joint_rows(L.jrows[r0:r1], P[k1], AM[k1], P[k2], AM[k2], g, C, r0)
        for r in range(r0, r1):  # rheonomic rows of markers moving along a path
            bt[r] = row_rate(C[r], VC[k1], WC[k1], VC[k2], WC[k2])
    for d in range(L.drv_joint.shape[0]):
        j = L.drv_joint[d]
        cx, cc = motion_curve(L.curve_x, L.curve_c, L.curve_meta, L.drv_curve[d])
        value, rate, _ = motion_state(L.drv_kind[d], L.drv_par[d], cx, cc, t)
        g[nrj + d] = coords[j, 0] - value
        bt[nrj + d] = convective[j] - rate
        put2(C[nrj + d], 0, 0, crows[j])
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
                w = uoff[b + 1] - uoff[b]
                add_rows(B, r, L.uoff[b], C[r], JT[k], JR[k], which, w)
                if stiffened:
                    add_rows(BF, r, L.uoff[b], C[r], JTF[k], JRF[k], which, w)


@jit
def constraint_power(L, B, bt, u, lam):  # pragma: no cover - compiled
    """Power (W) the rheonomic rows put into the bodies, -sum lambda_r (B u)_r over the drivers'
    rows and the rows with b_t != 0 (joints on markers moving along a path): the work of the
    drives.  B (m_all, n), bt (m_all,) from evaluate, u (n,), lam (m_all,)."""
    nrj = L.joint_off[-1]
    power = 0.0
    for r in range(B.shape[0]):
        if r >= nrj or bt[r] != 0.0:
            power -= lam[r] * dot(B[r], u)
    return power


@jit
def energies(L, R, A, Q, u, M):  # pragma: no cover - compiled
    """(kinetic, strain, gravity potential) of all bodies, J; M the system mass matrix."""
    kinetic = 0.5 * dot(u, matvec(M, u))
    strain = grav = 0.0
    for i in range(R.shape[0]):
        q = Q[L.qoff[i]:L.qoff[i + 1]].copy()
        s, gp = body_potentials(L.body_F, L.body_off[i], L.body_flags[i], L.body_mass[i], R[i], A[i], q, L.gravity)
        strain += s
        grav += gp
    return kinetic, strain, grav
