"""Marker kinematics, joint constraint rows and joint coordinates (model/joints.py describes the
rows; the module docstring there gives the two primitives).

Marker on body (r, A, q) at c with orientation AP0 and node shapes Phi, Psi (sid-spec 5.2):

    d = c + Phi q,   p = r + A d,   A_m = A R(Psi q) AP0,
    JT = [E, -A d~, A Phi],   JR = [0, A, A Psi]     (v_m = JT u, omega_m = JR u, inertial)

With load stiffening the force Jacobians use Phi(q) = Phi + K0F q, Psi(q) = Psi + K0M q.
Array layouts: constraints.pxd.
"""

from libc.math cimport atan2, fmod, M_PI
from libc.stdint cimport int64_t

import numpy as np

from sidprep.solver.core.rotations cimport cross3, dot3, exp_so3, matmul3


cdef void marker_jacobians(const double* A, const double* d, const double* phi, const double* psi, Py_ssize_t nq,
                           Py_ssize_t lds, double* jt, double* jr, Py_ssize_t ld) noexcept nogil:
    """JT = [E, -A d~, A Phi], JR = [0, A, A Psi] (module doc) written into the first 6 + nq
    columns of jt, jr (3, ld >= 6 + nq); A (3, 3), d (3,), phi, psi (3, nq), rows lds apart."""
    cdef Py_ssize_t a, b, k
    cdef double st, sr
    for a in range(3):  # -A d~ (d~ x = d x x): column b of A d~ is A (d x e_b)
        jt[a * ld + 3] = -(A[3 * a + 1] * d[2] - A[3 * a + 2] * d[1])
        jt[a * ld + 4] = -(A[3 * a + 2] * d[0] - A[3 * a] * d[2])
        jt[a * ld + 5] = -(A[3 * a] * d[1] - A[3 * a + 1] * d[0])
        for b in range(3):
            jt[a * ld + b] = 1.0 if a == b else 0.0
            jr[a * ld + b] = 0.0
            jr[a * ld + 3 + b] = A[3 * a + b]
        for k in range(nq):
            st = 0.0
            sr = 0.0
            for b in range(3):
                st += A[3 * a + b] * phi[b * lds + k]
                sr += A[3 * a + b] * psi[b * lds + k]
            jt[a * ld + 6 + k] = st
            jr[a * ld + 6 + k] = sr


cdef void marker_pose(const double* r, const double* A, const double* q, Py_ssize_t nq, const double* position,
                      const double* rotation, const double* phi, const double* psi,
                      Py_ssize_t lds, double* p, double* rot, double* d) noexcept nogil:
    """p (3,), A_m (3, 3) and d (3,) of a marker (module doc), written into p, rot, d; r (3,),
    A (3, 3), q (nq,), position c (3,), rotation AP0 (3, 3), phi, psi (3, nq) rows lds apart."""
    cdef double rv[3]
    cdef double e[9]
    cdef double ae[9]
    cdef double da, pa
    cdef Py_ssize_t a, b, k
    for a in range(3):
        da = position[a]
        rv[a] = 0.0
        for k in range(nq):
            da += phi[a * lds + k] * q[k]
            rv[a] += psi[a * lds + k] * q[k]
        d[a] = da
    exp_so3(rv, e)
    matmul3(A, e, ae)
    matmul3(ae, rotation, rot)
    for a in range(3):
        pa = r[a]
        for b in range(3):
            pa += A[3 * a + b] * d[b]
        p[a] = pa


def marker_kinematics(r, A, q, position, rotation, phi, psi):
    """p (3,), A_m (3, 3), JT (3, 6+nq), JR (3, 6+nq), d (3,) of a marker (module doc), numpy
    arrays; r (3,), A (3, 3), q (nq,), position (3,), rotation (3, 3), phi, psi (3, nq)."""
    cdef const double[::1] r_ = np.ascontiguousarray(r, dtype=float)
    cdef const double[:, ::1] A_ = np.ascontiguousarray(A, dtype=float)
    cdef const double[::1] q_ = np.ascontiguousarray(q, dtype=float).reshape(-1)
    cdef const double[::1] c_ = np.ascontiguousarray(position, dtype=float)
    cdef const double[:, ::1] rot_ = np.ascontiguousarray(rotation, dtype=float)
    cdef Py_ssize_t nq = q_.shape[0]
    cdef const double[:, ::1] phi_ = np.ascontiguousarray(phi, dtype=float).reshape(3, nq)
    cdef const double[:, ::1] psi_ = np.ascontiguousarray(psi, dtype=float).reshape(3, nq)
    p, rot, d = np.empty(3), np.empty((3, 3)), np.empty(3)
    jt, jr = np.empty((3, 6 + nq)), np.empty((3, 6 + nq))
    cdef double[::1] p_ = p, d_ = d
    cdef double[:, ::1] m_ = rot, jt_ = jt, jr_ = jr
    cdef double none = 0.0
    cdef const double* qp = &q_[0] if nq else &none
    cdef const double* phip = &phi_[0, 0] if nq else &none
    cdef const double* psip = &psi_[0, 0] if nq else &none
    marker_pose(&r_[0], &A_[0, 0], qp, nq, &c_[0], &rot_[0, 0], phip, psip, nq, &p_[0], &m_[0, 0], &d_[0])
    marker_jacobians(&A_[0, 0], &d_[0], phip, psip, nq, nq, &jt_[0, 0], &jr_[0, 0], 6 + nq)
    return p, rot, jt, jr, d


