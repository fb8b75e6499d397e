"""The FFR equations of one body (sid-spec 5.2), compiled: the one implementation.

For the accelerations [a_O (K), omega_dot, q_ddot] of a body with velocities [v_O, omega
(K), qd] the equations in the body frame K are

    M_K(q) du = h_K(q, qd, omega) + (gravity) + (applied loads),
    h_K = -k_omega - k_e          (sid-spec 5.2; k_e = Ke q + Ge(omega) qd + Oe(q) omega_hat
                                    + ksigma(q) + De qd)

with M_K = [[m E, md~^T, Ct^T], [md~, I, Cr^T], [Ct, Cr, Me]], md(q) = md0 + md1 q,
I(q) = I0 + I1 q (+ I2(q, q)), Ct(q) = Ct0 + Ct1 q, Cr(q) = Cr0 + Cr1 q.  Gravity is the
gradient of the potential V = -g.(m r_O + A md_g(q)) - 1/2 q^T (Ct1 . g_K) q with
md_g = md0 + Ct0^T q (sid-spec 5.2: the modal force Ct g_K), so that energy is conserved
whichever effects are switched on.

The body's SID arrays live in one flat float array F at the offsets ``off`` (see layout.py,
``pack_terms``); absent terms have offset -1 and a zero flag.
"""

from __future__ import annotations

import numpy as np

from sidprep.solver.equations.rotations import add, cross, dot, jit, matvec, put, put2, tmatvec

# offsets table columns (layout.pack_terms): where each term of BodyTerms starts in F
MD0, I0, ME, KE, MD1, I1, CT0, CT1, CR0, CR1, GR0, GE, OE0, OE1, KS0, KS1, DE, P2 = range(18)
N_TERMS = 18
# flags table columns: term switched on
F_INERTIA, F_CT1, F_CR1, F_CORIOLIS, F_OE0, F_OE1, F_PRELOAD, F_DAMPING, F_GRAVITY, F_SECOND = range(10)
N_FLAGS = 10


@jit
def block(F, o, rows, cols):  # pragma: no cover - compiled
    """The (rows, cols) array stored row-major in F from offset o."""
    return F[o:o + rows * cols].reshape((rows, cols))


@jit
def add_first_order(x, x1f, q):  # pragma: no cover - compiled
    """x[k, a] += sum_j q_j X1[k, j, a] for a first-order term stored as X1f[j, 3k + a]."""
    nq = q.shape[0]
    for j in range(nq):
        for k in range(nq):
            for a in range(3):
                x[k, a] += q[j] * x1f[j, 3 * k + a]


@jit
def pair_contraction(p, x, y):  # pragma: no cover - compiled
    """(3, 3) sum_jk P[a, b, j, k] x_j y_k of the mode-pair integrals stored as P[3a+b, j nq + k]."""
    nq = x.shape[0]
    out = np.zeros((3, 3))
    for a in range(3):
        for b in range(3):
            acc = 0.0
            for j in range(nq):
                for k in range(nq):
                    acc += p[3 * a + b, j * nq + k] * x[j] * y[k]
            out[a, b] = acc
    return out


@jit
def inertia_terms(F, off, flags, nq, q):  # pragma: no cover - compiled
    """md (3,), I (3, 3), Ct (nq, 3), Cr (nq, 3) at q (sid-spec 5.2)."""
    md = F[off[MD0]:off[MD0] + 3].copy()
    inertia = block(F, off[I0], 3, 3).copy()
    ct = block(F, off[CT0], nq, 3).copy()
    cr = block(F, off[CR0], nq, 3).copy()
    if flags[F_INERTIA]:
        md1, i1 = block(F, off[MD1], nq, 3), block(F, off[I1], nq, 9)
        for j in range(nq):
            for a in range(3):
                md[a] += q[j] * md1[j, a]
                for b in range(3):
                    inertia[a, b] += q[j] * i1[j, 3 * a + b]
    if flags[F_CT1]:
        add_first_order(ct, block(F, off[CT1], nq, 3 * nq), q)
    if flags[F_CR1]:
        add_first_order(cr, block(F, off[CR1], nq, 3 * nq), q)
    if flags[F_SECOND]:  # I2 = tr(Pqq) E - Pqq (sid-spec 3.8)
        pqq = pair_contraction(block(F, off[P2], 9, nq * nq), q, q)
        tr = pqq[0, 0] + pqq[1, 1] + pqq[2, 2]
        for a in range(3):
            inertia[a, a] += tr
            for b in range(3):
                inertia[a, b] -= pqq[a, b]
    return md, inertia, ct, cr


