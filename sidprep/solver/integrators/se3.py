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

and the pose moves by the SE(3) exponential of the increment (rho, theta) (base.advance_pose
with body_frame, rotations.se3_jacobian; its inverse rotations.se3_jacobian_solve):

    r <- r + A V(theta) rho,   A <- A exp(theta~),   V = E + (1 - cos t)/t^2 theta~ + (t - sin t)/t^3 theta~^2

(t = |theta|).  The stepper keeps u, ud and its pseudo-accelerations in these coordinates and
hands out inertial ones (samples, state).
"""

from __future__ import annotations

import numpy as np

from sidprep.solver.equations.assemble import load_stiffened
from sidprep.solver.equations.rotations import SMALL_ANGLE, jit, matmul, put, se3_jacobian_solve, tmatvec

@jit
def rotate_translations(L, A, u, inverse):  # pragma: no cover - compiled
    """u_O = S u_K (inverse False) or u_K = S^T u_O (inverse True), (n,) (in scalars: one
    array per call, this runs at every Newton iteration)."""
    out = u.copy()
    for b in range(A.shape[0]):
        s = L.uoff[b]
        v0, v1, v2 = u[s], u[s + 1], u[s + 2]
        for i in range(3):
            acc = 0.0
            if inverse:
                acc += A[b, 0, i] * v0
                acc += A[b, 1, i] * v1
                acc += A[b, 2, i] * v2
            else:
                acc += A[b, i, 0] * v0
                acc += A[b, i, 1] * v1
                acc += A[b, i, 2] * v2
            out[s + i] = acc
    return out


@jit
def inertial_velocities(L, A, u_K):  # pragma: no cover - compiled
    """u_O = S u_K (n,)."""
    return rotate_translations(L, A, u_K, False)


@jit
def body_velocities(L, A, u_O):  # pragma: no cover - compiled
    """u_K = S^T u_O (n,)."""
    return rotate_translations(L, A, u_O, True)


@jit
def convective(L, A, u_K):  # pragma: no cover - compiled
    """c = dS/dt u_K (n,): A (omega x v_K) on each body's translational rows (in scalars)."""
    c = np.zeros(u_K.shape[0])
    for b in range(A.shape[0]):
        s = L.uoff[b]
        w0, w1, w2, v0, v1, v2 = u_K[s + 3], u_K[s + 4], u_K[s + 5], u_K[s], u_K[s + 1], u_K[s + 2]
        x0, x1, x2 = w1 * v2 - w2 * v1, w2 * v0 - w0 * v2, w0 * v1 - w1 * v0
        for i in range(3):
            acc = 0.0
            acc += A[b, i, 0] * x0
            acc += A[b, i, 1] * x1
            acc += A[b, i, 2] * x2
            c[s + i] = acc
    return c


@jit
def inertial_accelerations(L, A, u_K, ud_K):  # pragma: no cover - compiled
    """ud_O = S ud_K + c (n,)."""
    return inertial_velocities(L, A, ud_K) + convective(L, A, u_K)


@jit
def body_accelerations(L, A, u_K, ud_O):  # pragma: no cover - compiled
    """ud_K = S^T (ud_O - c) (n,)."""
    return body_velocities(L, A, ud_O - convective(L, A, u_K))


@jit
def right_multiply(X, L, A):  # pragma: no cover - compiled
    """X S in place (X (k, n)): body b's translational columns times A_b (in scalars: no
    temporaries, this runs at every Newton iteration)."""
    for b in range(A.shape[0]):
        s = L.uoff[b]
        for r in range(X.shape[0]):
            x0, x1, x2 = X[r, s], X[r, s + 1], X[r, s + 2]
            for i in range(3):
                acc = 0.0
                acc += A[b, 0, i] * x0
                acc += A[b, 1, i] * x1
                acc += A[b, 2, i] * x2
                X[r, s + i] = acc


@jit
def left_multiply(X, L, A):  # pragma: no cover - compiled
    """S^T X in place (X (n, k)): body b's translational rows times A_b^T (in scalars)."""
    for b in range(A.shape[0]):
        s = L.uoff[b]
        for col in range(X.shape[1]):
            x0, x1, x2 = X[s, col], X[s + 1, col], X[s + 2, col]
            for i in range(3):
                acc = 0.0
                acc += A[b, 0, i] * x0
                acc += A[b, 1, i] * x1
                acc += A[b, 2, i] * x2
                X[s + i, col] = acc


@jit
def to_body_frame(L, A, u_K, e):  # pragma: no cover - compiled
    """The Evaluation e (assemble.evaluate_into, at the inertial velocities S u_K) turned in
    place into the coordinates of this module (module doc): M -> S^T M S, f -> S^T (f - M c),
    B -> B S, B_F -> B_F S; the rest as evaluate_into gives it.  (The callers evaluate
    themselves: every compiled function that calls evaluate_into compiles its whole call tree
    once more; docs/performance.md.)"""
    M, f = e.M, e.f
    c = convective(L, A, u_K)
    for i in range(f.shape[0]):
        acc = 0.0
        for j in range(M.shape[1]):
            acc += M[i, j] * c[j]
        f[i] = f[i] - acc
    left_multiply(f.reshape((-1, 1)), L, A)
    right_multiply(M, L, A)
    left_multiply(M, L, A)
    right_multiply(e.B, L, A)
    if load_stiffened(L.mk_k0):  # B_F is B itself otherwise
        right_multiply(e.BF, L, A)


@jit
def body_increment(L, R0, A0, R1, A1, Q0, Q1):  # pragma: no cover - compiled
    """The increment dx (n,) = [rho, theta, dq] per body with R1, A1, Q1 = the pose R0, A0, Q0
    moved by dx (base.advance_pose with body_frame): theta = log(A0^T A1),
    rho = V(theta)^-1 A0^T (R1 - R0)."""
    n = L.uoff[-1]
    dx = np.empty(n)
    for i in range(R0.shape[0]):
        s = L.uoff[i]
        rot = matmul(A0[i].T, A1[i])
        angle = np.arccos(min(1.0, max(-1.0, 0.5 * (rot[0, 0] + rot[1, 1] + rot[2, 2] - 1.0))))
        scale = 0.5 if angle < SMALL_ANGLE else 0.5 * angle / np.sin(angle)
        theta = np.array([scale * (rot[2, 1] - rot[1, 2]), scale * (rot[0, 2] - rot[2, 0]),
                          scale * (rot[1, 0] - rot[0, 1])])
        put(dx, s + 3, theta)
        put(dx, s, se3_jacobian_solve(theta, tmatvec(A0[i], R1[i] - R0[i])))
        for k in range(L.qoff[i + 1] - L.qoff[i]):
            dx[s + 6 + k] = Q1[L.qoff[i] + k] - Q0[L.qoff[i] + k]
    return dx


def body_frame_free(free: np.ndarray, uoff: np.ndarray) -> np.ndarray:
    """The integrated coordinates in body-frame velocities: in a planar run (one free rotation
    axis k per body, the plane normal) the free translations are the K components other than k;
    otherwise ``free`` unchanged."""
    keep = set(int(i) for i in free)
    out = []
    for b in range(len(uoff) - 1):
        s, e = int(uoff[b]), int(uoff[b + 1])
        rot = [a for a in range(3) if s + 3 + a in keep]
        trans = [a for a in range(3) if a not in rot] if len(rot) == 1 else [a for a in range(3) if s + a in keep]
        out += [s + a for a in trans] + [s + 3 + a for a in rot] + [i for i in range(s + 6, e) if i in keep]
    return np.array(sorted(out), dtype=free.dtype)
