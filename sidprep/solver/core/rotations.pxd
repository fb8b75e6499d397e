# Rotation kinematics of the compiled kernels: 3-vectors and row-major 3x3 matrices on double
# pointers (inline here), and small strided matrix products (rotations.pyx).  Rotation matrices A
# map body components to inertial components (sid-spec 5.1); angular velocities are body
# components, so the Lie-group update is A_{n+1} = A_n exp(skew(dtheta)).
#
# The pointer functions read all their inputs before writing out, so out may be an input.
from libc.math cimport cos, sin, sqrt

cdef extern from *:
    """
    #define SIDPREP_SMALL_ANGLE 1e-6
    #define SIDPREP_SE3_SMALL_ANGLE 1e-4
    """
    # below this rotation angle (rad) the Rodrigues coefficients use their Taylor series
    const double SMALL_ANGLE "SIDPREP_SMALL_ANGLE"
    # ... and those of the SE(3) Jacobian (its (t - sin t)/t^3 loses digits sooner)
    const double SE3_SMALL_ANGLE "SIDPREP_SE3_SMALL_ANGLE"


cdef inline double dot3(const double* a, const double* b) noexcept nogil:
    """a . b of two 3-vectors."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


cdef inline void cross3(const double* a, const double* b, double* out) noexcept nogil:
    """out = a x b (3,)."""
    cdef double x = a[1] * b[2] - a[2] * b[1], y = a[2] * b[0] - a[0] * b[2], z = a[0] * b[1] - a[1] * b[0]
    out[0] = x
    out[1] = y
    out[2] = z


cdef inline void matvec3(const double* A, const double* x, double* out) noexcept nogil:
    """out = A x; A (3, 3) row-major, x (3,)."""
    cdef double x0 = x[0], x1 = x[1], x2 = x[2]
    out[0] = A[0] * x0 + A[1] * x1 + A[2] * x2
    out[1] = A[3] * x0 + A[4] * x1 + A[5] * x2
    out[2] = A[6] * x0 + A[7] * x1 + A[8] * x2


cdef inline void tmatvec3(const double* A, const double* x, double* out) noexcept nogil:
    """out = A^T x; A (3, 3) row-major, x (3,)."""
    cdef double x0 = x[0], x1 = x[1], x2 = x[2]
    out[0] = A[0] * x0 + A[3] * x1 + A[6] * x2
    out[1] = A[1] * x0 + A[4] * x1 + A[7] * x2
    out[2] = A[2] * x0 + A[5] * x1 + A[8] * x2


cdef inline void matmul3(const double* A, const double* B, double* out) noexcept nogil:
    """out = A B; (3, 3) row-major each."""
    cdef double C[9]
    cdef int i, k
    for i in range(3):
        for k in range(3):
            C[3 * i + k] = A[3 * i] * B[k] + A[3 * i + 1] * B[3 + k] + A[3 * i + 2] * B[6 + k]
    for i in range(9):
        out[i] = C[i]


cdef inline void skew3(const double* a, double* out) noexcept nogil:
    """The tilde operator, skew(a) b == a x b; (3,) -> (3, 3) row-major."""
    cdef double x = a[0], y = a[1], z = a[2]
    out[0] = 0.0
    out[1] = -z
    out[2] = y
    out[3] = z
    out[4] = 0.0
    out[5] = -x
    out[6] = -y
    out[7] = x
    out[8] = 0.0


cdef inline void rodrigues_form(const double* theta, double a, double b, double* out) noexcept nogil:
    """out = E + a T + b T T (3, 3) with T = skew(theta): the form of exp_so3 and se3_jacobian."""
    cdef double x = theta[0], y = theta[1], z = theta[2]
    cdef double angle2 = x * x + y * y + z * z
    # T T = theta theta^T - angle2 E
    out[0] = 1.0 + b * (x * x - angle2)
    out[1] = -a * z + b * x * y
    out[2] = a * y + b * x * z
    out[3] = a * z + b * x * y
    out[4] = 1.0 + b * (y * y - angle2)
    out[5] = -a * x + b * y * z
    out[6] = -a * y + b * x * z
    out[7] = a * x + b * y * z
    out[8] = 1.0 + b * (z * z - angle2)


cdef inline void exp_so3(const double* theta, double* out) noexcept nogil:
    """Rotation matrix (3, 3) of the rotation vector theta (3,), rad (Rodrigues)."""
    cdef double angle2 = theta[0] * theta[0] + theta[1] * theta[1] + theta[2] * theta[2]
    cdef double angle
    if angle2 < SMALL_ANGLE * SMALL_ANGLE:
        rodrigues_form(theta, 1.0 - angle2 / 6.0, 0.5 - angle2 / 24.0, out)
        return
    angle = sqrt(angle2)
    rodrigues_form(theta, sin(angle) / angle, (1.0 - cos(angle)) / angle2, out)


cdef inline void se3_jacobian(const double* theta, double* out) noexcept nogil:
    """V(theta) (3, 3) of the SE(3) exponential: exp of the twist (rho, theta) moves the origin
    by V rho (body components), V = E + (1 - cos t)/t^2 T + (t - sin t)/t^3 T T, t = |theta|."""
    cdef double t2 = theta[0] * theta[0] + theta[1] * theta[1] + theta[2] * theta[2]
    cdef double t
    if t2 < SE3_SMALL_ANGLE * SE3_SMALL_ANGLE:
        rodrigues_form(theta, 0.5 - t2 / 24.0, 1.0 / 6.0 - t2 / 120.0, out)
        return
    t = sqrt(t2)
    rodrigues_form(theta, (1.0 - cos(t)) / t2, (t - sin(t)) / (t2 * t), out)


cdef inline void se3_jacobian_solve(const double* theta, const double* v, double* out) noexcept nogil:
    """out = V(theta)^-1 v (3,) in closed form (se3_jacobian): V^-1 = E - T / 2 + (1 - (t / 2) cot(t / 2)) / t^2 T T,
    t = |theta| < 2 pi (V and V^-1 are functions of T: on its eigenvalues 0, +-i t, V is
    (e^(i t) - 1) / (i t) and V^-1 its reciprocal); below SE3_SMALL_ANGLE 1/12 + t^2/720."""
    cdef double x = theta[0], y = theta[1], z = theta[2]
    cdef double v0 = v[0], v1 = v[1], v2 = v[2]
    cdef double t2 = x * x + y * y + z * z
    cdef double b, half, tv0, tv1, tv2, ttv0, ttv1, ttv2
    if t2 < SE3_SMALL_ANGLE * SE3_SMALL_ANGLE:
        b = 1.0 / 12.0 + t2 / 720.0
    else:
        half = 0.5 * sqrt(t2)
        b = (1.0 - half * cos(half) / sin(half)) / t2
    tv0, tv1, tv2 = y * v2 - z * v1, z * v0 - x * v2, x * v1 - y * v0  # T v
    ttv0, ttv1, ttv2 = y * tv2 - z * tv1, z * tv0 - x * tv2, x * tv1 - y * tv0  # T T v
    out[0] = v0 - 0.5 * tv0 + b * ttv0
    out[1] = v1 - 0.5 * tv1 + b * ttv1
    out[2] = v2 - 0.5 * tv2 + b * ttv2


cdef inline void align(const double* a, const double* b, double* out) noexcept nogil:
    """The smallest rotation (3, 3) taking the unit vector a to the unit vector b (a . b > -1):
    E + v~ + v~^2 / (1 + a . b), v = a x b."""
    cdef double v[3]
    cdef double vv[9]
    cdef double vv2[9]
    cdef double c = 1.0 + dot3(a, b)
    cdef int i
    cross3(a, b, v)
    skew3(v, vv)
    matmul3(vv, vv, vv2)
    for i in range(9):
        out[i] = vv[i] + vv2[i] / c
    out[0] += 1.0
    out[4] += 1.0
    out[8] += 1.0


cdef inline void quaternion_to_matrix(const double* e, double* out) noexcept nogil:
    """Rotation matrix (3, 3) of the (normalised on the fly) quaternion e = [e0, e1, e2, e3]."""
    cdef double norm = sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2] + e[3] * e[3])
    cdef double e0 = e[0] / norm, e1 = e[1] / norm, e2 = e[2] / norm, e3 = e[3] / norm
    out[0] = 1 - 2 * (e2 * e2 + e3 * e3)
    out[1] = 2 * (e1 * e2 - e0 * e3)
    out[2] = 2 * (e1 * e3 + e0 * e2)
    out[3] = 2 * (e1 * e2 + e0 * e3)
    out[4] = 1 - 2 * (e1 * e1 + e3 * e3)
    out[5] = 2 * (e2 * e3 - e0 * e1)
    out[6] = 2 * (e1 * e3 - e0 * e2)
    out[7] = 2 * (e2 * e3 + e0 * e1)
    out[8] = 1 - 2 * (e1 * e1 + e2 * e2)


cdef inline void quaternion_rate(const double* e, const double* omega_body, double* out) noexcept nogil:
    """out = de/dt (4,) = 0.5 e (x) [0, omega] for the body-frame angular velocity omega (3,),
    rad/s (e normalised on the fly)."""
    cdef double norm = sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2] + e[3] * e[3])
    cdef double e0 = e[0] / norm, e1 = e[1] / norm, e2 = e[2] / norm, e3 = e[3] / norm
    cdef double w1 = omega_body[0], w2 = omega_body[1], w3 = omega_body[2]
    out[0] = 0.5 * (-e1 * w1 - e2 * w2 - e3 * w3)
    out[1] = 0.5 * (e0 * w1 + e2 * w3 - e3 * w2)
    out[2] = 0.5 * (e0 * w2 - e1 * w3 + e3 * w1)
    out[3] = 0.5 * (e0 * w3 + e1 * w2 - e2 * w1)


# strided memoryviews of any size (rotations.pyx); out must not overlap the inputs
cdef double dot(const double[:] a, const double[:] b) noexcept nogil
cdef void matvec(const double[:, :] a, const double[:] x, double[:] out) noexcept nogil
cdef void tmatvec(const double[:, :] a, const double[:] x, double[:] out) noexcept nogil
cdef void matmul(const double[:, :] a, const double[:, :] b, double[:, :] out) noexcept nogil
