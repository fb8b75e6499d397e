# Curves over time or a joint coordinate (curves.pyx): piecewise polynomials on row-major pointers
# (x (nx,) breakpoints, c (rows, nx - 1) coefficients, rows = degree + 1), the closed-form motion
# profiles of drivers and the mode shapes along a path.
from libc.stdint cimport int64_t

from sidprep.solver.core.records cimport Layout

#: motion kinds of the driver table (compile/layout.py)
cpdef enum:
    CONSTANT_SPEED = 0
    SMOOTH_START = 1
    TABULATED = 2

cdef double curve_value(const double* x, Py_ssize_t nx, const double* c, Py_ssize_t rows, double period, double at,
                        int derivative) noexcept nogil
cdef (double, double, double) motion_state(int64_t kind, const double* params,
                                           (const double*, Py_ssize_t, const double*, Py_ssize_t) curve,
                                           double t) noexcept nogil
cdef bint path_shapes(Layout L, Py_ssize_t first, Py_ssize_t nq, double s, double* point, double* phi, double* psi,
                      double* dpoint, double* dphi) noexcept nogil
