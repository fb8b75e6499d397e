"""Classic fourth-order Runge-Kutta (Kutta 1901), compiled: the one RK4 of the project.

    k1 = f(t, y),              k2 = f(t + h/2, y + h/2 k1),
    k3 = f(t + h/2, y + h/2 k2),  k4 = f(t + h, y + h k3),
    y_{n+1} = y_n + h/6 (k1 + 2 k2 + 2 k3 + k4)

The stages and their combination are ``rk4_stage`` and ``rk4_combine``: the solver's compiled
loops (explicit.pyx, absolute_nodal) call their own right-hand side between them.  ``rk4_step`` /
``rk4_fixed`` take any Python callable ``rhs(t, y, params) -> ydot``: for ad-hoc right-hand
sides.  Local error O(h^5), global error O(h^4); exact for solutions that are polynomials of
degree <= 4 in t.
"""

import numpy as np


cpdef void rk4_stage(const double[::1] y, double h, const double[::1] k, double[::1] out) noexcept nogil:
    """The argument out = y + h k (n,) of a stage (h: the stage's fraction of the step times the
    step, s)."""
    cdef Py_ssize_t i
    for i in range(y.shape[0]):
        out[i] = y[i] + h * k[i]


cpdef void rk4_combine(const double[::1] y, double h, const double[::1] k1, const double[::1] k2,
                       const double[::1] k3, const double[::1] k4, double[::1] out) noexcept nogil:
    """out = y_{n+1} = y_n + h/6 (k1 + 2 k2 + 2 k3 + k4) (n,) from the four stage slopes."""
    cdef Py_ssize_t i
    cdef double sixth = h / 6.0
    for i in range(y.shape[0]):
        out[i] = y[i] + sixth * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])


cpdef (double, double, double, double) hermite(double theta) noexcept nogil:
    """The cubic Hermite basis (h00, h10, h01, h11) at theta in [0, 1]."""
    cdef double t2 = theta * theta
    cdef double t3 = theta * theta * theta
    return 2.0 * t3 - 3.0 * t2 + 1.0, t3 - 2.0 * t2 + theta, 3.0 * t2 - 2.0 * t3, t3 - t2


def rk4_step(rhs, double t, y, double h, params):
    """One classic RK4 step.

    Parameters
    ----------
    rhs : callable ``rhs(t, y, params) -> ydot``, ydot of shape (n,)
    t : float, time at the start of the step (s)
    y : (n,) float array, state at ``t``
    h : float, step size (s)
    params : anything ``rhs`` accepts (tuple of arrays / floats)

    Returns
    -------
    (n,) float array, state at ``t + h``
    """
    cdef double half = 0.5 * h
    y = np.ascontiguousarray(y, dtype=np.float64)
    stage = np.empty_like(y)
    k1 = np.ascontiguousarray(rhs(t, y, params), dtype=np.float64)
    rk4_stage(y, half, k1, stage)
    k2 = np.ascontiguousarray(rhs(t + half, stage, params), dtype=np.float64)
    rk4_stage(y, half, k2, stage)
    k3 = np.ascontiguousarray(rhs(t + half, stage, params), dtype=np.float64)
    rk4_stage(y, h, k3, stage)
    k4 = np.ascontiguousarray(rhs(t + h, stage, params), dtype=np.float64)
    out = np.empty_like(y)
    rk4_combine(y, h, k1, k2, k3, k4, out)
    return out


def rk4_fixed(rhs, double t0, y0, double h, Py_ssize_t n_steps, Py_ssize_t every, params):
    """``n_steps`` fixed RK4 steps of size ``h`` from ``(t0, y0)``, sampled every ``every`` steps.

    Parameters
    ----------
    rhs : callable ``rhs(t, y, params) -> ydot``
    t0 : float, start time (s)
    y0 : (n,) float array, initial state
    h : float, step size (s)
    n_steps : int >= 0, number of steps
    every : int >= 1, output interval in steps (the start is always sampled, the last step too
        when ``n_steps`` is a multiple of ``every``)
    params : passed to ``rhs`` unchanged

    Returns
    -------
    t_out : (n_steps // every + 1,) sample times (s), ``t0 + k * every * h``
    Y_out : (n_steps // every + 1, n) states at ``t_out``
    """
    if every < 1:
        raise ValueError("rk4_fixed: every must be >= 1")
    cdef Py_ssize_t n_out = n_steps // every + 1, i, k = 1
    y = np.array(y0, dtype=np.float64)
    t_out = np.empty(n_out)
    Y_out = np.empty((n_out, y.shape[0]))
    t_out[0] = t0
    Y_out[0] = y
    for i in range(1, n_steps + 1):
        y = rk4_step(rhs, t0 + (i - 1) * h, y, h, params)
        if i % every == 0:
            t_out[k] = t0 + i * h
            Y_out[k] = y
            k += 1
    return t_out, Y_out
