"""Classic RK4 (sidprep/solver/core/runge_kutta.pyx) against closed-form solutions."""

import numpy as np
import pytest

from sidprep.solver.core.runge_kutta import rk4_fixed, rk4_step

#: fourth order: the global error falls by 2^4 = 16 per halving of h, within 10 %
ORDER_RATIO, ORDER_RATIO_TOL = 16.0, 0.10
#: a cubic in t is integrated to round-off
EXACT_TOL = 1e-12


def _growth(t, y, params):
    """y' = a y cos(t): closed form y = y0 exp(a sin t)."""
    return params[0] * y * np.cos(t)


def _cubic(t, y, params):
    """y' = 3 c3 t^2 + 2 c2 t + c1: closed form y = y0 + c3 t^3 + c2 t^2 + c1 t."""
    c1, c2, c3 = params
    return np.full(y.shape[0], 3.0 * c3 * t * t + 2.0 * c2 * t + c1)


def _oscillator(t, y, params):
    """x'' = -w^2 x as a first-order system (x, v)."""
    w = params[0]
    return np.array([y[1], -w * w * y[0]])


def _growth_error(n):
    t_end, a = 2.0, 1.3
    t, Y = rk4_fixed(_growth, 0.0, np.array([1.0]), t_end / n, n, n, (a,))
    assert t[-1] == pytest.approx(t_end)
    return abs(Y[-1, 0] - np.exp(a * np.sin(t_end)))


def test_fourth_order_convergence():
    errors = [_growth_error(n) for n in (20, 40, 80, 160)]
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    assert np.all(np.abs(ratios / ORDER_RATIO - 1.0) < ORDER_RATIO_TOL), ratios


def test_oscillator_order_and_sampling():
    w, t_end = 2.0, 3.0
    errs = []
    for n in (64, 128):
        t, Y = rk4_fixed(_oscillator, 0.5, np.array([1.0, 0.0]), t_end / n, n, 4, (w,))
        assert len(t) == n // 4 + 1 and np.allclose(np.diff(t), 4 * t_end / n)
        exact = np.column_stack([np.cos(w * (t - 0.5)), -w * np.sin(w * (t - 0.5))])
        errs.append(np.max(np.abs(Y - exact)))
    assert abs(errs[0] / errs[1] / ORDER_RATIO - 1.0) < ORDER_RATIO_TOL


def test_exact_for_cubic_in_t():
    c = (0.7, -1.1, 2.3)
    t, Y = rk4_fixed(_cubic, -0.4, np.array([0.5, 2.0]), 0.37, 9, 1, c)
    exact = (c[2] * t**3 + c[1] * t**2 + c[0] * t) - (c[2] * t[0] ** 3 + c[1] * t[0] ** 2 + c[0] * t[0])
    assert np.max(np.abs(Y - (exact[:, None] + np.array([0.5, 2.0])))) < EXACT_TOL


def _linear(t, y, params):
    """y' = lam y."""
    return params[0] * y


def test_single_step_is_the_rk4_stability_polynomial():
    # one step of y' = lam y multiplies y by 1 + z + z^2/2 + z^3/6 + z^4/24, z = lam h
    lam, h = -2.5, 0.3
    z = lam * h
    y1 = rk4_step(_linear, 0.0, np.array([1.0, -2.0]), h, (lam,))
    amp = 1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24
    assert np.allclose(y1, amp * np.array([1.0, -2.0]), rtol=EXACT_TOL, atol=0)
