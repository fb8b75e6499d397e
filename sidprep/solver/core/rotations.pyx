"""Rotation kinematics (skew matrices, the SO(3) exponential map, quaternions) and the small
matrix products of the compiled kernels: the geometry under both the descriptions (model/, e.g.
``as_rotation``) and the kernels (rotations.pxd holds the 3-vector and 3x3 functions inline).

Rotation matrices A map body components to inertial components (sid-spec 5.1); angular
velocities are body components, so the Lie-group update is A_{n+1} = A_n exp(skew(dtheta)).
"""

import numpy as np

# the constants of rotations.pxd for Python code, under the same names
globals().update(SMALL_ANGLE=SMALL_ANGLE, SE3_SMALL_ANGLE=SE3_SMALL_ANGLE)


cdef double dot(const double[:] a, const double[:] b) noexcept nogil:
    """a . b for two vectors of equal length (any memory layout)."""
    cdef double acc = 0.0
    cdef Py_ssize_t i
    for i in range(a.shape[0]):
        acc += a[i] * b[i]
    return acc


cdef void matvec(const double[:, :] a, const double[:] x, double[:] out) noexcept nogil:
    """out = a x; (p, r) x (r,) -> (p,)."""
    cdef double acc
    cdef Py_ssize_t i, j
    for i in range(a.shape[0]):
        acc = 0.0
        for j in range(a.shape[1]):
            acc += a[i, j] * x[j]
        out[i] = acc


cdef void tmatvec(const double[:, :] a, const double[:] x, double[:] out) noexcept nogil:
    """out = a^T x; (r, p) x (r,) -> (p,)."""
    cdef double xj
    cdef Py_ssize_t i, j
    for i in range(a.shape[1]):
        out[i] = 0.0
    for j in range(a.shape[0]):
        xj = x[j]
        for i in range(a.shape[1]):
            out[i] += a[j, i] * xj


cdef void matmul(const double[:, :] a, const double[:, :] b, double[:, :] out) noexcept nogil:
    """out = a b by loops: for the small (3 x k) products of the kernels, where a BLAS call costs
    more than the arithmetic; (p, r) x (r, k) -> (p, k)."""
    cdef double aij
    cdef Py_ssize_t i, j, k
    for i in range(a.shape[0]):
        for k in range(b.shape[1]):
            out[i, k] = 0.0
        for j in range(a.shape[1]):
            aij = a[i, j]
            for k in range(b.shape[1]):
                out[i, k] += aij * b[j, k]


ctypedef void (*VectorToMatrix)(const double*, double*) noexcept nogil


cdef object matrix_of(VectorToMatrix kernel, vector):
    """The (3, 3) array that ``kernel`` writes for the (3,) ``vector``."""
    cdef double[::1] v = np.ascontiguousarray(vector, dtype=float).reshape(3)
    out = np.empty((3, 3))
    cdef double[:, ::1] o = out
    kernel(&v[0], &o[0, 0])
    return out


def rotation_matrix(theta) -> np.ndarray:
    """Rotation matrix (3, 3) of the rotation vector theta (3,), rad (Rodrigues: exp_so3)."""
    return matrix_of(exp_so3, theta)


def skew_matrix(a) -> np.ndarray:
    """The tilde operator, skew(a) @ b == cross(a, b); (3,) -> (3, 3)."""
    return matrix_of(skew3, a)


def se3_jacobian_matrix(theta) -> np.ndarray:
    """V(theta) (3, 3) of the SE(3) exponential (se3_jacobian) of the rotation vector theta (3,), rad."""
    return matrix_of(se3_jacobian, theta)


def solve_se3_jacobian(theta, v) -> np.ndarray:
    """V(theta)^-1 v (3,) in closed form (se3_jacobian_solve); theta, v (3,)."""
    cdef double[::1] t = np.ascontiguousarray(theta, dtype=float).reshape(3)
    cdef double[::1] x = np.ascontiguousarray(v, dtype=float).reshape(3)
    out = np.empty(3)
    cdef double[::1] o = out
    se3_jacobian_solve(&t[0], &x[0], &o[0])
    return out


def matrix_to_quaternion(rot) -> np.ndarray:
    """Unit quaternion [e0, e1, e2, e3] (e0 >= 0) of a rotation matrix (3, 3) (Shepperd's method)."""
    rot = np.asarray(rot, dtype=float)
    tr = np.trace(rot)
    diag = np.array([tr, rot[0, 0], rot[1, 1], rot[2, 2]])
    i = int(np.argmax(diag))
    if i == 0:
        e0 = 0.5 * np.sqrt(1.0 + tr)
        e = np.array([e0, (rot[2, 1] - rot[1, 2]) / (4 * e0), (rot[0, 2] - rot[2, 0]) / (4 * e0),
                      (rot[1, 0] - rot[0, 1]) / (4 * e0)])
    else:
        a, b, c = (i - 1, i % 3, (i + 1) % 3)
        ea = 0.5 * np.sqrt(1.0 + 2 * rot[a, a] - tr)
        e = np.empty(4)
        e[0] = (rot[c, b] - rot[b, c]) / (4 * ea)
        e[1 + a] = ea
        e[1 + b] = (rot[a, b] + rot[b, a]) / (4 * ea)
        e[1 + c] = (rot[a, c] + rot[c, a]) / (4 * ea)
    return e if e[0] >= 0 else -e


def as_rotation(value) -> np.ndarray:
    """A rotation matrix (3, 3) from None (identity), a (3, 3) matrix or a rotation vector (3,), rad."""
    if value is None:
        return np.eye(3)
    a = np.asarray(value, dtype=float)
    if a.shape == (3, 3):
        return a
    if a.shape == (3,):
        return rotation_matrix(a)
    raise ValueError(f"rotation must be a 3x3 matrix or a rotation vector, got shape {a.shape}")
