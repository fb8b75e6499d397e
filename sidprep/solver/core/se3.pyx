"""The coordinates the generalised-alpha stepper integrates: per body the group SE(3) x R^nq,
with the translational velocity in body-frame components v_K = A^T v_O (Bruls, Cardona & Arnold
2012, the SE(3) variant), instead of R^3 x SO(3) with inertial v_O.

Why: the Newmark update with alpha-lagged accelerations carries an O(h^2) error in every
integrated acceleration.  In R^3 x SO(3) a body whirling at Omega about a hinge away from its
frame origin O has the rotating inertial acceleration Omega^2 |O - hinge| of O; the error of a
rotating vector has a component along the motion, and through the coupling blocks of the mass
matrix (md~, Ct) it becomes a torque or a modal force of one sign: energy grows ~ h^2 Omega^3
per second (the bundled bar, frame at a corner, hinged at its end-face centre,
+2.5 % per 10 s at 50 rad/s, h = 1 ms; a rigid body with that frame placement did the same;
with clamped modes the growth diverged).  In SE(3) a uniform rotation about any fixed axis is
a one-parameter subgroup: v_K and omega stay constant, their accelerations are zero, the
exponential update is exact and nothing lags.

Per body, u_O = S u_K with S = blockdiag(A, E, E), ud_O = S ud_K + c, c = [A (omega x v_K); 0; 0];
the equations M ud_O - f + B_F^T lambda = 0, multiplied by S^T, become

    (S^T M S) ud_K - S^T (f - M c) + (B_F S)^T lambda = 0,    B -> B S   (g, b_t unchanged),

and the pose moves by the SE(3) exponential of the increment (rho, theta) (steps.advance_pose
with body_frame, rotations.se3_jacobian; its inverse rotations.se3_jacobian_solve):

    r <- r + A V(theta) rho,   A <- A exp(theta~),   V = E + (1 - cos t)/t^2 theta~ + (t - sin t)/t^3 theta~^2

(t = |theta|).  The stepper keeps u, ud and its pseudo-accelerations in these coordinates and
hands out inertial ones (samples, state).
"""

from libc.math cimport acos, sin

from sidprep.solver.core.records cimport Evaluation, Layout
from sidprep.solver.core.rotations cimport SMALL_ANGLE, se3_jacobian_solve


cpdef void rotate_translations(Layout L, const double[:, :, ::1] A, const double[::1] u, bint inverse,
                               double[::1] out) noexcept nogil:
    """out = S u_K (inverse False) or S^T u_O (inverse True), (n,); out may be u."""
    cdef Py_ssize_t b, i, s
    cdef double v0, v1, v2, acc
    cdef Py_ssize_t k
    if &out[0] != &u[0]:
        for k in range(u.shape[0]):
            out[k] = u[k]
    for b in range(A.shape[0]):
        s = L.uoff[b]
        v0, v1, v2 = u[s], u[s + 1], u[s + 2]
        for i in range(3):
            if inverse:
                acc = A[b, 0, i] * v0 + A[b, 1, i] * v1 + A[b, 2, i] * v2
            else:
                acc = A[b, i, 0] * v0 + A[b, i, 1] * v1 + A[b, i, 2] * v2
            out[s + i] = acc


cpdef void inertial_velocities(Layout L, const double[:, :, ::1] A, const double[::1] u_K,
                               double[::1] out) noexcept nogil:
    """out = u_O = S u_K (n,)."""
    rotate_translations(L, A, u_K, False, out)


cpdef void body_velocities(Layout L, const double[:, :, ::1] A, const double[::1] u_O, double[::1] out) noexcept nogil:
    """out = u_K = S^T u_O (n,)."""
    rotate_translations(L, A, u_O, True, out)


cdef inline void body_convective(const double[:, :, ::1] A, Py_ssize_t b, const double[::1] u_K, Py_ssize_t s,
                                 double* c) noexcept nogil:
    """c (3,) = A_b (omega x v_K) of body b, its velocities at offset s of u_K."""
    cdef double w0 = u_K[s + 3], w1 = u_K[s + 4], w2 = u_K[s + 5], v0 = u_K[s], v1 = u_K[s + 1], v2 = u_K[s + 2]
    cdef double x0 = w1 * v2 - w2 * v1, x1 = w2 * v0 - w0 * v2, x2 = w0 * v1 - w1 * v0
    cdef Py_ssize_t i
    for i in range(3):
        c[i] = A[b, i, 0] * x0 + A[b, i, 1] * x1 + A[b, i, 2] * x2


cpdef void convective(Layout L, const double[:, :, ::1] A, const double[::1] u_K, double[::1] c) noexcept nogil:
    """c = dS/dt u_K (n,): A (omega x v_K) on each body's translational rows, zero elsewhere."""
    cdef Py_ssize_t b, i
    for i in range(c.shape[0]):
        c[i] = 0.0
    for b in range(A.shape[0]):
        body_convective(A, b, u_K, L.uoff[b], &c[L.uoff[b]])


cpdef void inertial_accelerations(Layout L, const double[:, :, ::1] A, const double[::1] u_K,
                                  const double[::1] ud_K, double[::1] out) noexcept nogil:
    """out = ud_O = S ud_K + c (n,); out may be ud_K, not u_K."""
    cdef Py_ssize_t b, i, s
    cdef double c[3]
    rotate_translations(L, A, ud_K, False, out)
    for b in range(A.shape[0]):
        s = L.uoff[b]
        body_convective(A, b, u_K, s, c)
        for i in range(3):
            out[s + i] += c[i]


