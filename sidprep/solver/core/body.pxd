# The FFR equations of one body (body.pyx; sid-spec 5.2).  A body's SID arrays live in one flat
# float array F (the layout's body_F) at the offsets off (N_TERMS,) (the layout's body_off row;
# -1: absent), its switched-on terms in flags (N_FLAGS,); arrays in F are row-major.  Matrices
# written by a kernel have their rows ld apart.
from libc.stdint cimport int64_t

#: columns of the offsets table (compile/layout.py pack_terms): where each term of BodyTerms starts in F
cpdef enum:
    MD0 = 0
    I0 = 1
    ME = 2
    KE = 3
    MD1 = 4
    I1 = 5
    CT0 = 6
    CT1 = 7
    CR0 = 8
    CR1 = 9
    GR0 = 10
    GE = 11
    OE0 = 12
    OE1 = 13
    KS0 = 14
    KS1 = 15
    DE = 16
    P2 = 17
    N_TERMS = 18

#: columns of the flags table: term switched on
cpdef enum:
    F_INERTIA = 0
    F_CT1 = 1
    F_CR1 = 2
    F_CORIOLIS = 3
    F_OE0 = 4
    F_OE1 = 5
    F_PRELOAD = 6
    F_DAMPING = 7
    F_GRAVITY = 8
    F_SECOND = 9
    N_FLAGS = 10


cdef inline const double* block(const double* F, int64_t o) noexcept nogil:
    """The array stored row-major in F from offset o."""
    return F + o


cdef void add_first_order(double* x, Py_ssize_t ld, const double* x1f, const double* q, Py_ssize_t nq) noexcept nogil
cdef void pair_contraction(const double* p, const double* x, const double* y, Py_ssize_t nq,
                           double* out) noexcept nogil
cdef void inertia_terms(const double* F, const int64_t* off, const int64_t* flags, Py_ssize_t nq, const double* q,
                        double* md, double* inertia, double* ct, double* cr, Py_ssize_t ld) noexcept nogil
cdef void body_equations(const double* F, const int64_t* off, const int64_t* flags, double mass, Py_ssize_t nq,
                         const double* q, const double* qd, const double* w, const double* gk, double* m,
                         Py_ssize_t ld, double* h) noexcept nogil
cdef void gravity_md(const double* F, const int64_t* off, Py_ssize_t nq, const double* q, double* md) noexcept nogil
cdef void add_gravity_force(const double* F, const int64_t* off, const int64_t* flags, double mass, Py_ssize_t nq,
                            const double* q, const double* gk, double* out) noexcept nogil
cdef (double, double) body_potentials(const double* F, const int64_t* off, const int64_t* flags, double mass,
                                      Py_ssize_t nq, const double* r, const double* A, const double* q,
                                      const double* g) noexcept nogil
