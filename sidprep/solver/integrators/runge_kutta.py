"""Classic fourth-order Runge-Kutta (Kutta 1901), compiled: the one RK4 of the project.

    k1 = f(t, y),              k2 = f(t + h/2, y + h/2 k1),
    k3 = f(t + h/2, y + h/2 k2),  k4 = f(t + h, y + h k3),
    y_{n+1} = y_n + h/6 (k1 + 2 k2 + 2 k3 + k4)

The stages and their combination are ``rk4_stage`` and ``rk4_combine`` (compiled, cached): the
solver's own loops (integrators/explicit.py, absolute_nodal/kernels.py) call their right-hand
side by name between them, so that every loop is cached on disk (numba cannot cache a compiled
function that receives another as an argument).  ``rk4_step`` / ``rk4_fixed`` take any
``numba.njit`` function ``rhs(t, y, params) -> ydot`` as an argument (compiled per process, not
cached): for ad-hoc right-hand sides.  Local error O(h^5), global error O(h^4); exact for
solutions that are polynomials of degree <= 4 in t.
"""

from __future__ import annotations

import numpy as np

from sidprep.solver.equations.aot import jit_uncached
from sidprep.solver.equations.rotations import jit


@jit
def rk4_stage(y, h, k):  # pragma: no cover - compiled
    """The argument y + h k of a stage (h: the stage's fraction of the step times the step)."""
    return y + h * k


@jit
def rk4_combine(y, h, k1, k2, k3, k4):  # pragma: no cover - compiled
    """y_{n+1} = y_n + h/6 (k1 + 2 k2 + 2 k3 + k4) from the four stage slopes."""
    return y + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


@jit
def hermite(theta):  # pragma: no cover - compiled
    """The cubic Hermite basis (h00, h10, h01, h11) at theta in [0, 1]."""
    t2, t3 = theta * theta, theta * theta * theta
    return 2.0 * t3 - 3.0 * t2 + 1.0, t3 - 2.0 * t2 + theta, 3.0 * t2 - 2.0 * t3, t3 - t2


# not cached: a jitted ``rhs`` argument is a new type in every process, so a disk cache would
# only grow, never hit
@jit_uncached
def rk4_step(rhs, t, y, h, params):
    """One classic RK4 step.

    Parameters
    ----------
    rhs : numba-jitted callable ``rhs(t, y, params) -> ydot``, ydot of shape (n,)
    t : float, time at the start of the step (s)
    y : (n,) float array, state at ``t``
    h : float, step size (s)
    params : anything ``rhs`` accepts (tuple of arrays / floats)

    Returns
    -------
    (n,) float array, state at ``t + h``
    """
    half = 0.5 * h
    k1 = rhs(t, y, params)
    k2 = rhs(t + half, rk4_stage(y, half, k1), params)
    k3 = rhs(t + half, rk4_stage(y, half, k2), params)
    k4 = rhs(t + h, rk4_stage(y, h, k3), params)
    return rk4_combine(y, h, k1, k2, k3, k4)


@jit_uncached
def rk4_fixed(rhs, t0, y0, h, n_steps, every, params):
    """``n_steps`` fixed RK4 steps of size ``h`` from ``(t0, y0)``, sampled every ``every`` steps.

    Parameters
    ----------
    rhs : numba-jitted callable ``rhs(t, y, params) -> ydot``
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
    n_out = n_steps // every + 1
    t_out = np.empty(n_out)
    Y_out = np.empty((n_out, y0.shape[0]))
    y = y0.astype(np.float64).copy()
    t_out[0] = t0
    Y_out[0] = y
    k = 1
    for i in range(1, n_steps + 1):
        y = rk4_step(rhs, t0 + (i - 1) * h, y, h, params)
        if i % every == 0:
            t_out[k] = t0 + i * h
            Y_out[k] = y
            k += 1
    return t_out, Y_out
