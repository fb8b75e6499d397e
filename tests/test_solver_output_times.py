"""Output samples at the asked times: every sample at exactly k / rate, taken from the stepper's own
interpolant inside the step that contains it, against an independent reference."""

import math

import numpy as np
from scipy.integrate import solve_ivp
from test_solver_integrate import AXIS_Y, pendulum

from sidprep.solver import RigidBody
from sidprep.solver.run import simulate

#: a sample's time equals k / rate to this, s
OUTPUT_TIME_TOL = 1e-12
#: halving the step divides the error of a second-order method by 4; accepted within
SECOND_ORDER_RATIO = (3.0, 5.0)
#: RK4 (interpolant of order 4 too) against the 1-DOF pendulum ODE at the output times, rad
RK4_ANGLE_TOL = 1e-9
#: pendulum: mass (kg), centre of mass on the body x axis (m), inertia about it (kg m^2)
MASS, XC, ICM = 2.0, 0.5, 0.02
T_END, RATE = 0.5, 100.0


def rod(s):
    b = s.add(RigidBody(MASS, (XC, 0, 0), np.diag([1e-3, ICM, ICM]), name="rod"))
    return b, b.marker(rotation=AXIS_Y)


def ode_angle(times):
    """The pendulum's angle at ``times`` from its 1-DOF equation (released horizontally)."""
    inertia = ICM + MASS * XC**2
    sol = solve_ivp(lambda t, y: [y[1], MASS * 9.81 * XC * np.cos(y[0]) / inertia], (0.0, T_END), [0.0, 0.0],
                    t_eval=times, rtol=1e-13, atol=1e-13, method="DOP853")
    return sol.y[0]


def run(settings):
    """(Result, name of the hinge) of the pendulum run with ``settings`` at RATE samples/s."""
    s, _, joint = pendulum(rod)
    return simulate(s, T_END, output_dt=1 / RATE, **settings), joint.name


def angle(settings):
    r, hinge = run(settings)
    return r.t, r.joints[hinge].coordinate


def test_genalpha_samples_at_k_over_rate_match_a_fine_run_to_second_order():
    k = np.arange(round(T_END * RATE) + 1)
    t, coarse = angle(dict(h=3e-4))
    assert t.size == k.size and np.max(np.abs(t - k / RATE)) <= OUTPUT_TIME_TOL
    _, half = angle(dict(h=1.5e-4))
    t_ref, fine = angle(dict(h=1e-5))
    assert np.max(np.abs(t_ref - k / RATE)) <= OUTPUT_TIME_TOL
    ratio = np.max(np.abs(coarse - fine)) / np.max(np.abs(half - fine))
    assert SECOND_ORDER_RATIO[0] < ratio < SECOND_ORDER_RATIO[1], ratio
    # and the fine run is the pendulum's own equation at those times
    assert np.max(np.abs(fine - ode_angle(k / RATE))) < np.max(np.abs(coarse - fine)) / 100


def test_rk4_samples_at_k_over_rate_match_the_pendulum_equation():
    k = np.arange(round(T_END * RATE) + 1)
    t, rk4 = angle(dict(h=3e-4, method="rk4", baumgarte=0.0))
    assert t.size == k.size and np.max(np.abs(t - k / RATE)) <= OUTPUT_TIME_TOL
    assert np.max(np.abs(rk4 - ode_angle(k / RATE))) < RK4_ANGLE_TOL


def test_the_output_rate_never_limits_the_step():
    """A fixed step is not cut to land on the output times (ceil(T_END / h) steps); error-controlled
    steps grow beyond the output interval, and a tighter rtol takes more of them (before the
    dense output, rtol 1e-3 and 1e-4 gave identical runs capped at the output interval)."""
    k = np.arange(round(T_END * RATE) + 1)
    for method in ("genalpha", "rk4"):
        assert run(dict(h=3e-4, method=method))[0].stats.steps == math.ceil(T_END / 3e-4)
    steps = {}
    for method, rtol in (("genalpha", 1e-3), ("genalpha", 1e-4), ("rk45", 1e-3), ("dop853", 1e-3)):
        r, _ = run(dict(h=1e-3, method=method, rtol=rtol))
        assert r.stats.h_max > 2 / RATE, (method, r.stats.h_max)
        assert np.max(np.abs(r.t - k / RATE)) <= OUTPUT_TIME_TOL
        steps[method, rtol] = r.stats.steps
    assert steps["genalpha", 1e-4] > steps["genalpha", 1e-3]


#: V(theta) se3_jacobian_solve(theta, v) = v, relative to |v| (se3_jacobian's own (t - sin t)/t^3
#: loses ~2e-13 just above SE3_SMALL_ANGLE, measured against 40-digit arithmetic)
SE3_INVERSE_RTOL = 1e-12


def test_the_dense_outputs_se3_increment_inverts_v_in_closed_form():
    """The dense output's translation increment V(theta)^-1 A0^T (R1 - R0) (se3.body_increment) in
    closed form: V applied to it (rotations.se3_jacobian, the forward formula) gives v back, for
    angles from 1e-9 rad over the series threshold to 3.1 rad."""
    from sidprep.solver.core.rotations import SE3_SMALL_ANGLE, se3_jacobian_matrix, solve_se3_jacobian

    rng = np.random.default_rng(7)
    for angle in (1e-9, 1e-6, 0.999 * SE3_SMALL_ANGLE, 1.001 * SE3_SMALL_ANGLE, 1e-3, 0.1, 1.0, 2.0, 3.1):
        for _ in range(5):
            theta, v = rng.standard_normal(3), rng.standard_normal(3)
            theta *= angle / np.linalg.norm(theta)
            back = se3_jacobian_matrix(theta) @ solve_se3_jacobian(theta, v)
            assert np.max(np.abs(back - v)) <= SE3_INVERSE_RTOL * np.max(np.abs(v)), angle
