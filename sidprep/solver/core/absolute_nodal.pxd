# The absolute-nodal beams of Kisu Lee, compiled (absolute_nodal.pyx): the model's constant arrays
# and the scratch of its right-hand side as one record, and the kernels on it.
from libc.stdint cimport int64_t


cdef class BeamSystem:
    """An absolute-nodal model's constant arrays (sidprep/solver/absolute_nodal/assembly.py,
    ``Assembly``; field meanings there) and the scratch its right-hand side writes (made once)."""
    cdef readonly const double[:, ::1] X0                   # (N, 2) m initial node positions
    cdef readonly const int64_t[::1] free                   # (nf,) free nodes
    cdef readonly const double[:, ::1] Minv                 # (nf, nf) 1/kg
    cdef readonly const double[:, ::1] f0                   # (N, 2) N gravity + nodal forces
    cdef readonly const int64_t[:, ::1] beam_nodes          # (B, nmax) -1 padded
    cdef readonly const int64_t[::1] beam_n                 # (B,)
    cdef readonly const double[::1] beam_e                  # (B,) m element lengths
    cdef readonly const double[:, :, ::1] beam_K            # (B, 6, 6) element stiffnesses
    cdef readonly const double[:, ::1] drv                  # (nd, 6) beam, at_end, psi0, speed, delta, duration
    cdef readonly double alpha                              # 1/s Baumgarte rate of the drivers
    cdef readonly double[:, ::1] X, V, A, Q, Z              # (N, 2) scratch: positions, velocities, accelerations, forces, unit
    cdef readonly double[::1] lam                           # (nd,) N m driver multipliers of the last accelerations
    cdef double[:, ::1] work                                # (9, nmax) a beam's stencil and stiffness scratch
    cdef double[:, ::1] G, MG, S, LU                        # (nd, 2 nf), (2 nf, nd), (nd, nd) G M^-1 G^T, its LAPACK copy
    cdef double[::1] res                                    # (nd,)
    cdef int[::1] pivots                                    # (nd,)
    cdef double[:, ::1] stages                              # (5, 4 nf) rk4 slopes k1..k4 and a stage's argument


cdef class RK4Progress:
    """Where an RK4 run stands: time t (s), state y (4 nf,), the next output time (s) and the steps so far."""
    cdef public double t
    cdef public double[::1] y
    cdef public double next_out
    cdef public Py_ssize_t steps


cdef double slope_weight(Py_ssize_t k, Py_ssize_t i, Py_ssize_t n, double e) noexcept nogil
cdef Py_ssize_t _slope_stencil_start(Py_ssize_t k, Py_ssize_t n) noexcept nogil
cdef (double, double, double) beam_kinematics(const double[:, ::1] X, const double[:, ::1] V, const double[:, ::1] A,
                                              const int64_t[::1] nodes, Py_ssize_t n, double e,
                                              double[:, ::1] work) noexcept nogil
cdef double beam_elastic(const double[:, ::1] X, const int64_t[::1] nodes, Py_ssize_t n, double e,
                         const double[:, ::1] Ke, double[:, ::1] Q, double[:, ::1] work) noexcept nogil
cpdef (double, double, double) driver_angle(double t, double psi0, double speed, double delta,
                                            double duration) noexcept nogil
cpdef double wrapped_angle(double a) noexcept nogil
cdef (double, double, double) driver_value(const double[:, ::1] X, const double[:, ::1] V, const double[:, ::1] A,
                                           const int64_t[::1] nodes, Py_ssize_t n, double e, bint at_end,
                                           double[:, ::1] work) noexcept nogil
cdef double accelerations(BeamSystem s, double t, const double[::1] y) noexcept nogil
cdef void rhs(BeamSystem s, double t, const double[::1] y, double[::1] yd) noexcept nogil
