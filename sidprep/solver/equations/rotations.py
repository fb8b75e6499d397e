"""Rotation kinematics (skew matrices, the SO(3) exponential map, quaternions) and the small
loop helpers of the compiled kernels (``jit``, the one decorator of all of them, is aot.py's): the geometry
under both the descriptions (model/, e.g. ``as_rotation``) and the kernels (equations/).

Rotation matrices A map body components to inertial components (sid-spec 5.1); angular
velocities are body components, so the Lie-group update is A_{n+1} = A_n exp(skew(dtheta)).
"""

from __future__ import annotations

import math

import numpy as np

from sidprep.solver.equations.aot import jit

#: below this rotation angle (rad) the Rodrigues coefficients use their Taylor series
SMALL_ANGLE = 1e-6
#: ... and those of the SE(3) Jacobian (its (t - sin t)/t^3 loses digits sooner)
SE3_SMALL_ANGLE = 1e-4


@jit
def skew(a: np.ndarray) -> np.ndarray:
    """The tilde operator, skew(a) @ b == cross(a, b); (3,) -> (3, 3)."""
    out = np.zeros((3, 3))  # element stores: np.array of nested lists costs 10 allocations in numba
    out[0, 1], out[0, 2], out[1, 0], out[1, 2], out[2, 0], out[2, 1] = -a[2], a[1], a[2], -a[0], -a[1], a[0]
    return out


@jit
def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b for two 3-vectors (np.cross has ~20 us of overhead per call)."""
    out = np.empty(3)
    out[0], out[1], out[2] = a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]
    return out


@jit
def matmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a @ b by loops: for the small (3 x k) products of the kernels, where a BLAS call costs
    more than the arithmetic; (p, r) x (r, k) -> (p, k)."""
    out = np.zeros((a.shape[0], b.shape[1]))
    for i in range(a.shape[0]):
        for j in range(a.shape[1]):
            aij = a[i, j]
            for k in range(b.shape[1]):
                out[i, k] += aij * b[j, k]
    return out


@jit
def put(dst: np.ndarray, start: int, src: np.ndarray, scale: float = 1.0) -> None:
    """dst[start:start+n] = scale * src for vectors, by a loop (an array slice assignment costs
    seconds of compilation in numba)."""
    for i in range(src.shape[0]):
        dst[start + i] = scale * src[i]


@jit
def add(dst: np.ndarray, start: int, src: np.ndarray, scale: float = 1.0) -> None:
    """dst[start:start+n] += scale * src for vectors, by a loop."""
    for i in range(src.shape[0]):
        dst[start + i] += scale * src[i]


@jit
def put2(dst: np.ndarray, r0: int, c0: int, src: np.ndarray) -> None:
    """dst[r0:r0+p, c0:c0+q] = src for matrices, by loops."""
    for i in range(src.shape[0]):
        for j in range(src.shape[1]):
            dst[r0 + i, c0 + j] = src[i, j]


@jit
def dot(a: np.ndarray, b: np.ndarray) -> float:
    """a . b for two vectors of equal length, by a loop (any memory layout)."""
    acc = 0.0
    for i in range(a.shape[0]):
        acc += a[i] * b[i]
    return acc


@jit
def matvec(a: np.ndarray, x: np.ndarray) -> np.ndarray:
    """a @ x by loops; (p, r) x (r,) -> (p,)."""
    out = np.zeros(a.shape[0])
    for i in range(a.shape[0]):
        for j in range(a.shape[1]):
            out[i] += a[i, j] * x[j]
    return out


@jit
def tmatvec(a: np.ndarray, x: np.ndarray) -> np.ndarray:
    """a^T @ x by loops; (r, p) x (r,) -> (p,)."""
    out = np.zeros(a.shape[1])
    for j in range(a.shape[0]):
        for i in range(a.shape[1]):
            out[i] += a[j, i] * x[j]
    return out


@jit
def rodrigues_form(theta: np.ndarray, a: float, b: float) -> np.ndarray:
    """E + a T + b T T (3, 3) with T = skew(theta): the form of exp_so3 and se3_jacobian."""
    x, y, z = theta[0], theta[1], theta[2]
    angle2 = x * x + y * y + z * z
    # T T = theta theta^T - angle2 E
    out = np.empty((3, 3))
    out[0, 0], out[0, 1], out[0, 2] = 1.0 + b * (x * x - angle2), -a * z + b * x * y, a * y + b * x * z
    out[1, 0], out[1, 1], out[1, 2] = a * z + b * x * y, 1.0 + b * (y * y - angle2), -a * x + b * y * z
    out[2, 0], out[2, 1], out[2, 2] = -a * y + b * x * z, a * x + b * y * z, 1.0 + b * (z * z - angle2)
    return out


@jit
def exp_so3(theta: np.ndarray) -> np.ndarray:
    """Rotation matrix of the rotation vector theta (Rodrigues); (3,) -> (3, 3)."""
    angle2 = theta[0] * theta[0] + theta[1] * theta[1] + theta[2] * theta[2]
    if angle2 < SMALL_ANGLE**2:
        return rodrigues_form(theta, 1.0 - angle2 / 6.0, 0.5 - angle2 / 24.0)
    angle = math.sqrt(angle2)
    return rodrigues_form(theta, math.sin(angle) / angle, (1.0 - math.cos(angle)) / angle2)


