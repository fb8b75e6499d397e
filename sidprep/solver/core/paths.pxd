# Markers moving along a path of a flexible body (paths.pyx): the point and frame at an arc length
# on the deformed path, their rates, the projection of a point onto it.  ``work`` is the caller's
# scratch (MarkerKinematics.work) of the doubles each kernel states; 3-vectors and (3, 3) frames
# are row-major C arrays by pointer.
from sidprep.solver.core.records cimport Layout


cdef struct BodyPose:
    const double* r     # (3,) origin, m (inertial)
    const double* a     # (3, 3) frame A, row-major
    const double* q     # (nq,) modal coordinates
    Py_ssize_t nq


cdef inline const double* at(const double[::1] v, Py_ssize_t o) noexcept nogil:
    """The address of v[o] (o may be the end of v, or anything when v is empty: a block of no elements)."""
    return &v[0] + o if v.shape[0] > 0 else NULL


cdef inline BodyPose body_pose(Layout L, Py_ssize_t b, const double[:, ::1] R, const double[:, :, ::1] A,
                               const double[::1] Q) noexcept nogil:
    """Body b's pose (r, A, q) in the state (R, A, Q)."""
    cdef BodyPose body
    body.r, body.a, body.q, body.nq = &R[b, 0], &A[b, 0, 0], at(Q, L.qoff[b]), L.qoff[b + 1] - L.qoff[b]
    return body


cdef double projected_arc(Layout L, Py_ssize_t first, BodyPose body, const double* target, double* work) noexcept nogil
cdef double motion_arc(Layout L, Py_ssize_t k, double t) noexcept nogil
cdef void path_acceleration(Layout L, Py_ssize_t k, BodyPose body, const double* ub, double t, double* work,
                            double* out) noexcept nogil
cdef bint path_pose(Layout L, Py_ssize_t first, BodyPose body, double s, const double* rotation, bint extend,
                    double* work, double* p, double* rot, double* point) noexcept nogil
cdef void path_convection(Layout L, Py_ssize_t first, BodyPose body, double s, double s_dot, const double* rotation,
                          const double* frame, bint on, double* work, double* vc, double* wc) noexcept nogil
