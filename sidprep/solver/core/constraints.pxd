# Marker kinematics, joint constraint rows and joint coordinates (constraints.pyx).
# Arrays are row-major C arrays by pointer: 3-vectors (3,), frames (3, 3), row coefficients
# c (4, 3) = (cT1, cR1, cT2, cR2), load-stiffening parts K0 (3, nq, nq); matrices with a
# leading dimension have their rows that far apart: mode shapes Phi, Psi (3, nq) lds (nq in the
# layout's shapes, wider in a scratch array), Jacobians (3, 6 + nq) ld (a marker's block of the
# padded JT (nmk, 3, w_max) has ld = w_max).
from libc.stdint cimport int64_t

#: joint coordinate kinds (compile/layout.py's joint_kind)
cpdef enum:
    NO_COORDINATE = 0
    ANGLE = 1
    SLIDE = 2

cdef void marker_jacobians(const double* A, const double* d, const double* phi, const double* psi, Py_ssize_t nq,
                           Py_ssize_t lds, double* jt, double* jr, Py_ssize_t ld) noexcept nogil
cdef void marker_pose(const double* r, const double* A, const double* q, Py_ssize_t nq, const double* position,
                      const double* rotation, const double* phi, const double* psi,
                      Py_ssize_t lds, double* p, double* rot, double* d) noexcept nogil
cdef void stiffened_jacobian(const double* jac, const double* A, const double* q, Py_ssize_t nq, const double* k0,
                             double* out, Py_ssize_t ld) noexcept nogil
cdef void joint_rows(const int64_t* rows, Py_ssize_t n, const double* p1, const double* a1, const double* p2,
                     const double* a2, double* g, double* c) noexcept nogil
cdef double unwrap(double raw, double ref) noexcept nogil
cdef double joint_coordinate(int64_t kind, const double* p1, const double* a1, const double* p2, const double* a2,
                             double ref, double* c) noexcept nogil
