"""The elastic rows of one body's equations of motion (sid-spec 5.2) at given states, compiled: the
effects estimates (sidprep/solver/effects.py) size a left-out effect by the difference of these
rows with and without its terms."""

from libc.stdint cimport int64_t
from scipy.linalg.cython_blas cimport dgemv

import numpy as np

from sidprep.solver.core.body cimport body_equations


def elastic_rows(pack, w, gk, ud, modes):
    """Elastic rows of M ud - h (sid-spec 5.2) of one body's packed terms at S states, at rest
    (q = qd = 0) and their change with q or qd along each of the n columns of ``modes``:
    (S, 1 + 2 n, nq).

    pack : (F, off, flags, mass) of ``pack_terms`` plus the mass; w, gk (S, 3) angular velocity
    (1/s) and gravity (m/s^2) in K; ud (S, 6 + nq) accelerations in K; modes (nq, n).
    """
    F, off, flags, mass = pack
    cdef const double[::1] Fv = np.ascontiguousarray(F, dtype=np.float64)
    cdef const int64_t[::1] offv = np.ascontiguousarray(off, dtype=np.int64)
    cdef const int64_t[::1] flagv = np.ascontiguousarray(flags, dtype=np.int64)
    cdef const double[:, ::1] wv = np.ascontiguousarray(w, dtype=np.float64)
    cdef const double[:, ::1] gv = np.ascontiguousarray(gk, dtype=np.float64)
    cdef const double[:, ::1] udv = np.ascontiguousarray(ud, dtype=np.float64)
    cdef const double[:, ::1] modev = np.ascontiguousarray(modes, dtype=np.float64)
    cdef Py_ssize_t S = wv.shape[0], nq = modev.shape[0], n = modev.shape[1], size = 6 + nq
    rows = np.zeros((S, 1 + 2 * n, nq))
    cdef double[:, :, ::1] out = rows
    cdef double[:, ::1] m = np.zeros((size, size))
    cdef double[::1] h = np.zeros(size), mu = np.zeros(size), zero = np.zeros(nq), mode = np.zeros(nq)
    cdef double bodymass = mass
    cdef const double* Fp = &Fv[0]
    cdef const int64_t* offp = &offv[0]
    cdef const int64_t* flagp = &flagv[0]
    cdef Py_ssize_t s, j, k
    with nogil:
        for s in range(S):
            body_equations(Fp, offp, flagp, bodymass, nq, &zero[0], &zero[0], &wv[s, 0], &gv[s, 0], &m[0, 0], size, &h[0])
            _product(m, udv[s], mu)
            for k in range(nq):
                out[s, 0, k] = mu[6 + k] - h[6 + k]
            for j in range(n):
                for k in range(nq):
                    mode[k] = modev[k, j]
                body_equations(Fp, offp, flagp, bodymass, nq, &mode[0], &zero[0], &wv[s, 0], &gv[s, 0], &m[0, 0], size,
                               &h[0])
                _product(m, udv[s], mu)
                for k in range(nq):
                    out[s, 1 + j, k] = (mu[6 + k] - h[6 + k]) - out[s, 0, k]
                body_equations(Fp, offp, flagp, bodymass, nq, &zero[0], &mode[0], &wv[s, 0], &gv[s, 0], &m[0, 0], size,
                               &h[0])
                _product(m, udv[s], mu)
                for k in range(nq):
                    out[s, 1 + n + j, k] = (mu[6 + k] - h[6 + k]) - out[s, 0, k]
    return rows


cdef void _product(const double[:, ::1] m, const double[::1] x, double[::1] out) noexcept nogil:
    """out = m x (m square) by BLAS as numpy's matmul of a C-ordered matrix: the transposed product
    of the column-ordered one."""
    cdef int size = <int>m.shape[0], one = 1
    cdef double alpha = 1.0, beta = 0.0
    dgemv("t", &size, &size, &alpha, <double*>&m[0, 0], &size, <double*>&x[0], &one, &beta, &out[0], &one)