cdef void stiffened_jacobian(const double* jac, const double* A, const double* q, Py_ssize_t nq, const double* k0,
                             double* out, Py_ssize_t ld) noexcept nogil:
    """out = jac (3, 6 + nq) with the modal columns of A (K0 q) added: K0 (3, nq, nq) [a, j, k]
    (phi.M1); jac and out have rows ld apart (out may be jac)."""
    cdef Py_ssize_t a, b, j, k
    cdef double s
    for a in range(3):
        for k in range(6 + nq):
            out[a * ld + k] = jac[a * ld + k]
        for k in range(nq):
            s = 0.0
            for b in range(3):
                for j in range(nq):
                    s += A[3 * a + b] * k0[(b * nq + j) * nq + k] * q[j]
            out[a * ld + 6 + k] += s


cdef void joint_rows(const int64_t* rows, Py_ssize_t n, const double* p1, const double* a1, const double* p2,
                     const double* a2, double* g, double* c) noexcept nogil:
    """The n rows (kind, axis 1, axis 2) (n, 3) of a joint -> g (n,) and c (n, 4, 3) = (cT1,
    cR1, cT2, cR2) (model/joints.py: kind 0 the position of marker 2 along an axis of marker 1,
    else the perpendicularity of an axis of marker 1 and one of marker 2); markers at p1, p2
    (3,) with frames a1, a2 (3, 3)."""
    cdef double d0 = p2[0] - p1[0], d1 = p2[1] - p1[1], d2 = p2[2] - p1[2]
    cdef double e0, e1, e2, b0, b1, b2, x0, x1, x2
    cdef int64_t k, kb
    cdef double* cr
    cdef Py_ssize_t r, i
    for r in range(n):
        k = rows[3 * r + 1]
        e0, e1, e2 = a1[k], a1[3 + k], a1[6 + k]
        cr = c + 12 * r
        for i in range(12):
            cr[i] = 0.0
        if rows[3 * r] == 0:
            g[r] = e0 * d0 + e1 * d1 + e2 * d2
            cr[0], cr[1], cr[2] = -e0, -e1, -e2
            cr[3], cr[4], cr[5] = e1 * d2 - e2 * d1, e2 * d0 - e0 * d2, e0 * d1 - e1 * d0
            cr[6], cr[7], cr[8] = e0, e1, e2
        else:
            kb = rows[3 * r + 2]
            b0, b1, b2 = a2[kb], a2[3 + kb], a2[6 + kb]
            g[r] = e0 * b0 + e1 * b1 + e2 * b2
            x0, x1, x2 = e1 * b2 - e2 * b1, e2 * b0 - e0 * b2, e0 * b1 - e1 * b0
            cr[3], cr[4], cr[5] = x0, x1, x2
            cr[9], cr[10], cr[11] = -x0, -x1, -x2


cdef double unwrap(double raw, double ref) noexcept nogil:
    """The angle equal to raw modulo 2 pi closest to ref (rad)."""
    cdef double x = raw - ref + M_PI
    cdef double m = fmod(x, 2.0 * M_PI)  # Python's modulo: the result takes the divisor's sign
    if m < 0.0:
        m += 2.0 * M_PI
    return ref + m - M_PI


cdef double joint_coordinate(int64_t kind, const double* p1, const double* a1, const double* p2, const double* a2,
                             double ref, double* c) noexcept nogil:
    """Joint coordinate value (rad or m) returned, its velocity row c (4, 3) = (cT1, cR1, cT2,
    cR2) written; markers at p1, p2 (3,) with frames a1, a2 (3, 3).

    ANGLE: rotation of x2 about z1 from x1, unwrapped against ref; SLIDE: z1 . (p2 - p1).
    """
    cdef double z[3]
    cdef double d[3]
    cdef double raw
    cdef Py_ssize_t a
    for a in range(3):
        z[a] = a1[3 * a + 2]
        d[a] = p2[a] - p1[a]
    for a in range(12):
        c[a] = 0.0
    if kind == ANGLE:
        raw = atan2(a1[1] * a2[0] + a1[4] * a2[3] + a1[7] * a2[6], a1[0] * a2[0] + a1[3] * a2[3] + a1[6] * a2[6])
        for a in range(3):
            c[3 + a] = -z[a]
            c[9 + a] = z[a]
        return unwrap(raw, ref)
    cross3(z, d, c + 3)
    for a in range(3):
        c[a] = -z[a]
        c[6 + a] = z[a]
    return dot3(z, d)
