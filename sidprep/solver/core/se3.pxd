# The SE(3) x R^nq coordinates of the generalised-alpha stepper (se3.pyx): body-frame
# translational velocities v_K = A^T v_O, the transformation S = blockdiag(A, E, E) of velocities,
# accelerations, the equations, and the SE(3) increment between two poses.
from sidprep.solver.core.records cimport Evaluation, Layout


cpdef void rotate_translations(Layout L, const double[:, :, ::1] A, const double[::1] u, bint inverse,
                               double[::1] out) noexcept nogil
cpdef void inertial_velocities(Layout L, const double[:, :, ::1] A, const double[::1] u_K,
                               double[::1] out) noexcept nogil
cpdef void body_velocities(Layout L, const double[:, :, ::1] A, const double[::1] u_O, double[::1] out) noexcept nogil
cpdef void convective(Layout L, const double[:, :, ::1] A, const double[::1] u_K, double[::1] c) noexcept nogil
cpdef void inertial_accelerations(Layout L, const double[:, :, ::1] A, const double[::1] u_K,
                                  const double[::1] ud_K, double[::1] out) noexcept nogil
cpdef void body_accelerations(Layout L, const double[:, :, ::1] A, const double[::1] u_K, const double[::1] ud_O,
                              double[::1] out) noexcept nogil
cpdef void right_multiply(double[:, ::1] X, Layout L, const double[:, :, ::1] A) noexcept nogil
cpdef void left_multiply(double[:, ::1] X, Layout L, const double[:, :, ::1] A) noexcept nogil
cpdef void to_body_frame(Layout L, const double[:, :, ::1] A, const double[::1] u_K, Evaluation e,
                         double[::1] c) noexcept nogil
cpdef void body_increment(Layout L, const double[:, ::1] R0, const double[:, :, ::1] A0, const double[:, ::1] R1,
                          const double[:, :, ::1] A1, const double[::1] Q0, const double[::1] Q1,
                          double[::1] dx) noexcept nogil
