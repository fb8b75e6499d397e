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

import numpy as np

from sidprep.solver.equations.body import DE, F_DAMPING, body_equations, body_potentials
from sidprep.solver.equations.constraints import (NO_COORDINATE, joint_coordinate, joint_rows, marker_kinematics,
                                                  stiffened_jacobian)
from sidprep.solver.equations.curves import motion_state
from sidprep.solver.equations.forces import curve_arrays, force_elements
from sidprep.solver.equations.rotations import add, dot, jit, matmul, matvec, put, put2, tmatvec


@jit
def body_state(L, i, Q, u):  # pragma: no cover - compiled
    """(q, qd, omega) of body i."""
    q = Q[L.qoff[i]:L.qoff[i + 1]].copy()
    s = L.uoff[i]
    return q, u[s + 6:L.uoff[i + 1]].copy(), u[s + 3:s + 6].copy()


@jit
def marker_state(L, k, R, A, Q):  # pragma: no cover - compiled
    """p (3,), A_m (3, 3), JT, JR (3, 6+nq) of marker k (empty Jacobians on the ground)."""
    b = L.mk_body[k]
    if b < 0:
        e = np.zeros((3, 0))
        return L.mk_pos[k].copy(), L.mk_rot[k].copy(), e, e
    nq = L.qoff[b + 1] - L.qoff[b]
    o = L.mk_shape[k]
    phi = L.shapes[o:o + 3 * nq].reshape((3, nq))
    psi = L.shapes[o + 3 * nq:o + 6 * nq].reshape((3, nq))
    p, rot, jt, jr, _ = marker_kinematics(R[b], A[b], Q[L.qoff[b]:L.qoff[b + 1]].copy(), L.mk_pos[k],
                                          L.mk_rot[k], phi, psi)
    return p, rot, jt, jr


@jit
def force_jacobians(L, k, A, Q, jt, jr):  # pragma: no cover - compiled
    """The marker Jacobians for loads: with the K0F / K0M parts when the body is stiffened."""
    b = L.mk_body[k]
    if b < 0 or (L.mk_k0[k, 0] < 0 and L.mk_k0[k, 1] < 0):
        return jt, jr
    nq = L.qoff[b + 1] - L.qoff[b]
    q = Q[L.qoff[b]:L.qoff[b + 1]].copy()
    if L.mk_k0[k, 0] >= 0:
        o = L.mk_k0[k, 0]
        jt = stiffened_jacobian(jt, A[b], q, L.shapes[o:o + 3 * nq * nq].reshape((3, nq, nq)))
    if L.mk_k0[k, 1] >= 0:
        o = L.mk_k0[k, 1]
        jr = stiffened_jacobian(jr, A[b], q, L.shapes[o:o + 3 * nq * nq].reshape((3, nq, nq)))
    return jt, jr


@jit
def add_rows(B, r, col, c, jt, jr, which, w):  # pragma: no cover - compiled
    """B[r, col:col+width] += cT JT + cR JR for marker ``which`` (0: marker 1, 1: marker 2) of
    the row coefficients c (4, 3)."""
    for a in range(3):
        for k in range(w):
            B[r, col + k] += c[2 * which, a] * jt[a, k] + c[2 * which + 1, a] * jr[a, k]


@jit
def width(L, b):  # pragma: no cover - compiled
    """Number of velocity coordinates of body b (0 for the ground, b < 0)."""
    return 0 if b < 0 else L.uoff[b + 1] - L.uoff[b]


@jit
def markers(L, R, A, Q, u):  # pragma: no cover - compiled
    """Kinematics of every marker: P (nmk, 3), AM (nmk, 3, 3), VEL, OMG (nmk, 3) inertial, and
    the Jacobians JT, JR and the load Jacobians JTF, JRF (nmk, 3, w_max), zero-padded."""
    nmk = L.mk_body.shape[0]
    wmax = 0
    for b in range(R.shape[0]):
        wmax = max(wmax, width(L, b))
    P = np.zeros((nmk, 3))
    AM = np.zeros((nmk, 3, 3))
    VEL = np.zeros((nmk, 3))
    OMG = np.zeros((nmk, 3))
    JT = np.zeros((nmk, 3, wmax))
    JR = np.zeros((nmk, 3, wmax))
    JTF = np.zeros((nmk, 3, wmax))
    JRF = np.zeros((nmk, 3, wmax))
    for k in range(nmk):
        p, rot, jt, jr = marker_state(L, k, R, A, Q)
        put(P[k], 0, p)
        put2(AM[k], 0, 0, rot)
        b = L.mk_body[k]
        if b < 0:
            continue
        ub = u[L.uoff[b]:L.uoff[b + 1]]
        put(VEL[k], 0, matvec(jt, ub))
        put(OMG[k], 0, matvec(jr, ub))
        jtf, jrf = force_jacobians(L, k, A, Q, jt, jr)
        put2(JT[k], 0, 0, jt)
        put2(JR[k], 0, 0, jr)
        put2(JTF[k], 0, 0, jtf)
        put2(JRF[k], 0, 0, jrf)
    return P, AM, VEL, OMG, JT, JR, JTF, JRF


