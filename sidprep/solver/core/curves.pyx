"""Curves over time or a joint coordinate, compiled: piecewise polynomials (tables, tabulated
motions) and the closed-form motion profiles of drivers (model/joints.py), and the mode shapes
along a path (the splines of compile/layout.py add_path).

A piecewise polynomial is stored as in scipy's PPoly: breakpoints x (k+1,), coefficients
c (degree+1, k): y = sum_i c[i, s] (x - x_s)^(degree - i) on [x_s, x_s+1], extrapolated with
the end pieces; a period > 0 wraps x into [x_0, x_0 + period).
"""

from libc.math cimport M_PI, cos, fmod, sin


cdef inline double int_power(double a, Py_ssize_t e) noexcept nogil:
    """a^e for an integer e >= 0 by repeated squaring."""
    cdef double r = 1.0
    while e != 0:
        if e & 1:
            r *= a
        e >>= 1
        a *= a
    return r


cdef inline double wrapped(double at, double x0, double period) noexcept nogil:
    """x0 + (at - x0) mod period, the remainder in [0, period) (floored, as Python's %)."""
    cdef double r = fmod(at - x0, period)
    if r < 0.0:
        r += period
    return x0 + r


cdef double curve_value(const double* x, Py_ssize_t nx, const double* c, Py_ssize_t rows, double period, double at,
                        int derivative) noexcept nogil:
    """Value (derivative 0), slope (1) or curvature (2) of the piecewise polynomial (x (nx,),
    c (rows, nx - 1) row-major) at ``at``."""
    cdef Py_ssize_t k = nx - 1, s = 0, deg = rows - 1, i, j, p
    cdef double d, factor, out = 0.0
    if period > 0.0:
        at = wrapped(at, x[0], period)
    while s < k - 1 and at >= x[s + 1]:
        s += 1
    d = at - x[0] if k == 0 else at - x[s]
    for i in range(deg + 1):
        p = deg - i
        if p < derivative:
            continue
        factor = 1.0
        for j in range(derivative):
            factor *= p - j
        out += factor * c[i * k + s] * int_power(d, p - derivative)
    return out


cdef (double, double, double) motion_state(int64_t kind, const double* params,
                                           (const double*, Py_ssize_t, const double*, Py_ssize_t) curve,
                                           double t) noexcept nogil:
    """(value, rate, acceleration) of a driver motion at time t.

    kind CONSTANT_SPEED: params [start, speed]; SMOOTH_START: [start, speed, ramp_time],
    speed ramped by (1 - cos(pi t / T)) / 2; TABULATED: the cubic spline curve = (x, nx, c, rows).
    """
    cdef const double* x = curve[0]
    cdef const double* c = curve[2]
    cdef Py_ssize_t nx = curve[1], rows = curve[3]
    cdef double start, w, ramp, s
    if kind == TABULATED:
        return (curve_value(x, nx, c, rows, 0.0, t, 0), curve_value(x, nx, c, rows, 0.0, t, 1),
                curve_value(x, nx, c, rows, 0.0, t, 2))
    start, w = params[0], params[1]
    if kind == CONSTANT_SPEED:
        return start + w * t, w, 0.0
    ramp = params[2]
    if t <= 0.0:
        return start, 0.0, 0.0
    if t < ramp:
        s = M_PI * t / ramp
        return (start + 0.5 * w * (t - ramp / M_PI * sin(s)), 0.5 * w * (1.0 - cos(s)),
                0.5 * w * M_PI / ramp * sin(s))
    return start + w * (t - 0.5 * ramp), w, 0.0



def motion_profile(int64_t kind, const double[::1] params, const double[::1] x, const double[:, ::1] c, double t):
    """(value, rate, acceleration) of motion_state for Python (compile/path_range.py): kind, params
    [start, speed, ramp_time] and the tabulated spline's breakpoints x (nx,) and coefficients
    c (degree + 1, nx - 1) as scipy's PPoly holds them."""
    if params.shape[0] < 3 or x.shape[0] < 2 or c.shape[1] != x.shape[0] - 1:
        raise ValueError("motion_profile: params (3,), x (nx >= 2,), c (degree + 1, nx - 1)")
    return motion_state(kind, &params[0], (&x[0], x.shape[0], &c[0, 0], c.shape[0]), t)

cdef bint path_shapes(Layout L, Py_ssize_t first, Py_ssize_t nq, double s, double* point, double* phi, double* psi,
                      double* dpoint, double* dphi) noexcept nogil:
    """Point (3,), Phi (3, nq), Psi (3, nq) (row-major) of a path (layout.add_path: 3 + 6 nq cubic
    curves from curve ``first`` on one grid of s) at arc length s (m), written into point, phi,
    psi, and the s-derivatives of the point and of Phi into dpoint, dphi (the deformed tangent is
    dpoint + dphi q); returns whether s is on the path (beyond its ends the end pieces are
    extrapolated; callers drop the load there)."""
    cdef const double* x = &L.curve_x[L.curve_meta[first, 0]]
    cdef Py_ssize_t nx = L.curve_meta[first, 1], lo = 0, hi = nx - 2, mid, comp, pieces
    cdef const double* c
    cdef double d, value, slope
    cdef bint on = x[0] <= s <= x[nx - 1]
    while lo < hi:  # the piece [x_lo, x_lo+1] holding s (the end pieces beyond the ends)
        mid = (lo + hi + 1) // 2
        if x[mid] <= s:
            lo = mid
        else:
            hi = mid - 1
    d = s - x[lo]
    for comp in range(3 + 6 * nq):
        pieces = L.curve_meta[first + comp, 1] - 1
        c = &L.curve_c[L.curve_meta[first + comp, 2]]  # (4, pieces) row-major
        value = ((c[lo] * d + c[pieces + lo]) * d + c[2 * pieces + lo]) * d + c[3 * pieces + lo]
        slope = (3.0 * c[lo] * d + 2.0 * c[pieces + lo]) * d + c[2 * pieces + lo]
        if comp < 3:
            point[comp], dpoint[comp] = value, slope
        elif comp < 3 + 3 * nq:
            phi[comp - 3] = value
            dphi[comp - 3] = slope
        else:
            psi[comp - 3 - 3 * nq] = value
    return on
