# The out-of-plane reactions of a planar run (planar.pyx): the equations of the dropped rows'
# reactions, their independent rows and their least-norm solution.
from libc.stdint cimport int64_t

from sidprep.solver.core.records cimport Evaluation


cdef class PlanarWork:
    """Scratch of the out-of-plane reactions of no equations in nd dropped rows' reactions
    (planar_work): the system a (no, nd), load (no,), the reactions x (nd,), the independent
    equations rows[:r] (picked once per stretch), and the Cholesky / lstsq scratch."""
    cdef readonly double[:, ::1] a
    cdef readonly double[::1] load, x
    cdef readonly int64_t[::1] rows
    cdef readonly Py_ssize_t r
    cdef double[:, ::1] g                      # (no, no) a_I a_I^T and its Cholesky factor
    cdef double[::1] z                         # (no,)


cpdef PlanarWork planar_work(Py_ssize_t no, Py_ssize_t nd)
cpdef void out_of_plane_system(Evaluation e, const double[::1] ud, const double[::1] lam_full,
                               const int64_t[::1] planar_rows, const int64_t[::1] dropped, const int64_t[::1] fixed,
                               double[:, ::1] a, double[::1] load) noexcept nogil
cpdef Py_ssize_t independent_equations(const double[:, ::1] a, int64_t[::1] rows) noexcept
cpdef void minimum_norm_solution(const double[:, ::1] a, const double[::1] load, const int64_t[::1] rows,
                                 double[:, ::1] g, double[::1] z, double[::1] x) noexcept nogil
cpdef bint solves(const double[:, ::1] a, const double[::1] x, const double[::1] load) noexcept nogil
cpdef void lstsq(const double[:, ::1] a, const double[::1] load, double[::1] x) noexcept nogil
cpdef void out_of_plane_reactions(Evaluation e, const double[::1] ud, double[::1] lam_full,
                                  const int64_t[::1] planar_rows, const int64_t[::1] dropped,
                                  const int64_t[::1] fixed, PlanarWork w) noexcept nogil