@jit
def evaluate(L, R, A, Q, u, t, lam, refs):  # pragma: no cover - compiled
    """The system at a state (module doc).

    R (nb, 3), A (nb, 3, 3), Q (sum nq,), u (n,), t s, lam (m,) multipliers of all rows
    (friction), refs (nj,) angle-unwrapping references.  Returns M (n, n), f (n,), g (m,),
    B (m, n), B_F (m, n), b_t (m,), C (m, 4, 3) the rows' marker coefficients (cT1, cR1, cT2,
    cR2), coords (nj, 2) joint coordinates and rates, loads (nmk, 6) applied marker loads
    (inertial) and flows (4,) = [power in by loads, power dissipated, spring energy, driver
    power in].
    """
    nb = R.shape[0]
    n = u.shape[0]
    M = np.zeros((n, n))
    f = np.zeros(n)
    for i in range(nb):
        q, qd, w = body_state(L, i, Q, u)
        gk = tmatvec(A[i], L.gravity)
        mk, h = body_equations(L.body_F, L.body_off[i], L.body_flags[i], L.body_mass[i], q, qd, w, gk)
        s = L.uoff[i]
        top = matmul(A[i], mk[:3, 3:])
        put2(mk, 0, 3, top)
        put2(mk, 3, 0, top.T)
        put2(M, s, s, mk)
        add(f, s, matvec(A[i], h[:3]))
        add(f, s + 3, h[3:])
    P, AM, VEL, OMG, JT, JR, JTF, JRF = markers(L, R, A, Q, u)
    nmk = P.shape[0]
    nj = L.joint_mk.shape[0]
    coords = np.zeros((nj, 2))
    crows = np.zeros((nj, 4, 3))
    for j in range(nj):
        if L.joint_kind[j] != NO_COORDINATE:
            k1, k2 = L.joint_mk[j, 0], L.joint_mk[j, 1]
            value, c = joint_coordinate(L.joint_kind[j], P[k1], AM[k1], P[k2], AM[k2], refs[j])
            coords[j, 0] = value
            coords[j, 1] = dot(c[0], VEL[k1]) + dot(c[1], OMG[k1]) + dot(c[2], VEL[k2]) + dot(c[3], OMG[k2])
            put2(crows[j], 0, 0, c)
    loads = np.zeros((nmk, 6))
    flows = np.zeros(4)
    force_elements(L, t, P, AM, VEL, OMG, coords, crows, lam, loads, flows)
    for i in range(nb):
        if L.body_flags[i, F_DAMPING]:  # modal damping dissipates qd^T De qd
            q, qd, w = body_state(L, i, Q, u)
            nq = qd.shape[0]
            o = L.body_off[i, DE]
            flows[1] += dot(qd, matvec(L.body_F[o:o + nq * nq].reshape((nq, nq)), qd))
    for k in range(nmk):
        b = L.mk_body[k]
        if b >= 0:
            w = width(L, b)
            add(f, L.uoff[b], tmatvec(JTF[k, :, :w], loads[k, 0:3]))
            add(f, L.uoff[b], tmatvec(JRF[k, :, :w], loads[k, 3:6]))
    nrj = L.joint_off[-1]
    m_all = nrj + L.drv_joint.shape[0]
    g = np.zeros(m_all)
    bt = np.zeros(m_all)
    B = np.zeros((m_all, n))
    BF = np.zeros((m_all, n))
    C = np.zeros((m_all, 4, 3))
    for j in range(nj):
        k1, k2 = L.joint_mk[j, 0], L.joint_mk[j, 1]
        r0, r1 = L.joint_off[j], L.joint_off[j + 1]
        gj, cj = joint_rows(L.jrows[r0:r1], P[k1], AM[k1], P[k2], AM[k2])
        put(g, r0, gj)
        for r in range(r1 - r0):
            put2(C[r0 + r], 0, 0, cj[r])
    for d in range(L.drv_joint.shape[0]):
        j = L.drv_joint[d]
        if L.drv_curve[d] >= 0:
            cx, cc = curve_arrays(L, L.drv_curve[d])
        else:
            cx, cc = np.zeros(2), np.zeros((1, 1))
        value, rate, _ = motion_state(L.drv_kind[d], L.drv_par[d], cx, cc, t)
        g[nrj + d] = coords[j, 0] - value
        bt[nrj + d] = -rate
        put2(C[nrj + d], 0, 0, crows[j])
        flows[3] -= lam[nrj + d] * coords[j, 1]
    for r in range(m_all):
        j = L.drv_joint[r - nrj] if r >= nrj else row_joint(L, r)
        for which in range(2):
            k = L.joint_mk[j, which]
            b = L.mk_body[k]
            if b >= 0:
                w = width(L, b)
                add_rows(B, r, L.uoff[b], C[r], JT[k], JR[k], which, w)
                add_rows(BF, r, L.uoff[b], C[r], JTF[k], JRF[k], which, w)
    return M, f, g, B, BF, bt, C, coords, loads, flows


@jit
def row_joint(L, r):  # pragma: no cover - compiled
    """The joint owning joint row r."""
    j = 0
    while L.joint_off[j + 1] <= r:
        j += 1
    return j


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
