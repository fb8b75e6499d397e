# Explicit Runge-Kutta methods on the index-1 form (explicit.pyx): the explicit state, its
# right-hand side and samples, and the fixed-step RK4 loop.
from libc.stdint cimport int64_t

from sidprep.solver.core.records cimport Evaluation, Layout
from sidprep.solver.core.steps cimport Index1Workspace


cdef class RhsParams:
    """What the right-hand side of a run needs (rhs_params): the layout L, the integrated
    coordinates free and kept rows, the joints' angle references refs (nj,; the run's own array,
    updated by sample), the Baumgarte rate baumgarte (1/s), the multipliers' first guess lam_guess
    (kept,; the last solve's), the run's Evaluation e and index-1 workspace ws; the state last
    unpacked R (nb, 3), A (nb, 3, 3), Q (nq,), u (n,), its accelerations ud (n,) and multipliers
    lam (kept,), lam_all (m_all,)."""
    cdef readonly Layout L
    cdef readonly const int64_t[::1] free, kept
    cdef readonly double[::1] refs
    cdef readonly double baumgarte
    cdef readonly double[::1] lam_guess
    cdef readonly Evaluation e
    cdef readonly Index1Workspace ws
    cdef readonly double[:, ::1] R
    cdef readonly double[:, :, ::1] A
    cdef readonly double[::1] Q, u, ud, lam, lam_all


cpdef RhsParams rhs_params(Layout L, const int64_t[::1] free, const int64_t[::1] kept, double[::1] refs,
                           double baumgarte, const double[::1] lam_guess)
cpdef void unpack(Layout L, const double[::1] y, double[:, ::1] R, double[:, :, ::1] A, double[::1] Q,
                  double[::1] u) noexcept nogil
cpdef void index1_rhs(double t, const double[::1] y, RhsParams p, double[::1] ydot) noexcept nogil
cpdef void sample(double t, const double[::1] y, RhsParams p) noexcept nogil
