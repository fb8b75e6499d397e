"""Python entries to the pointer kernels of sidprep/solver/core/constraints.pyx and forces.pyx, for
tests/port/test_joint_layer.py (which compiles this file): numpy arrays in, numpy arrays out."""

import numpy as np

from libc.stdint cimport int64_t

from sidprep.solver.core cimport constraints, forces
from sidprep.solver.core.records cimport Layout


def marker_pose(r, A, q, position, rotation, phi, psi):
    """(p, rot, d) of constraints.marker_pose; phi, psi (3, lds >= nq) with nq = q.size."""
    cdef double[::1] r_ = np.ascontiguousarray(r, float), q_ = np.append(np.asarray(q, float), 0.0)
    cdef double[::1] c_ = np.ascontiguousarray(position, float)
    cdef double[:, ::1] a_ = np.ascontiguousarray(A, float), rot_ = np.ascontiguousarray(rotation, float)
    cdef double[:, ::1] phi_ = np.ascontiguousarray(phi, float), psi_ = np.ascontiguousarray(psi, float)
    out = np.zeros(3), np.zeros((3, 3)), np.zeros(3)
    cdef double[::1] p_ = out[0], d_ = out[2]
    cdef double[:, ::1] m_ = out[1]
    constraints.marker_pose(&r_[0], &a_[0, 0], &q_[0], q_.shape[0] - 1, &c_[0], &rot_[0, 0], &phi_[0, 0],
                            &psi_[0, 0], phi_.shape[1], &p_[0], &m_[0, 0], &d_[0])
    return out


def marker_jacobians(A, d, phi, psi, nq, jt, jr):
    """constraints.marker_jacobians into jt, jr (3, ld) in place; phi, psi (3, lds >= nq)."""
    cdef double[::1] d_ = np.ascontiguousarray(d, float)
    cdef double[:, ::1] a_ = np.ascontiguousarray(A, float)
    cdef double[:, ::1] phi_ = np.ascontiguousarray(phi, float), psi_ = np.ascontiguousarray(psi, float)
    cdef double[:, ::1] jt_ = jt, jr_ = jr
    constraints.marker_jacobians(&a_[0, 0], &d_[0], &phi_[0, 0], &psi_[0, 0], nq, phi_.shape[1], &jt_[0, 0],
                                 &jr_[0, 0], jt_.shape[1])


def stiffened_jacobian(jac, A, q, k0, out):
    """constraints.stiffened_jacobian of jac into out (3, ld) in place; k0 (3, nq, nq)."""
    cdef double[:, ::1] jac_ = jac, out_ = out, a_ = np.ascontiguousarray(A, float)
    cdef double[::1] q_ = np.ascontiguousarray(q, float), k0_ = np.ascontiguousarray(k0, float).ravel()
    constraints.stiffened_jacobian(&jac_[0, 0], &a_[0, 0], &q_[0], q_.shape[0], &k0_[0], &out_[0, 0], jac_.shape[1])


def joint_rows(rows, p1, a1, p2, a2, g, c):
    """constraints.joint_rows of rows (n, 3) into g (n,), c (n, 4, 3) in place."""
    cdef const int64_t[:, ::1] rows_ = np.ascontiguousarray(rows, np.int64)
    cdef double[::1] p1_ = np.ascontiguousarray(p1, float), p2_ = np.ascontiguousarray(p2, float), g_ = g
    cdef double[:, ::1] a1_ = np.ascontiguousarray(a1, float), a2_ = np.ascontiguousarray(a2, float)
    cdef double[:, :, ::1] c_ = c
    constraints.joint_rows(&rows_[0, 0], rows_.shape[0], &p1_[0], &a1_[0, 0], &p2_[0], &a2_[0, 0], &g_[0],
                           &c_[0, 0, 0])


def joint_coordinate(kind, p1, a1, p2, a2, ref):
    """(value, c (4, 3)) of constraints.joint_coordinate."""
    cdef double[::1] p1_ = np.ascontiguousarray(p1, float), p2_ = np.ascontiguousarray(p2, float)
    cdef double[:, ::1] a1_ = np.ascontiguousarray(a1, float), a2_ = np.ascontiguousarray(a2, float)
    c = np.full((4, 3), np.nan)
    cdef double[:, ::1] c_ = c
    value = constraints.joint_coordinate(kind, &p1_[0], &a1_[0, 0], &p2_[0], &a2_[0, 0], ref, &c_[0, 0])
    return value, c


def unwrap(raw, ref):
    return constraints.unwrap(raw, ref)


def spring_tension(par, x, rate):
    cdef double[::1] par_ = np.ascontiguousarray(par, float)
    return forces.spring_tension(&par_[0], x, rate)


def bump_potential(par, x):
    cdef double[::1] par_ = np.ascontiguousarray(par, float)
    return forces.bump_potential(&par_[0], x)


def curve(Layout L, index, at):
    return forces.curve(L, index, at)


def motion_curve(Layout L, index):
    """(x, c) of forces.motion_curve as arrays: x (nx,), c (rows, nx - 1)."""
    cdef const double* x
    cdef const double* c
    cdef Py_ssize_t nx, rows
    x, nx, c, rows = forces.motion_curve(L, index)
    return np.array([x[i] for i in range(nx)]), np.array([c[i] for i in range(rows * max(nx - 1, 1))])


def add_joint_load(loads, mk1, mk2, crow, value):
    """forces.add_joint_load into loads (nmk, 6) in place."""
    cdef double[:, ::1] crow_ = np.ascontiguousarray(crow, float)
    forces.add_joint_load(loads, mk1, mk2, &crow_[0, 0], value)