@jit
def body_equations(F, off, flags, mass, q, qd, w, gk):  # pragma: no cover - compiled
    """M_K (6+nq, 6+nq) and h_K (6+nq,) of sid-spec 5.2 with gravity g_K (K components)."""
    nq = q.shape[0]
    n = 6 + nq
    md, inertia, ct, cr = inertia_terms(F, off, flags, nq, q)
    m = np.zeros((n, n))
    for a in range(3):
        m[a, a] = mass
        for b in range(3):
            m[3 + a, 3 + b] = inertia[a, b]
    m[3, 1], m[3, 2], m[4, 0], m[4, 2], m[5, 0], m[5, 1] = -md[2], md[1], md[2], -md[0], -md[1], md[0]
    for a in range(3):
        for b in range(3):
            m[a, 3 + b] = m[3 + b, a]
    for k in range(nq):
        for a in range(3):
            m[6 + k, a] = ct[k, a]
            m[a, 6 + k] = ct[k, a]
            m[6 + k, 3 + a] = cr[k, a]
            m[3 + a, 6 + k] = cr[k, a]
    me = block(F, off[ME], nq, nq)
    ke = block(F, off[KE], nq, nq)
    put2(m, 6, 6, me)
    h = np.zeros(n)
    c0, c1, c2 = w[1] * md[2] - w[2] * md[1], w[2] * md[0] - w[0] * md[2], w[0] * md[1] - w[1] * md[0]  # w x md
    h[0], h[1], h[2] = -(w[1] * c2 - w[2] * c1), -(w[2] * c0 - w[0] * c2), -(w[0] * c1 - w[1] * c0)
    i0, i1, i2 = 0.0, 0.0, 0.0  # I w
    for b in range(3):
        i0 += inertia[0, b] * w[b]
        i1 += inertia[1, b] * w[b]
        i2 += inertia[2, b] * w[b]
    h[3], h[4], h[5] = -(w[1] * i2 - w[2] * i1), -(w[2] * i0 - w[0] * i2), -(w[0] * i1 - w[1] * i0)
    wh = np.array([w[0] * w[0], w[1] * w[1], w[2] * w[2], w[0] * w[1], w[1] * w[2], w[0] * w[2]]) if (
        flags[F_OE0] or flags[F_OE1]) else np.zeros(0)
    if flags[F_CORIOLIS]:
        ctq = np.zeros(3)
        g = np.zeros((3, 3))
        gr0 = block(F, off[GR0], nq, 9)
        for k in range(nq):
            for a in range(3):
                ctq[a] += ct[k, a] * qd[k]
                for b in range(3):
                    g[a, b] += qd[k] * gr0[k, 3 * a + b]
        add(h, 0, cross(w, ctq), -2.0)
        add(h, 3, matvec(g, w), -1.0)
        ge = block(F, off[GE], 3, nq * nq)
        for k in range(nq):
            for j in range(nq):
                for a in range(3):
                    h[6 + k] -= w[a] * ge[a, k * nq + j] * qd[j]
    if flags[F_SECOND]:  # Gr1 part of Gr(q, qd): r[i, a] = sum_kj P[i, a, k, j] qd_k q_j (sid-spec 3.8)
        r = pair_contraction(block(F, off[P2], 9, nq * nq), qd, q)
        tr = r[0, 0] + r[1, 1] + r[2, 2]
        rw = matvec(r, w)
        for a in range(3):
            h[3 + a] -= 2.0 * (tr * w[a] - rw[a])
    for k in range(nq):
        for j in range(nq):
            h[6 + k] -= ke[k, j] * q[j]
    if flags[F_OE0]:
        oe0 = block(F, off[OE0], nq, 6)
        for k in range(nq):
            for i in range(6):
                h[6 + k] -= oe0[k, i] * wh[i]
    if flags[F_OE1]:
        oe1 = block(F, off[OE1], nq, 6 * nq)
        for j in range(nq):
            for k in range(nq):
                for i in range(6):
                    h[6 + k] -= q[j] * oe1[j, 6 * k + i] * wh[i]
    if flags[F_PRELOAD]:
        ks0 = F[off[KS0]:off[KS0] + nq]
        ks1 = block(F, off[KS1], nq, nq)
        for k in range(nq):
            h[6 + k] -= ks0[k]
            for j in range(nq):
                h[6 + k] -= ks1[k, j] * q[j]
    if flags[F_DAMPING]:
        de = block(F, off[DE], nq, nq)
        for k in range(nq):
            for j in range(nq):
                h[6 + k] -= de[k, j] * qd[j]
    if flags[F_GRAVITY]:
        add(h, 0, gravity_force(F, off, flags, mass, q, gk))
    return m, h


