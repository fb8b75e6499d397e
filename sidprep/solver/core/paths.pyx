"""Markers moving along a path of a flexible body, compiled: the point and frame at an arc length on
the deformed path (Hartweg and Heckmann 2012), their derivatives along the path and along the
motion, and the projection of a point onto the path (model/bodies.py PathMarker, OnPath).

A path (layout.add_path: 3 + 6 nq cubic curves from curve ``first`` on one grid of s) gives the
undeformed point x(s) and the mode shapes Phi(s), Psi(s) (curves.path_shapes); a body's pose
(r, A, q) travels as a BodyPose (paths.pxd).  Nothing here allocates: the shapes live in the
caller's scratch ``work`` (row-major (3, nq) blocks nq apart), 3-vectors and frames in C arrays.
"""

from libc.math cimport INFINITY, sqrt
from libc.stdint cimport int64_t

from sidprep.solver.core.curves cimport motion_state, path_shapes
from sidprep.solver.core.forces cimport motion_curve
from sidprep.solver.core.records cimport Layout
from sidprep.solver.core.rotations cimport align, dot3, exp_so3, matmul3, matvec3, tmatvec3

#: time step of the second central difference giving a path point's convective acceleration, s
cdef double PATH_GAMMA_STEP = 1e-5
#: arc-length step of the central difference giving a path's tangent, m
cdef double PATH_TANGENT_STEP = 1e-6
#: Newton steps projecting a point onto a path (from the nearest sample; quadratic convergence)
cdef Py_ssize_t PROJECTION_ITERATIONS = 3


cdef void shape_combination(const double* phi, const double* q, Py_ssize_t nq, const double* base,
                            double* out) noexcept nogil:
    """out (3,) = base + Phi q for Phi (3, nq) row-major."""
    cdef Py_ssize_t a, k
    cdef double acc
    for a in range(3):
        acc = 0.0
        for k in range(nq):
            acc += phi[a * nq + k] * q[k]
        out[a] = base[a] + acc


cdef void path_point(Layout L, Py_ssize_t first, BodyPose body, double s, double* work, double* out) noexcept nogil:
    """out (3,): inertial position of the point at arc length s of a path of a body at (r, A, q);
    work: 9 nq scratch doubles."""
    cdef Py_ssize_t nq = body.nq
    cdef double point[3]
    cdef double dpoint[3]
    cdef double x[3]
    path_shapes(L, first, nq, s, point, work, work + 3 * nq, dpoint, work + 6 * nq)
    shape_combination(work, body.q, nq, point, x)
    matvec3(body.a, x, out)
    out[0] += body.r[0]
    out[1] += body.r[1]
    out[2] += body.r[2]


cdef double projected_arc(Layout L, Py_ssize_t first, BodyPose body, const double* target, double* work) noexcept nogil:
    """Arc length s (m) of the point of a path (of a body at r, A, q) nearest to ``target`` (3,):
    the undeformed sample nearest to it in the body frame, then Newton on
    tau(s) . (target - point(s)) = 0 on the deformed path; work: 9 nq scratch doubles."""
    cdef const int64_t[:, ::1] meta = L.curve_meta
    cdef const double[::1] curve_x = L.curve_x, curve_c = L.curve_c
    cdef Py_ssize_t x0 = meta[first, 0], nx = meta[first, 1], i, comp, _
    cdef double local[3]
    cdef double diff[3]
    cdef double point[3]
    cdef double plus[3]
    cdef double minus[3]
    cdef double tangent[3]
    cdef double best = INFINITY, s = curve_x[x0], d2, e, h = PATH_TANGENT_STEP
    for comp in range(3):
        diff[comp] = target[comp] - body.r[comp]
    tmatvec3(body.a, diff, local)
    for i in range(nx - 1):  # the sample points are the cubic pieces' constant terms
        d2 = 0.0
        for comp in range(3):
            e = local[comp] - curve_c[meta[first + comp, 2] + 3 * (meta[first + comp, 1] - 1) + i]
            d2 += e * e
        if d2 < best:
            best, s = d2, curve_x[x0 + i]
    for _ in range(PROJECTION_ITERATIONS):
        path_point(L, first, body, s, work, point)
        path_point(L, first, body, s + h, work, plus)
        path_point(L, first, body, s - h, work, minus)
        for comp in range(3):
            tangent[comp] = (plus[comp] - minus[comp]) / (2.0 * h)
            diff[comp] = target[comp] - point[comp]
        s += dot3(tangent, diff) / dot3(tangent, tangent)
    return s


cdef double motion_arc(Layout L, Py_ssize_t k, double t) noexcept nogil:
    """Arc length s(t) (m) of path marker k's motion."""
    cdef (const double*, Py_ssize_t, const double*, Py_ssize_t) curve = motion_curve(L, L.mk_path[k, 1])
    return motion_state(<int64_t>L.mk_motion[k, 0], &L.mk_motion[k, 1], curve, t)[0]


cdef void path_position(Layout L, Py_ssize_t k, BodyPose body, const double* ub, double t, double tau, double* work,
                        double* out) noexcept nogil:
    """out (3,): inertial position of path marker k's point after ``tau`` s along the motion of
    its body (at r, A, q) at constant velocities ub = [v_O, omega, qd] and of its arc length
    s(t + tau); work: 10 nq scratch doubles."""
    cdef double s = motion_arc(L, k, t + tau)
    cdef double r1[3]
    cdef double theta[3]
    cdef double turn[9]
    cdef double a1[9]
    cdef double* q1 = work + 9 * body.nq
    cdef BodyPose moved = body
    cdef Py_ssize_t i
    for i in range(3):
        r1[i] = body.r[i] + tau * ub[i]
        theta[i] = tau * ub[3 + i]
    exp_so3(theta, turn)
    matmul3(body.a, turn, a1)
    for i in range(body.nq):
        q1[i] = body.q[i] + tau * ub[6 + i]
    moved.r, moved.a, moved.q = r1, a1, q1
    path_point(L, L.mk_path[k, 0], moved, s, work, out)


