"""Marker kinematics, joint constraint rows and joint coordinates, compiled (model/joints.py
describes the rows; the module docstring there gives the two primitives).

Marker on body (r, A, q) at c with orientation AP0 and node shapes Phi, Psi (sid-spec 5.2):

    d = c + Phi q,   p = r + A d,   A_m = A R(Psi q) AP0,
    JT = [E, -A d~, A Phi],   JR = [0, A, A Psi]     (v_m = JT u, omega_m = JR u, inertial)

With load stiffening the force Jacobians use Phi(q) = Phi + K0F q, Psi(q) = Psi + K0M q.
"""

from __future__ import annotations

import numpy as np

from sidprep.solver.equations.rotations import cross, dot, exp_so3, jit, put

#: joint coordinate kinds (layout.py)
NO_COORDINATE, ANGLE, SLIDE = 0, 1, 2


@jit
def marker_jacobians(A, d, phi, psi, jt, jr):  # pragma: no cover - compiled
    """JT = [E, -A d~, A Phi], JR = [0, A, A Psi] (module doc) written into the first 6 + nq
    columns of jt, jr (3, >= 6+nq), in scalars (no temporaries: this runs for every marker at
    every evaluation)."""
    nq = phi.shape[1]
    for a in range(3):  # -A d~ (d~ x = d x x): column b of A d~ is A (d x e_b)
        jt[a, 3] = -(A[a, 1] * d[2] - A[a, 2] * d[1])
        jt[a, 4] = -(A[a, 2] * d[0] - A[a, 0] * d[2])
        jt[a, 5] = -(A[a, 0] * d[1] - A[a, 1] * d[0])
        for b in range(3):
            jt[a, b] = 1.0 if a == b else 0.0
            jr[a, b] = 0.0
            jr[a, 3 + b] = A[a, b]
        for k in range(nq):
            st = 0.0
            sr = 0.0
            for b in range(3):
                st += A[a, b] * phi[b, k]
                sr += A[a, b] * psi[b, k]
            jt[a, 6 + k] = st
            jr[a, 6 + k] = sr


@jit
def marker_pose(r, A, q, position, rotation, phi, psi, p, rot, d):  # pragma: no cover - compiled
    """p (3,), A_m (3, 3) and d (3,) of a marker (module doc), written into p, rot, d (in
    scalars: this runs for every marker at every evaluation)."""
    nq = q.shape[0]
    rv = np.zeros(3)
    for a in range(3):
        da = position[a]
        for k in range(nq):
            da += phi[a, k] * q[k]
            rv[a] += psi[a, k] * q[k]
        d[a] = da
    e = exp_so3(rv)
    for a in range(3):  # row a of (A exp(rv~)) rotation
        t0, t1, t2 = 0.0, 0.0, 0.0
        for j in range(3):
            t0 += A[a, j] * e[j, 0]
            t1 += A[a, j] * e[j, 1]
            t2 += A[a, j] * e[j, 2]
        for k in range(3):
            acc = 0.0
            acc += t0 * rotation[0, k]
            acc += t1 * rotation[1, k]
            acc += t2 * rotation[2, k]
            rot[a, k] = acc
    for a in range(3):
        pa = r[a]
        for b in range(3):
            pa += A[a, b] * d[b]
        p[a] = pa


@jit
def marker_kinematics(r, A, q, position, rotation, phi, psi):  # pragma: no cover - compiled
    """p (3,), A_m (3, 3), JT (3, 6+nq), JR (3, 6+nq), d (3,) of a marker (module doc)."""
    p, rot, d = np.empty(3), np.empty((3, 3)), np.empty(3)
    marker_pose(r, A, q, position, rotation, phi, psi, p, rot, d)
    jt = np.empty((3, 6 + q.shape[0]))
    jr = np.empty((3, 6 + q.shape[0]))
    marker_jacobians(A, d, phi, psi, jt, jr)
    return p, rot, jt, jr, d


@jit
def stiffened_jacobian(jac, A, q, k0):  # pragma: no cover - compiled
    """jac with the modal columns of A (K0 q) added: K0 (3, nq, nq) [a, j, k] (phi.M1)."""
    out = jac.copy()
    nq = q.shape[0]
    for a in range(3):
        for k in range(nq):
            s = 0.0
            for b in range(3):
                for j in range(nq):
                    s += A[a, b] * k0[b, j, k] * q[j]
            out[a, 6 + k] += s
    return out


@jit
def joint_rows(rows, p1, a1, p2, a2, g, c, r0):  # pragma: no cover - compiled
    """Rows (kind, axis 1, axis 2) -> g[r0 + r] and c[r0 + r] (4, 3) = (cT1, cR1, cT2, cR2)
    (model/joints.py: position along an axis of marker 1, perpendicularity of two axes);
    written in place, in scalars (no temporaries: this runs at every evaluation)."""
    d0, d1, d2 = p2[0] - p1[0], p2[1] - p1[1], p2[2] - p1[2]
    for r in range(rows.shape[0]):
        k = rows[r, 1]
        e0, e1, e2 = a1[0, k], a1[1, k], a1[2, k]
        cr = c[r0 + r]
        if rows[r, 0] == 0:
            g[r0 + r] = e0 * d0 + e1 * d1 + e2 * d2
            cr[0, 0], cr[0, 1], cr[0, 2] = -e0, -e1, -e2
            cr[1, 0], cr[1, 1], cr[1, 2] = e1 * d2 - e2 * d1, e2 * d0 - e0 * d2, e0 * d1 - e1 * d0
            cr[2, 0], cr[2, 1], cr[2, 2] = e0, e1, e2
        else:
            kb = rows[r, 2]
            b0, b1, b2 = a2[0, kb], a2[1, kb], a2[2, kb]
            g[r0 + r] = e0 * b0 + e1 * b1 + e2 * b2
            x0, x1, x2 = e1 * b2 - e2 * b1, e2 * b0 - e0 * b2, e0 * b1 - e1 * b0
            cr[1, 0], cr[1, 1], cr[1, 2] = x0, x1, x2
            cr[3, 0], cr[3, 1], cr[3, 2] = -x0, -x1, -x2


@jit
def unwrap(raw, ref):  # pragma: no cover - compiled
    """The angle equal to raw modulo 2 pi closest to ref."""
    return ref + (raw - ref + np.pi) % (2 * np.pi) - np.pi


@jit
def joint_coordinate(kind, p1, a1, p2, a2, ref):  # pragma: no cover - compiled
    """Joint coordinate value and its velocity row c (4, 3) = (cT1, cR1, cT2, cR2).

    ANGLE: rotation of x2 about z1 from x1, unwrapped against ref; SLIDE: z1 . (p2 - p1).
    """
    z = a1[:, 2].copy()
    c = np.zeros((4, 3))
    if kind == ANGLE:
        raw = np.arctan2(dot(a1[:, 1], a2[:, 0]), dot(a1[:, 0], a2[:, 0]))
        put(c[1], 0, z, -1.0)
        put(c[3], 0, z)
        return unwrap(raw, ref), c
    d = p2 - p1
    put(c[0], 0, z, -1.0)
    put(c[1], 0, cross(z, d))
    put(c[2], 0, z)
    return dot(z, d), c
