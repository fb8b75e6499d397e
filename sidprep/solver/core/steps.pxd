# What every integrator's step shares (steps.pyx): the output sample buffers, the multipliers of
# all rows, the Lie-group pose update, the LU solve, the index-1 accelerations and the KKT system.
from libc.stdint cimport int64_t

from sidprep.solver.core.records cimport Evaluation, Layout

# the status codes of the compiled loops (also Python ints of this module)
cpdef enum:
    RUNNING = 0
    FINISHED = 1
    MAX_STEPS = 2
    NEWTON_FAILED = 3
    LARGE_DEFORMATION = 4

cdef enum:
    CHUNK = 4096                  # output samples per call of a compiled integration loop
    MULTIPLIER_ITERATIONS = 30    # most fixed-point iterations on lambda per evaluation (friction)

cdef double GAMMA_STEP            # s, time step of the central difference giving gamma
cdef double MULTIPLIER_RTOL       # the index-1 solve iterates until lambda changes less than this
cdef double APPROACH_REACH        # a step from an open, closing bump stop reaches this x its closing time


cdef class SampleBuffers:
    """The output samples of one call of a compiled loop (sample_buffers): t (k,), R (k, nb, 3),
    A (k, nb, 3, 3), Q (k, nq), u, ud (k, n), lam (k, m), refs (k, nj), work (k, 3); ``arrays``
    the same as a SampleArrays namedtuple of numpy arrays."""
    cdef readonly double[::1] t
    cdef readonly double[:, :, ::1] R
    cdef readonly double[:, :, :, ::1] A
    cdef readonly double[:, ::1] Q, u, ud, lam, refs, work
    cdef readonly object arrays


cdef class Index1Workspace:
    """Scratch of the index-1 solve and the constraint convection for one run (index1_workspace):
    the restricted system Mf (nf, nf), ff (nf,), Bk, BFk (m, nf), the KKT matrix K (nf + m)^2, its
    pivots piv and solution z, rhs and gam (m,), the previous multipliers lam_prev (m,), all rows'
    multipliers lam_all and zero_all and B u + b_t plus (m_all,), a moved pose Rp, Ap, Qp and its
    increment dx (n,)."""
    cdef readonly double[:, ::1] Mf, Bk, BFk, K, Rp
    cdef readonly double[::1] ff, z, rhs, gam, lam_prev, lam_all, zero_all, plus, Qp, dx
    cdef readonly int[::1] piv
    cdef readonly double[:, :, ::1] Ap


cpdef SampleBuffers sample_buffers(Py_ssize_t capacity, const double[:, ::1] R, const double[::1] Q,
                                   const double[::1] u, const double[::1] lam, const double[::1] refs)
cpdef object first_samples(SampleBuffers buf, Py_ssize_t count)
cpdef void store_sample(SampleBuffers buf, Py_ssize_t k, double t, const double[:, ::1] R,
                        const double[:, :, ::1] A, const double[::1] Q, const double[::1] u,
                        const double[::1] ud, const double[::1] lam, const double[::1] refs,
                        const double[::1] work) noexcept nogil
cpdef void expand(const double[::1] lam, const int64_t[::1] kept, double[::1] out) noexcept nogil
cpdef void advance_pose(Layout L, const double[:, ::1] R, const double[:, :, ::1] A, const double[::1] Q,
                        const double[::1] dx, bint body_frame, double[:, ::1] R2, double[:, :, ::1] A2,
                        double[::1] Q2) noexcept nogil
cpdef int lu_factor(double[:, ::1] a, int[::1] piv) noexcept nogil
cpdef void lu_solve(const double[:, ::1] lu, const int[::1] piv, const double[::1] b, double[::1] x) noexcept nogil
cpdef void restrict(const double[:, ::1] M, const double[::1] f, const double[:, ::1] B, const double[:, ::1] BF,
                    const int64_t[::1] free, const int64_t[::1] kept, double[:, ::1] Mf, double[::1] ff,
                    double[:, ::1] Bk, double[:, ::1] BFk) noexcept nogil
cpdef void kkt_solve(const double[:, ::1] M, const double[::1] f, const double[:, ::1] B, const double[:, ::1] BF,
                     const double[::1] rhs, double[:, ::1] K, int[::1] piv, double[::1] z) noexcept nogil
cpdef Index1Workspace index1_workspace(Layout L, Py_ssize_t nfree, Py_ssize_t nkept)
cpdef void constraint_convection(Layout L, Evaluation W, Index1Workspace ws, const double[:, ::1] R,
                                 const double[:, :, ::1] A, const double[::1] Q, const double[::1] u, double t,
                                 const double[::1] refs, const int64_t[::1] kept, double[::1] gam) noexcept nogil
cpdef bint has_friction(Layout L) noexcept nogil
cpdef bint multipliers_settled(const double[::1] lam, const double[::1] lam_new) noexcept nogil
cpdef void index1_solve(Evaluation e, Index1Workspace ws, const double[::1] gam, const double[::1] u,
                        const int64_t[::1] free, const int64_t[::1] kept, double baumgarte, double[::1] ud,
                        double[::1] lam) noexcept nogil
cpdef void index1_accelerations(Layout L, Evaluation W, Index1Workspace ws, const double[:, ::1] R,
                                const double[:, :, ::1] A, const double[::1] Q, const double[::1] u, double t,
                                const double[::1] refs, const int64_t[::1] free, const int64_t[::1] kept,
                                double baumgarte, const double[::1] lam_guess, double[::1] ud,
                                double[::1] lam) noexcept nogil
cpdef tuple state_equations(Layout L, const double[:, ::1] R, const double[:, :, ::1] A, const double[::1] Q,
                            const double[::1] u, double t, const double[::1] lam, const double[::1] refs,
                            const int64_t[::1] free, const int64_t[::1] kept, bint solve)
