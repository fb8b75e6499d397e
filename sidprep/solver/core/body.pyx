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

The body's SID arrays live in one flat float array F at the offsets ``off`` (see
compile/layout.py, ``pack_terms``); absent terms have offset -1 and a zero flag.
"""

import numpy as np

from sidprep.solver.core.rotations cimport cross3, dot3, matvec3, tmatvec3


cdef void add_first_order(double* x, Py_ssize_t ld, const double* x1f, const double* q, Py_ssize_t nq) noexcept nogil:
    """x[k, a] += sum_j q_j X1[k, j, a] for a first-order term stored as X1f[j, 3k + a] (nq, 3 nq);
    x (nq, 3) with rows ld apart."""
    cdef Py_ssize_t j, k, a
    for j in range(nq):
        for k in range(nq):
            for a in range(3):
                x[k * ld + a] += q[j] * x1f[j * 3 * nq + 3 * k + a]


cdef void pair_contraction(const double* p, const double* x, const double* y, Py_ssize_t nq,
                           double* out) noexcept nogil:
    """out (3, 3) = sum_jk P[a, b, j, k] x_j y_k of the mode-pair integrals stored as P[3a+b, j nq + k]."""
    cdef Py_ssize_t a, b, j, k
    cdef double acc
    for a in range(3):
        for b in range(3):
            acc = 0.0
            for j in range(nq):
                for k in range(nq):
                    acc += p[(3 * a + b) * nq * nq + j * nq + k] * x[j] * y[k]
            out[3 * a + b] = acc


cdef void inertia_terms(const double* F, const int64_t* off, const int64_t* flags, Py_ssize_t nq, const double* q,
                        double* md, double* inertia, double* ct, double* cr, Py_ssize_t ld) noexcept nogil:
    """md (3,), I (3, 3), Ct (nq, 3), Cr (nq, 3) at q (sid-spec 5.2), written into md, inertia,
    ct, cr (the rows of ct and cr ld apart)."""
    cdef const double* md0 = block(F, off[MD0])
    cdef const double* i0 = block(F, off[I0])
    cdef const double* ct0 = block(F, off[CT0])
    cdef const double* cr0 = block(F, off[CR0])
    cdef const double* md1
    cdef const double* i1
    cdef double pqq[9]
    cdef double tr
    cdef Py_ssize_t j, k, a, b
    for a in range(3):
        md[a] = md0[a]
    for a in range(9):
        inertia[a] = i0[a]
    for k in range(nq):
        for a in range(3):
            ct[k * ld + a] = ct0[3 * k + a]
            cr[k * ld + a] = cr0[3 * k + a]
    if flags[F_INERTIA]:
        md1, i1 = block(F, off[MD1]), block(F, off[I1])
        for j in range(nq):
            for a in range(3):
                md[a] += q[j] * md1[3 * j + a]
                for b in range(3):
                    inertia[3 * a + b] += q[j] * i1[9 * j + 3 * a + b]
    if flags[F_CT1]:
        add_first_order(ct, ld, block(F, off[CT1]), q, nq)
    if flags[F_CR1]:
        add_first_order(cr, ld, block(F, off[CR1]), q, nq)
    if flags[F_SECOND]:  # I2 = tr(Pqq) E - Pqq (sid-spec 3.8)
        pair_contraction(block(F, off[P2]), q, q, nq, pqq)
        tr = pqq[0] + pqq[4] + pqq[8]
        for a in range(3):
            inertia[4 * a] += tr
            for b in range(3):
                inertia[3 * a + b] -= pqq[3 * a + b]


cdef void body_equations(const double* F, const int64_t* off, const int64_t* flags, double mass, Py_ssize_t nq,
                         const double* q, const double* qd, const double* w, const double* gk, double* m,
                         Py_ssize_t ld, double* h) noexcept nogil:
    """M_K (6+nq, 6+nq; rows ld apart) and h_K (6+nq,) of sid-spec 5.2 with gravity g_K (K
    components), written into m and h; q, qd (nq,), w, gk (3,)."""
    cdef Py_ssize_t n = 6 + nq, i, j, k, a, b
    cdef double md[3]
    cdef double inertia[9]
    cdef double wh[6]
    cdef double ctq[3]
    cdef double g[9]
    cdef double r[9]
    cdef double v[3]
    cdef double c0, c1, c2, i0, i1, i2, tr
    cdef double* ct = m + 6 * ld  # Ct and Cr straight into their blocks of M_K
    cdef double* cr = m + 6 * ld + 3
    cdef const double* me = block(F, off[ME])
    cdef const double* ke = block(F, off[KE])
    cdef const double* gr0
    cdef const double* ge
    cdef const double* oe0
    cdef const double* oe1
    cdef const double* ks0
    cdef const double* ks1
    cdef const double* de
    for i in range(n):
        h[i] = 0.0
        for j in range(n):
            m[i * ld + j] = 0.0
    inertia_terms(F, off, flags, nq, q, md, inertia, ct, cr, ld)
    for a in range(3):
        m[a * ld + a] = mass
        for b in range(3):
            m[(3 + a) * ld + 3 + b] = inertia[3 * a + b]
    m[3 * ld + 1], m[3 * ld + 2], m[4 * ld], m[4 * ld + 2], m[5 * ld], m[5 * ld + 1] = \
        -md[2], md[1], md[2], -md[0], -md[1], md[0]
    for a in range(3):
        for b in range(3):
            m[a * ld + 3 + b] = m[(3 + b) * ld + a]
    for k in range(nq):
        for a in range(3):
            m[a * ld + 6 + k] = ct[k * ld + a]
            m[(3 + a) * ld + 6 + k] = cr[k * ld + a]
        for j in range(nq):
            m[(6 + k) * ld + 6 + j] = me[k * nq + j]
    c0, c1, c2 = w[1] * md[2] - w[2] * md[1], w[2] * md[0] - w[0] * md[2], w[0] * md[1] - w[1] * md[0]  # w x md
    h[0], h[1], h[2] = -(w[1] * c2 - w[2] * c1), -(w[2] * c0 - w[0] * c2), -(w[0] * c1 - w[1] * c0)
    i0, i1, i2 = 0.0, 0.0, 0.0  # I w
    for b in range(3):
        i0 += inertia[b] * w[b]
        i1 += inertia[3 + b] * w[b]
        i2 += inertia[6 + b] * w[b]
    h[3], h[4], h[5] = -(w[1] * i2 - w[2] * i1), -(w[2] * i0 - w[0] * i2), -(w[0] * i1 - w[1] * i0)
    if flags[F_OE0] or flags[F_OE1]:
        wh[0], wh[1], wh[2], wh[3], wh[4], wh[5] = w[0] * w[0], w[1] * w[1], w[2] * w[2], w[0] * w[1], w[1] * w[2], \
            w[0] * w[2]
    if flags[F_CORIOLIS]:
        for a in range(3):
            ctq[a] = 0.0
        for a in range(9):
            g[a] = 0.0
        gr0 = block(F, off[GR0])
        for k in range(nq):
            for a in range(3):
                ctq[a] += ct[k * ld + a] * qd[k]
                for b in range(3):
                    g[3 * a + b] += qd[k] * gr0[9 * k + 3 * a + b]
        cross3(w, ctq, v)
        for a in range(3):
            h[a] += -2.0 * v[a]
        matvec3(g, w, v)
        for a in range(3):
            h[3 + a] += -1.0 * v[a]
        ge = block(F, off[GE])
        for k in range(nq):
            for j in range(nq):
                for a in range(3):
                    h[6 + k] -= w[a] * ge[a * nq * nq + k * nq + j] * qd[j]
    if flags[F_SECOND]:  # Gr1 part of Gr(q, qd): r[i, a] = sum_kj P[i, a, k, j] qd_k q_j (sid-spec 3.8)
        pair_contraction(block(F, off[P2]), qd, q, nq, r)
        tr = r[0] + r[4] + r[8]
        matvec3(r, w, v)
        for a in range(3):
            h[3 + a] -= 2.0 * (tr * w[a] - v[a])
    for k in range(nq):
        for j in range(nq):
            h[6 + k] -= ke[k * nq + j] * q[j]
    if flags[F_OE0]:
        oe0 = block(F, off[OE0])
        for k in range(nq):
            for i in range(6):
                h[6 + k] -= oe0[6 * k + i] * wh[i]
    if flags[F_OE1]:
        oe1 = block(F, off[OE1])
        for j in range(nq):
            for k in range(nq):
                for i in range(6):
                    h[6 + k] -= q[j] * oe1[j * 6 * nq + 6 * k + i] * wh[i]
    if flags[F_PRELOAD]:
        ks0, ks1 = block(F, off[KS0]), block(F, off[KS1])
        for k in range(nq):
            h[6 + k] -= ks0[k]
            for j in range(nq):
                h[6 + k] -= ks1[k * nq + j] * q[j]
    if flags[F_DAMPING]:
        de = block(F, off[DE])
        for k in range(nq):
            for j in range(nq):
                h[6 + k] -= de[k * nq + j] * qd[j]
    if flags[F_GRAVITY]:
        add_gravity_force(F, off, flags, mass, nq, q, gk, h)


cdef void gravity_md(const double* F, const int64_t* off, Py_ssize_t nq, const double* q, double* md) noexcept nogil:
    """md (3,) = md_g(q) = md0 + Ct0^T q (kg m): the first mass moment seen by gravity."""
    cdef const double* md0 = block(F, off[MD0])
    cdef const double* ct0 = block(F, off[CT0])
    cdef Py_ssize_t k, a
    for a in range(3):
        md[a] = md0[a]
    for k in range(nq):
        for a in range(3):
            md[a] += ct0[3 * k + a] * q[k]


cdef void add_gravity_force(const double* F, const int64_t* off, const int64_t* flags, double mass, Py_ssize_t nq,
                            const double* q, const double* gk, double* out) noexcept nogil:
    """out (6+nq,) += -dV/d(coordinates) of the gravity potential (module doc), K components."""
    cdef const double* ct0 = block(F, off[CT0])
    cdef const double* ct1
    cdef double md[3]
    cdef double c[3]
    cdef double acc, s
    cdef Py_ssize_t j, k, a
    gravity_md(F, off, nq, q, md)
    for a in range(3):
        out[a] += mass * gk[a]
    cross3(md, gk, c)
    for a in range(3):
        out[3 + a] += c[a]
    for k in range(nq):
        acc = 0.0
        for a in range(3):
            acc += ct0[3 * k + a] * gk[a]
        if flags[F_CT1]:
            ct1 = block(F, off[CT1])
            for j in range(nq):
                s = 0.0
                for a in range(3):
                    s += 0.5 * (ct1[j * 3 * nq + 3 * k + a] + ct1[k * 3 * nq + 3 * j + a]) * gk[a]
                acc += s * q[j]
        out[6 + k] += acc


cdef inline double quadratic_form(const double* a, const double* x, Py_ssize_t nq) noexcept nogil:
    """x^T a x for a (nq, nq) row-major."""
    cdef double acc = 0.0, row
    cdef Py_ssize_t k, j
    for k in range(nq):
        row = 0.0
        for j in range(nq):
            row += a[k * nq + j] * x[j]
        acc += x[k] * row
    return acc


cdef (double, double) body_potentials(const double* F, const int64_t* off, const int64_t* flags, double mass,
                                      Py_ssize_t nq, const double* r, const double* A, const double* q,
                                      const double* g) noexcept nogil:
    """(strain energy, gravity potential) of one body, J; r (3,), A (3, 3), g (3,) inertial, q (nq,)."""
    cdef double strain = 0.5 * quadratic_form(block(F, off[KE]), q, nq), grav = 0.0, acc
    cdef const double* ks0
    cdef const double* ct1
    cdef double md[3]
    cdef double amd[3]
    cdef double gk[3]
    cdef Py_ssize_t j, k, a
    if flags[F_PRELOAD]:
        ks0 = block(F, off[KS0])
        acc = 0.0
        for k in range(nq):
            acc += ks0[k] * q[k]
        strain += acc + 0.5 * quadratic_form(block(F, off[KS1]), q, nq)
    if flags[F_GRAVITY]:
        gravity_md(F, off, nq, q, md)
        matvec3(A, md, amd)
        grav = -(mass * dot3(g, r) + dot3(g, amd))
        if flags[F_CT1]:
            tmatvec3(A, g, gk)
            ct1 = block(F, off[CT1])
            for j in range(nq):
                for k in range(nq):
                    for a in range(3):
                        grav -= 0.5 * q[k] * ct1[j * 3 * nq + 3 * k + a] * gk[a] * q[j]
    return strain, grav


def body_matrices(const double[::1] F, const int64_t[::1] off, const int64_t[::1] flags, double mass,
                  const double[::1] q, const double[::1] qd, const double[::1] w, const double[::1] gk):
    """(M_K (6+nq, 6+nq), h_K (6+nq,)) of body_equations, for Python: the packed terms (F, off,
    flags) of compile/layout.py pack_terms, the mass (kg), q, qd (nq,), w (3,) rad/s and the
    gravity gk (3,) m/s^2 in K."""
    cdef Py_ssize_t nq = q.shape[0]
    if qd.shape[0] != nq or w.shape[0] != 3 or gk.shape[0] != 3 or off.shape[0] != N_TERMS or flags.shape[0] != N_FLAGS:
        raise ValueError(f"body_matrices: q, qd must be (nq,), w and gk (3,), off ({N_TERMS},), flags ({N_FLAGS},)")
    m, h = np.empty((6 + nq, 6 + nq)), np.empty(6 + nq)
    cdef double[:, ::1] m_ = m
    cdef double[::1] h_ = h
    body_equations(&F[0], &off[0], &flags[0], mass, nq, &q[0] if nq else NULL, &qd[0] if nq else NULL, &w[0], &gk[0],
                   &m_[0, 0], 6 + nq, &h_[0])
    return m, h
