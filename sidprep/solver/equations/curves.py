"""Curves over time or a joint coordinate, compiled: piecewise polynomials (tables, tabulated
motions) and the closed-form motion profiles of drivers (model/joints.py).

A piecewise polynomial is stored as in scipy's PPoly: breakpoints x (k+1,), coefficients
c (degree+1, k): y = sum_i c[i, s] (x - x_s)^(degree - i) on [x_s, x_s+1], extrapolated with
the end pieces; a period > 0 wraps x into [x_0, x_0 + period).
"""

from __future__ import annotations

import numpy as np

from sidprep.solver.equations.rotations import jit

#: motion kinds of the driver table (layout.py)
CONSTANT_SPEED, SMOOTH_START, TABULATED = 0, 1, 2


@jit
def curve_value(x, c, period, at, derivative):  # pragma: no cover - compiled
    """Value (derivative 0), slope (1) or curvature (2) of the piecewise polynomial (x, c) at
    ``at``; c (degree+1, k)."""
    if period > 0.0:
        at = x[0] + (at - x[0]) % period
    k = x.shape[0] - 1
    s = 0
    while s < k - 1 and at >= x[s + 1]:
        s += 1
    d = at - x[0] if k == 0 else at - x[s]
    deg = c.shape[0] - 1
    out = 0.0
    for i in range(deg + 1):
        p = deg - i
        if p < derivative:
            continue
        factor = 1.0
        for j in range(derivative):
            factor *= p - j
        out += factor * c[i, s] * d ** (p - derivative)
    return out


@jit
def motion_state(kind, params, x, c, t):  # pragma: no cover - compiled
    """(value, rate, acceleration) of a driver motion at time t.

    kind CONSTANT_SPEED: params [start, speed]; SMOOTH_START: [start, speed, ramp_time],
    speed ramped by (1 - cos(pi t / T)) / 2; TABULATED: the cubic spline (x, c).
    """
    if kind == TABULATED:
        return curve_value(x, c, 0.0, t, 0), curve_value(x, c, 0.0, t, 1), curve_value(x, c, 0.0, t, 2)
    start, w = params[0], params[1]
    if kind == CONSTANT_SPEED:
        return start + w * t, w, 0.0
    ramp = params[2]
    if t <= 0.0:
        return start, 0.0, 0.0
    if t < ramp:
        s = np.pi * t / ramp
        return (start + 0.5 * w * (t - ramp / np.pi * np.sin(s)), 0.5 * w * (1.0 - np.cos(s)),
                0.5 * w * np.pi / ramp * np.sin(s))
    return start + w * (t - 0.5 * ramp), w, 0.0


@jit
def path_shapes(curve_x, curve_c, curve_meta, first, nq, s):  # pragma: no cover - compiled
    """Point (3,), Phi (3, nq), Psi (3, nq) of a path (layout.add_path: 3 + 6 nq cubic curves
    from curve ``first`` on one grid of s) at arc length s (m), whether s is on the path
    (beyond its ends the end pieces are extrapolated; callers drop the load there), and the
    s-derivatives of the point and of Phi (the deformed tangent is dpoint + dphi q)."""
    meta = curve_meta[first]
    x = curve_x[meta[0]:meta[0] + meta[1]]
    point, phi, psi = np.zeros(3), np.zeros((3, nq)), np.zeros((3, nq))
    dpoint, dphi = np.zeros(3), np.zeros((3, nq))
    on = x[0] <= s <= x[-1]
    lo, hi = 0, x.shape[0] - 2
    while lo < hi:  # the piece [x_lo, x_lo+1] holding s (the end pieces beyond the ends)
        mid = (lo + hi + 1) // 2
        if x[mid] <= s:
            lo = mid
        else:
            hi = mid - 1
    d = s - x[lo]
    for comp in range(3 + 6 * nq):
        m = curve_meta[first + comp]
        c = curve_c[m[2]:m[2] + 4 * (m[1] - 1)].reshape((4, m[1] - 1))
        value = ((c[0, lo] * d + c[1, lo]) * d + c[2, lo]) * d + c[3, lo]
        slope = (3.0 * c[0, lo] * d + 2.0 * c[1, lo]) * d + c[2, lo]
        if comp < 3:
            point[comp], dpoint[comp] = value, slope
        elif comp < 3 + 3 * nq:
            phi[(comp - 3) // nq, (comp - 3) % nq] = value
            dphi[(comp - 3) // nq, (comp - 3) % nq] = slope
        else:
            psi[(comp - 3 - 3 * nq) // nq, (comp - 3 - 3 * nq) % nq] = value
    return point, phi, psi, on, dpoint, dphi