@jit
def gravity_md(F, off, nq, q):  # pragma: no cover - compiled
    """md_g(q) = md0 + Ct0^T q (kg m): the first mass moment seen by gravity."""
    md = F[off[MD0]:off[MD0] + 3].copy()
    ct0 = block(F, off[CT0], nq, 3)
    for k in range(nq):
        for a in range(3):
            md[a] += ct0[k, a] * q[k]
    return md


@jit
def gravity_force(F, off, flags, mass, q, gk):  # pragma: no cover - compiled
    """-dV/d(coordinates) of the gravity potential (module doc), (6+nq,), K components."""
    nq = q.shape[0]
    out = np.zeros(6 + nq)
    md = gravity_md(F, off, nq, q)
    for a in range(3):
        out[a] = mass * gk[a]
    put(out, 3, cross(md, gk))
    ct0 = block(F, off[CT0], nq, 3)
    for k in range(nq):
        for a in range(3):
            out[6 + k] += ct0[k, a] * gk[a]
    if flags[F_CT1]:
        ct1 = block(F, off[CT1], nq, 3 * nq)
        for j in range(nq):
            for k in range(nq):
                s = 0.0
                for a in range(3):
                    s += 0.5 * (ct1[j, 3 * k + a] + ct1[k, 3 * j + a]) * gk[a]
                out[6 + k] += s * q[j]
    return out


@jit
def body_potentials(F, off, flags, mass, r, A, q, g):  # pragma: no cover - compiled
    """(strain energy, gravity potential) of one body, J; r (3,), A (3, 3), g (3,) inertial."""
    nq = q.shape[0]
    ke = block(F, off[KE], nq, nq)
    strain = 0.5 * dot(q, matvec(ke, q))
    if flags[F_PRELOAD]:
        strain += dot(F[off[KS0]:off[KS0] + nq], q) + 0.5 * dot(q, matvec(block(F, off[KS1], nq, nq), q))
    grav = 0.0
    if flags[F_GRAVITY]:
        md = gravity_md(F, off, nq, q)
        grav = -(mass * dot(g, r) + dot(g, matvec(A, md)))
        if flags[F_CT1]:
            gk = tmatvec(A, g)
            ct1 = block(F, off[CT1], nq, 3 * nq)
            for j in range(nq):
                for k in range(nq):
                    for a in range(3):
                        grav -= 0.5 * q[k] * ct1[j, 3 * k + a] * gk[a] * q[j]
    return strain, grav