cpdef void body_accelerations(Layout L, const double[:, :, ::1] A, const double[::1] u_K, const double[::1] ud_O,
                              double[::1] out) noexcept nogil:
    """out = ud_K = S^T (ud_O - c) (n,); out may be ud_O, not u_K."""
    cdef Py_ssize_t b, i, s
    cdef double c[3]
    cdef double d[3]
    if &out[0] != &ud_O[0]:
        for i in range(ud_O.shape[0]):
            out[i] = ud_O[i]
    for b in range(A.shape[0]):
        s = L.uoff[b]
        body_convective(A, b, u_K, s, c)
        for i in range(3):
            d[i] = ud_O[s + i] - c[i]
        for i in range(3):
            out[s + i] = A[b, 0, i] * d[0] + A[b, 1, i] * d[1] + A[b, 2, i] * d[2]


cpdef void right_multiply(double[:, ::1] X, Layout L, const double[:, :, ::1] A) noexcept nogil:
    """X S in place (X (k, n)): body b's translational columns times A_b."""
    cdef Py_ssize_t b, r, i, s
    cdef double x0, x1, x2
    for b in range(A.shape[0]):
        s = L.uoff[b]
        for r in range(X.shape[0]):
            x0, x1, x2 = X[r, s], X[r, s + 1], X[r, s + 2]
            for i in range(3):
                X[r, s + i] = A[b, 0, i] * x0 + A[b, 1, i] * x1 + A[b, 2, i] * x2


cpdef void left_multiply(double[:, ::1] X, Layout L, const double[:, :, ::1] A) noexcept nogil:
    """S^T X in place (X (n, k)): body b's translational rows times A_b^T."""
    cdef Py_ssize_t b, col, i, s
    cdef double x0, x1, x2
    for b in range(A.shape[0]):
        s = L.uoff[b]
        for col in range(X.shape[1]):
            x0, x1, x2 = X[s, col], X[s + 1, col], X[s + 2, col]
            for i in range(3):
                X[s + i, col] = A[b, 0, i] * x0 + A[b, 1, i] * x1 + A[b, 2, i] * x2


cpdef void to_body_frame(Layout L, const double[:, :, ::1] A, const double[::1] u_K, Evaluation e,
                         double[::1] c) noexcept nogil:
    """The Evaluation e (assemble.evaluate_into, at the inertial velocities S u_K) turned in
    place into the coordinates of this module (module doc): M -> S^T M S, f -> S^T (f - M c),
    B -> B S, B_F -> B_F S; the rest as evaluate_into gives it.  c (n,) scratch (it holds
    c = dS/dt u_K afterwards)."""
    cdef Py_ssize_t i, j
    cdef double acc
    cdef double[:, ::1] M = e.M
    cdef double[::1] f = e.f
    convective(L, A, u_K, c)
    for i in range(f.shape[0]):
        acc = 0.0
        for j in range(M.shape[1]):
            acc += M[i, j] * c[j]
        f[i] = f[i] - acc
    rotate_translations(L, A, f, True, f)  # S^T f
    right_multiply(M, L, A)
    left_multiply(M, L, A)
    right_multiply(e.B, L, A)
    if e.kin.stiffened:  # B_F is B itself otherwise
        right_multiply(e.BF, L, A)


cpdef void body_increment(Layout L, const double[:, ::1] R0, const double[:, :, ::1] A0, const double[:, ::1] R1,
                          const double[:, :, ::1] A1, const double[::1] Q0, const double[::1] Q1,
                          double[::1] dx) noexcept nogil:
    """The increment dx (n,) = [rho, theta, dq] per body with R1, A1, Q1 = the pose R0, A0, Q0
    moved by dx (steps.advance_pose with body_frame): theta = log(A0^T A1),
    rho = V(theta)^-1 A0^T (R1 - R0)."""
    cdef Py_ssize_t i, a, b, j, k, s
    cdef double rot[9]
    cdef double theta[3]
    cdef double v[3]
    cdef double angle, scale
    for i in range(R0.shape[0]):
        s = L.uoff[i]
        for a in range(3):  # A0^T A1
            for b in range(3):
                rot[3 * a + b] = 0.0
            for j in range(3):
                for b in range(3):
                    rot[3 * a + b] += A0[i, j, a] * A1[i, j, b]
        angle = acos(min(1.0, max(-1.0, 0.5 * (rot[0] + rot[4] + rot[8] - 1.0))))
        scale = 0.5 if angle < SMALL_ANGLE else 0.5 * angle / sin(angle)
        theta[0] = scale * (rot[7] - rot[5])
        theta[1] = scale * (rot[2] - rot[6])
        theta[2] = scale * (rot[3] - rot[1])
        for a in range(3):  # A0^T (R1 - R0)
            v[a] = 0.0
        for j in range(3):
            for a in range(3):
                v[a] += A0[i, j, a] * (R1[i, j] - R0[i, j])
        se3_jacobian_solve(theta, v, &dx[s])
        for a in range(3):
            dx[s + 3 + a] = theta[a]
        for k in range(L.qoff[i + 1] - L.qoff[i]):
            dx[s + 6 + k] = Q1[L.qoff[i] + k] - Q0[L.qoff[i] + k]