@jit
def se3_jacobian(theta: np.ndarray) -> np.ndarray:
    """V(theta) (3, 3) of the SE(3) exponential: exp of the twist (rho, theta) moves the origin
    by V rho (body components), V = E + (1 - cos t)/t^2 T + (t - sin t)/t^3 T T, t = |theta|."""
    t2 = theta[0] * theta[0] + theta[1] * theta[1] + theta[2] * theta[2]
    if t2 < SE3_SMALL_ANGLE**2:
        return rodrigues_form(theta, 0.5 - t2 / 24.0, 1.0 / 6.0 - t2 / 120.0)
    t = math.sqrt(t2)
    return rodrigues_form(theta, (1.0 - math.cos(t)) / t2, (t - math.sin(t)) / (t2 * t))


@jit
def se3_jacobian_solve(theta: np.ndarray, v: np.ndarray) -> np.ndarray:
    """V(theta)^-1 v (3,) in closed form (se3_jacobian): V^-1 = E - T / 2 + (1 - (t / 2) cot(t / 2)) / t^2 T T,
    t = |theta| < 2 pi (V and V^-1 are functions of T: on its eigenvalues 0, +-i t, V is
    (e^(i t) - 1) / (i t) and V^-1 its reciprocal); below SE3_SMALL_ANGLE 1/12 + t^2/720."""
    x, y, z = theta[0], theta[1], theta[2]
    t2 = x * x + y * y + z * z
    if t2 < SE3_SMALL_ANGLE**2:
        b = 1.0 / 12.0 + t2 / 720.0
    else:
        half = 0.5 * math.sqrt(t2)
        b = (1.0 - half * math.cos(half) / math.sin(half)) / t2
    tv0, tv1, tv2 = y * v[2] - z * v[1], z * v[0] - x * v[2], x * v[1] - y * v[0]  # T v
    ttv0, ttv1, ttv2 = y * tv2 - z * tv1, z * tv0 - x * tv2, x * tv1 - y * tv0  # T T v
    out = np.empty(3)
    out[0], out[1], out[2] = v[0] - 0.5 * tv0 + b * ttv0, v[1] - 0.5 * tv1 + b * ttv1, v[2] - 0.5 * tv2 + b * ttv2
    return out


@jit
def align(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotation taking the unit vector a to the unit vector b (a . b > -1):
    E + v~ + v~^2 / (1 + a . b), v = a x b; (3,), (3,) -> (3, 3)."""
    v = cross(a, b)
    vv = skew(v)
    return np.eye(3) + vv + matmul(vv, vv) / (1.0 + dot(a, b))


@jit
def quaternion_to_matrix(e: np.ndarray) -> np.ndarray:
    """Rotation matrix of the (normalised on the fly) quaternion e = [e0, e1, e2, e3]."""
    norm = math.sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2] + e[3] * e[3])
    e0, e1, e2, e3 = e[0] / norm, e[1] / norm, e[2] / norm, e[3] / norm
    return np.array(
        [
            [1 - 2 * (e2 * e2 + e3 * e3), 2 * (e1 * e2 - e0 * e3), 2 * (e1 * e3 + e0 * e2)],
            [2 * (e1 * e2 + e0 * e3), 1 - 2 * (e1 * e1 + e3 * e3), 2 * (e2 * e3 - e0 * e1)],
            [2 * (e1 * e3 - e0 * e2), 2 * (e2 * e3 + e0 * e1), 1 - 2 * (e1 * e1 + e2 * e2)],
        ]
    )


def matrix_to_quaternion(rot: np.ndarray) -> np.ndarray:
    """Unit quaternion [e0, e1, e2, e3] (e0 >= 0) of a rotation matrix (Shepperd's method)."""
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


@jit
def quaternion_rate(e: np.ndarray, omega_body: np.ndarray) -> np.ndarray:
    """de/dt = 0.5 e (x) [0, omega] for body-frame angular velocity omega (e normalised)."""
    norm = math.sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2] + e[3] * e[3])
    e0, e1, e2, e3 = e[0] / norm, e[1] / norm, e[2] / norm, e[3] / norm
    w1, w2, w3 = omega_body[0], omega_body[1], omega_body[2]
    return 0.5 * np.array(
        [
            -e1 * w1 - e2 * w2 - e3 * w3,
            e0 * w1 + e2 * w3 - e3 * w2,
            e0 * w2 - e1 * w3 + e3 * w1,
            e0 * w3 + e1 * w2 - e2 * w1,
        ]
    )


def as_rotation(value) -> np.ndarray:
    """A rotation matrix (3, 3) from None (identity), a (3, 3) matrix or a rotation vector (3,), rad."""
    if value is None:
        return np.eye(3)
    a = np.asarray(value, dtype=float)
    if a.shape == (3, 3):
        return a
    if a.shape == (3,):
        return exp_so3(a)
    raise ValueError(f"rotation must be a 3x3 matrix or a rotation vector, got shape {a.shape}")
