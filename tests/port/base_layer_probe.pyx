"""Python entries to the pointer kernels of sidprep/solver/core/rotations, curves and body, for
tests/port/test_base_layer.py (which compiles this file): numpy arrays in, numpy arrays out."""

import numpy as np

from libc.stdint cimport int64_t

from sidprep.solver.core cimport body, curves, rotations
from sidprep.solver.core.records cimport Layout


cdef double* ptr(double[::1] v):
    """The address of v's first element (NULL when v is empty: a block of no elements)."""
    return &v[0] if v.shape[0] > 0 else NULL



def vec(x):
    return np.array(x, dtype=float).ravel()


def rotation_kernel(name, *args, alias=-1):
    """The 3-vector / 3x3 kernel ``name`` of rotations.pxd on flat copies of args; the result
    written into a new array, or into the copy of args[alias] (out = an input)."""
    cdef double[::1] a = vec(args[0])
    cdef double[::1] b = vec(args[1]) if len(args) > 1 else vec(np.zeros(1))
    size = {"cross3": 3, "matvec3": 3, "tmatvec3": 3, "matmul3": 9, "skew3": 9, "exp_so3": 9, "se3_jacobian": 9,
            "se3_jacobian_solve": 3, "align": 9, "quaternion_to_matrix": 9, "quaternion_rate": 4}[name]
    cdef double[::1] out = np.asarray(a) if alias == 0 else np.asarray(b) if alias == 1 else np.zeros(size)
    if name == "cross3":
        rotations.cross3(&a[0], &b[0], &out[0])
    elif name == "matvec3":
        rotations.matvec3(&a[0], &b[0], &out[0])
    elif name == "tmatvec3":
        rotations.tmatvec3(&a[0], &b[0], &out[0])
    elif name == "matmul3":
        rotations.matmul3(&a[0], &b[0], &out[0])
    elif name == "skew3":
        rotations.skew3(&a[0], &out[0])
    elif name == "exp_so3":
        rotations.exp_so3(&a[0], &out[0])
    elif name == "se3_jacobian":
        rotations.se3_jacobian(&a[0], &out[0])
    elif name == "se3_jacobian_solve":
        rotations.se3_jacobian_solve(&a[0], &b[0], &out[0])
    elif name == "align":
        rotations.align(&a[0], &b[0], &out[0])
    elif name == "quaternion_to_matrix":
        rotations.quaternion_to_matrix(&a[0], &out[0])
    elif name == "quaternion_rate":
        rotations.quaternion_rate(&a[0], &b[0], &out[0])
    result = np.asarray(out)
    return result.reshape(3, 3) if size == 9 else result


def dot3(a, b):
    cdef double[::1] a_ = vec(a), b_ = vec(b)
    return rotations.dot3(&a_[0], &b_[0])


def dot(const double[:] a, const double[:] b):
    return rotations.dot(a, b)


def matvec(const double[:, :] a, const double[:] x, double[:] out):
    rotations.matvec(a, x, out)


def tmatvec(const double[:, :] a, const double[:] x, double[:] out):
    rotations.tmatvec(a, x, out)


def matmul(const double[:, :] a, const double[:, :] b, double[:, :] out):
    rotations.matmul(a, b, out)


def constants():
    return rotations.SMALL_ANGLE, rotations.SE3_SMALL_ANGLE


def curve_value(x, c, double period, double at, int derivative):
    """curves.curve_value of the piecewise polynomial x (nx,), c (rows, nx - 1)."""
    cdef double[::1] x_ = vec(x), c_ = vec(c)
    return curves.curve_value(&x_[0], x_.shape[0], &c_[0], np.shape(c)[0], period, at, derivative)


def motion_state(int64_t kind, params, x, c, double t):
    cdef double[::1] p_ = vec(params), x_ = vec(x), c_ = vec(c)
    cdef Py_ssize_t rows = np.shape(c)[0]
    cdef (const double*, Py_ssize_t, const double*, Py_ssize_t) curve = (&x_[0], x_.shape[0], &c_[0], rows)
    return curves.motion_state(kind, &p_[0], curve, t)