cdef void path_acceleration(Layout L, Py_ssize_t k, BodyPose body, const double* ub, double t, double* work,
                            double* out) noexcept nogil:
    """out (3,): acceleration of path marker k's point at zero accelerations of its body (at
    r, A, q with velocities ub; the convective part: s_ddot, s_dot^2, 2 s_dot Phi' qd, rotation),
    by the second central difference of its position along the motion (step PATH_GAMMA_STEP s);
    work: 10 nq doubles."""
    cdef double e = PATH_GAMMA_STEP
    cdef double plus[3]
    cdef double mid[3]
    cdef double minus[3]
    cdef Py_ssize_t i
    path_position(L, k, body, ub, t, e, work, plus)
    path_position(L, k, body, ub, t, 0.0, work, mid)
    path_position(L, k, body, ub, t, -e, work, minus)
    for i in range(3):
        out[i] = (plus[i] - 2.0 * mid[i] + minus[i]) / (e * e)


cdef bint path_pose(Layout L, Py_ssize_t first, BodyPose body, double s, const double* rotation, bint extend,
                    double* work, double* p, double* rot, double* point) noexcept nogil:
    """Position p (3,) and frame A_m (3, 3) (inertial) of a marker at arc length s on a path of
    a body at (r, A, q), the path's undeformed point x(s) (3,, K), its Phi, Psi (3, nq) there
    (in work[0:3 nq], work[3 nq:6 nq]; work: 9 nq doubles) and whether s is on the path (beyond
    the ends Phi = Psi = 0: the marker rides the straight extension rigidly; ``extend``: the end
    pieces' shapes go on, for derivatives at the ends): p = r + A (x(s) + Phi q); the frame is
    the marker rotation R_m turned from the undeformed tangent t0 to the deformed t = x' + Phi' q
    (the smallest rotation) and about t by the twist t0 . (Psi q):

        A_m = A exp(t0.(Psi q) t~) align(t0, t) R_m."""
    cdef const double* r = body.r
    cdef const double* a = body.a
    cdef const double* q = body.q
    cdef Py_ssize_t nq = body.nq
    cdef double dpoint[3]
    cdef double t0[3]
    cdef double t1[3]
    cdef double tangent[3]
    cdef double psi_q[3]
    cdef double zero[3]
    cdef double x[3]
    cdef double twist[9]
    cdef double turn[9]
    cdef double m[9]
    cdef double norm, spin
    cdef Py_ssize_t i
    cdef bint on = path_shapes(L, first, nq, s, point, work, work + 3 * nq, dpoint, work + 6 * nq)
    if not (on or extend):
        for i in range(9 * nq):
            work[i] = 0.0
    norm = sqrt(dot3(dpoint, dpoint))
    for i in range(3):
        t0[i] = dpoint[i] / norm
    shape_combination(work + 6 * nq, q, nq, dpoint, tangent)
    norm = sqrt(dot3(tangent, tangent))
    for i in range(3):
        t1[i] = tangent[i] / norm
        zero[i] = 0.0
    shape_combination(work + 3 * nq, q, nq, zero, psi_q)
    spin = dot3(t0, psi_q)
    for i in range(3):
        x[i] = spin * t1[i]
    exp_so3(x, twist)
    align(t0, t1, turn)
    matmul3(turn, rotation, m)
    matmul3(twist, m, m)
    matmul3(a, m, rot)
    shape_combination(work, q, nq, point, x)
    matvec3(a, x, p)
    for i in range(3):
        p[i] += r[i]
    return on


cdef void path_convection(Layout L, Py_ssize_t first, BodyPose body, double s, double s_dot, const double* rotation,
                          const double* frame, bint on, double* work, double* vc, double* wc) noexcept nogil:
    """Velocity vc (3,) and angular velocity wc (3,) (inertial) of a path marker at arc length s
    moving at s_dot (m/s) over its body held still, frame (3, 3) its A_m there: s_dot dp/ds and
    s_dot vee(dA_m/ds A_m^T) (path_pose; central differences, step PATH_TANGENT_STEP m; at the
    path's ends (``on``) with the end pieces' shapes on both sides); work: 9 nq doubles."""
    cdef double h = PATH_TANGENT_STEP, scale = s_dot / (2.0 * h)
    cdef double p_plus[3]
    cdef double p_minus[3]
    cdef double point[3]
    cdef double a_plus[9]
    cdef double a_minus[9]
    cdef double w[9]
    cdef Py_ssize_t i, j, k
    path_pose(L, first, body, s + h, rotation, on, work, p_plus, a_plus, point)
    path_pose(L, first, body, s - h, rotation, on, work, p_minus, a_minus, point)
    for i in range(9):
        a_plus[i] -= a_minus[i]
    for i in range(3):  # w = (A_m(s + h) - A_m(s - h)) frame^T
        for j in range(3):
            w[3 * i + j] = 0.0
            for k in range(3):
                w[3 * i + j] += a_plus[3 * i + k] * frame[3 * j + k]
    for i in range(3):
        vc[i] = scale * (p_plus[i] - p_minus[i])
    wc[0] = scale * (0.5 * (w[7] - w[5]))
    wc[1] = scale * (0.5 * (w[2] - w[6]))
    wc[2] = scale * (0.5 * (w[3] - w[1]))
