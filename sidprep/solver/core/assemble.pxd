# The equations of a whole system at one state (assemble.pyx): the entry kernels the integrators,
# the outputs and the start call; all write into the run's records and allocate nothing.
from libc.stdint cimport int64_t

from sidprep.solver.core.records cimport Evaluation, Layout, MarkerKinematics


cpdef bint has_moving_masses(Layout L) noexcept nogil
cpdef void markers_into(Layout L, MarkerKinematics kin, const double[:, ::1] R, const double[:, :, ::1] A,
                        const double[::1] Q, const double[::1] u, double t) noexcept nogil
cpdef void evaluate_into(Layout L, Evaluation W, const double[:, ::1] R, const double[:, :, ::1] A,
                         const double[::1] Q, const double[::1] u, double t, const double[::1] lam,
                         const double[::1] refs) noexcept nogil
cpdef double constraint_power(Layout L, const double[:, ::1] B, const double[::1] bt, const double[::1] u,
                              const double[::1] lam) noexcept nogil
cpdef (double, double, double) energies(Layout L, const double[:, ::1] R, const double[:, :, ::1] A,
                                        const double[::1] Q, const double[::1] u,
                                        const double[:, ::1] M) noexcept nogil
cpdef (double, double, double) moving_masses(Layout L, MarkerKinematics kin, const double[:, ::1] R,
                                             const double[:, :, ::1] A, const double[::1] Q, const double[::1] u,
                                             const double[::1] ud, double t) noexcept nogil