def path_shapes(Layout L, Py_ssize_t first, Py_ssize_t nq, double s):
    """(point, phi, psi, on, dpoint, dphi) of curves.path_shapes."""
    cdef double[::1] point = np.zeros(3), dpoint = np.zeros(3)
    cdef double[::1] phi = np.zeros(3 * nq), psi = np.zeros(3 * nq), dphi = np.zeros(3 * nq)
    on = curves.path_shapes(L, first, nq, s, &point[0], ptr(phi), ptr(psi), &dpoint[0], ptr(dphi))
    shape = (3, nq)
    return (np.asarray(point), np.asarray(phi).reshape(shape), np.asarray(psi).reshape(shape), on,
            np.asarray(dpoint), np.asarray(dphi).reshape(shape))


def add_first_order(double[:, ::1] x, x1f, q):
    """body.add_first_order into x (nq, ld >= 3) in place."""
    cdef double[::1] x1f_ = vec(x1f), q_ = vec(q)
    body.add_first_order(&x[0, 0], x.shape[1], &x1f_[0], &q_[0], q_.shape[0])


def pair_contraction(p, x, y):
    cdef double[::1] p_ = vec(p), x_ = vec(x), y_ = vec(y), out = np.zeros(9)
    body.pair_contraction(&p_[0], &x_[0], &y_[0], x_.shape[0], &out[0])
    return np.asarray(out).reshape(3, 3)


def inertia_terms(F, const int64_t[::1] off, const int64_t[::1] flags, q, Py_ssize_t ld):
    """(md, I, Ct, Cr) of body.inertia_terms, Ct and Cr written with rows ld apart."""
    cdef double[::1] F_ = vec(F), q_ = vec(q), md = np.zeros(3), inertia = np.zeros(9)
    nq = q_.shape[0]
    cdef double[:, ::1] ct = np.full((max(nq, 1), ld), np.nan), cr = np.full((max(nq, 1), ld), np.nan)
    body.inertia_terms(&F_[0], &off[0], &flags[0], nq, ptr(q_), &md[0], &inertia[0], &ct[0, 0], &cr[0, 0], ld)
    return np.asarray(md), np.asarray(inertia).reshape(3, 3), np.asarray(ct)[:nq, :3], np.asarray(cr)[:nq, :3]


def body_equations(F, const int64_t[::1] off, const int64_t[::1] flags, double mass, q, qd, w, gk,
                   double[:, ::1] m, double[::1] h):
    """body.body_equations into the top left (6 + nq, 6 + nq) of m (rows m.shape[1] apart) and h."""
    cdef double[::1] F_ = vec(F), q_ = vec(q), qd_ = vec(qd), w_ = vec(w), gk_ = vec(gk)
    body.body_equations(&F_[0], &off[0], &flags[0], mass, q_.shape[0], ptr(q_), ptr(qd_), &w_[0], &gk_[0],
                        &m[0, 0], m.shape[1], &h[0])


def gravity_md(F, const int64_t[::1] off, q):
    cdef double[::1] F_ = vec(F), q_ = vec(q), md = np.zeros(3)
    body.gravity_md(&F_[0], &off[0], q_.shape[0], ptr(q_), &md[0])
    return np.asarray(md)


def add_gravity_force(F, const int64_t[::1] off, const int64_t[::1] flags, double mass, q, gk, double[::1] out):
    cdef double[::1] F_ = vec(F), q_ = vec(q), gk_ = vec(gk)
    body.add_gravity_force(&F_[0], &off[0], &flags[0], mass, q_.shape[0], ptr(q_), &gk_[0], &out[0])


def body_potentials(F, const int64_t[::1] off, const int64_t[::1] flags, double mass, r, A, q, g):
    cdef double[::1] F_ = vec(F), r_ = vec(r), A_ = vec(A), q_ = vec(q), g_ = vec(g)
    return body.body_potentials(&F_[0], &off[0], &flags[0], mass, q_.shape[0], &r_[0], &A_[0], ptr(q_), &g_[0])
