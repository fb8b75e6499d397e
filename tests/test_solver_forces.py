"""Every force element and driver runs in the compiled loop and matches an independent
reference: a second formulation (scipy's ODE solvers on the one-degree-of-freedom equation),
closed forms, or conservation laws.  Also the RK4 convergence order on a constrained system."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.interpolate import CubicSpline

from sidprep.solver import (ConstantSpeed, Driver, JointForce, JointFriction, PointTorque, Prismatic, Revolute,
                            RigidBody, SpringDamper, System, TabulatedMotion, Table, bump_stop)
from sidprep.solver.run import simulate

ALONG_X = np.array([0.0, np.pi / 2, 0.0])  # rotation vector taking z to x

#: stick-slip block against scipy Radau (rtol 1e-10) on the same regularised law, m
STICK_SLIP_ATOL = 2e-5
#: bump stop: energy conservation (relative to the impact energy) and peak penetration (relative)
BUMP_ENERGY_RTOL, BUMP_PENETRATION_RTOL = 1e-4, 1e-3
#: damped rotational oscillator against the closed form, rad
OSCILLATOR_ATOL = 1e-5
#: torque ramp against the closed form omega = T1 t^2 / (2 I t1), rad/s (the generalised-alpha
#: start a_0 = ud_0 leaves a constant offset of 5.5e-8 rad/s at h = 1 ms; the ramp reaches 20 rad/s)
RAMP_ATOL = 1e-7
#: tabulated driver against scipy's CubicSpline of the same table, rad
SPLINE_ATOL = 1e-9
#: driver torque against I theta'' of the spline, relative to its peak (generalised-alpha's
#: accelerations lag the spline's kinks at the knots by O(h))
EFFORT_RTOL = 5e-3
#: RK4 order: the error ratio per halving of h is 16 +- 10 % (measured 15.1 and 15.8 at h = 5,
#: 2.5, 1.25 ms; errors 2.0e-9, 1.3e-10, 8.5e-12 rad)
RK4_RATIO, RK4_RATIO_TOL = 16.0, 0.1


def slider(s, name, mass, x0=0.0, v0=0.0):
    """A block on a prismatic joint along x."""
    block = s.add(RigidBody(mass, name=name, position=(x0, 0, 0), velocity=(v0, 0, 0)))
    joint = s.add(Prismatic(s.ground.marker(rotation=ALONG_X), block.marker(rotation=ALONG_X), name=f"{name}_slide"))
    return block, joint


def test_friction_stick_slip_block_matches_the_one_dof_equation():
    """A block (m) with Coulomb friction mu N tanh(v / eps) pulled through a spring (k) by a sled
    driven at constant speed V: it sticks and slips.  Reference: m x'' = k (V t - x) - mu N
    tanh(x' / eps), integrated by scipy's Radau."""
    m, k, mu, normal, speed, eps = 1.0, 100.0, 0.5, 10.0, 0.1, 1e-3
    s = System(gravity=(0, 0, 0))
    block, slide = slider(s, "block", m)
    sled, track = slider(s, "sled", 1.0, x0=0.5)
    s.add(Driver(track, ConstantSpeed(speed, 0.5), name="pull"))
    s.add(SpringDamper(block.marker(), sled.marker(), stiffness=k, length=0.5))
    s.add(JointFriction(slide, mu, preload=normal, regularisation=eps))
    r = simulate(s, 1.5, h=2e-4, output_dt=0.01, rho_inf=0.9)
    ref = solve_ivp(lambda t, y: [y[1], (k * (speed * t - y[0]) - mu * normal * np.tanh(y[1] / eps)) / m],
                    (0.0, 1.5), [0.0, 0.0], method="Radau", rtol=1e-10, atol=1e-12, t_eval=r.t)
    x = r.bodies["block"].position[:, 0]
    assert np.max(np.abs(x - ref.y[0])) < STICK_SLIP_ATOL
    v = r.bodies["block"].velocity[:, 0]
    assert np.min(v) < 1e-3 * speed and np.max(v) > 1.5 * speed          # it really sticks and slips
    work = r.energy["external"][-1]                                       # the sled's driver work
    assert r.energy["total"][-1] - r.energy["total"][0] == pytest.approx(0.0, abs=2e-4 * work)


@pytest.mark.parametrize("exponent", [1.0, 1.5])
def test_bump_stop_impact_conserves_energy_and_reaches_the_closed_form_penetration(exponent):
    """A mass runs at v0 into an undamped stop k pen^e: kinetic + stop energy is conserved, the
    peak penetration is ((e+1) m v0^2 / (2 k))^(1/(e+1)) and it rebounds at -v0."""
    m, v0, k, clearance = 2.0, 1.0, 1e5, 0.05
    s = System(gravity=(0, 0, 0))
    block, _ = slider(s, "block", m, x0=1.0, v0=-v0)
    s.add(SpringDamper(s.ground.marker(), block.marker(), length=1.0, law=bump_stop(clearance, k, exponent)))
    r = simulate(s, 0.12, h=2e-5, rho_inf=1.0)
    e = r.energy
    impact = 0.5 * m * v0**2
    assert np.max(np.abs(e["total"] - e["total"][0])) < BUMP_ENERGY_RTOL * impact
    assert np.max(e["spring"]) == pytest.approx(impact, rel=1e-3)          # all kinetic energy stored once
    penetration = -np.min(r.bodies["block"].position[:, 0] - 1.0) - clearance
    expected = ((exponent + 1) * m * v0**2 / (2 * k)) ** (1 / (exponent + 1))
    assert penetration == pytest.approx(expected, rel=BUMP_PENETRATION_RTOL)
    assert r.bodies["block"].velocity[-1, 0] == pytest.approx(v0, rel=1e-4)


def test_bump_stop_damping_dissipates_what_the_rebound_loses():
    m, v0, k, c = 2.0, 1.0, 1e5, 50.0
    s = System(gravity=(0, 0, 0))
    block, _ = slider(s, "block", m, x0=1.0, v0=-v0)
    s.add(SpringDamper(s.ground.marker(), block.marker(), length=1.0, law=bump_stop(0.05, k, 1.0, c)))
    r = simulate(s, 0.12, h=2e-5, rho_inf=1.0)
    v1 = r.bodies["block"].velocity[-1, 0]
    assert 0 < v1 < 0.99 * v0
    assert r.energy["dissipated"][-1] == pytest.approx(0.5 * m * (v0**2 - v1**2), rel=1e-3)


def wheel(s, inertia, omega0=0.0):
    w = s.add(RigidBody(1.0, inertia=[inertia, inertia, inertia], name="wheel", omega=(0, 0, omega0)))
    hub = s.add(Revolute(s.ground.marker(), w.marker(), name="hub"))
    return w, hub


def test_rotational_spring_damper_joint_force_is_a_damped_oscillator():
    inertia, k, c, theta0 = 0.05, 20.0, 0.1, 0.3
    s = System(gravity=(0, 0, 0))
    _, hub = wheel(s, inertia)
    s.add(JointForce(hub, stiffness=k, damping=c, reference=theta0))
    r = simulate(s, 1.0, h=1e-4, rho_inf=1.0)
    wn, zeta = np.sqrt(k / inertia), c / (2 * np.sqrt(k * inertia))
    wd = wn * np.sqrt(1 - zeta**2)
    t = r.t
    expected = theta0 * (1 - np.exp(-zeta * wn * t) * (np.cos(wd * t) + zeta * wn / wd * np.sin(wd * t)))
    assert np.max(np.abs(r.joints["hub"].coordinate - expected)) < OSCILLATOR_ATOL
    assert np.max(np.abs(r.energy["total"] - r.energy["total"][0])) < 1e-6 * k * theta0**2


def test_tabulated_torque_ramp_spins_a_wheel_up_as_the_closed_form():
    inertia, torque, t1 = 0.05, 2.0, 1.0
    s = System(gravity=(0, 0, 0))
    w, hub = wheel(s, inertia)
    s.add(PointTorque(w.marker(), Table([0.0, t1], [0.0, torque]), direction=(0, 0, 1.0)))
    r = simulate(s, t1, h=1e-3, output_dt=0.1)
    assert np.max(np.abs(r.joints["hub"].rate - torque * r.t**2 / (2 * inertia * t1))) < RAMP_ATOL
    assert r.energy["external"][-1] == pytest.approx(r.energy["kinetic"][-1], rel=1e-6)


def test_tabulated_driver_follows_the_spline_and_its_torque_is_i_theta_ddot():
    inertia = 0.05
    times, values = [0.0, 0.3, 0.6, 1.0], [0.0, 0.4, 0.2, 1.0]
    s = System(gravity=(0, 0, 0))
    _, hub = wheel(s, inertia)
    s.add(Driver(hub, TabulatedMotion(times, values), name="motor"))
    r = simulate(s, 1.0, h=1e-3, output_dt=0.05)
    spline = CubicSpline(times, values)
    assert np.max(np.abs(r.joints["hub"].coordinate - spline(r.t))) < SPLINE_ATOL
    torque = inertia * spline(r.t, 2)
    assert np.max(np.abs(r.joints["motor"].effort - torque)) < EFFORT_RTOL * np.max(np.abs(torque))


def test_rk4_on_a_constrained_pendulum_converges_at_fourth_order():
    """Classic RK4 (index-1 form, Baumgarte) on a rigid pendulum against scipy DOP853 on the
    one-degree-of-freedom equation: the angle error falls 16-fold per halving of h."""
    mass, xc, icm = 2.0, 0.5, 0.02
    inertia = icm + mass * xc**2
    ref = solve_ivp(lambda t, y: [y[1], -mass * 9.81 * xc * np.cos(y[0]) / inertia], (0.0, 1.0), [0.0, 0.0],
                    method="DOP853", rtol=1e-13, atol=1e-13).y[0, -1]
    errors = []
    for h in (0.005, 0.0025, 0.00125):
        s = System(gravity=(0, -9.81, 0))
        rod = s.add(RigidBody(mass, (xc, 0, 0), np.diag([1e-3, icm, icm]), name="rod"))
        s.add(Revolute(s.ground.marker(), rod.marker(), name="pivot"))
        r = simulate(s, 1.0, method="rk4", h=h, baumgarte=0.0)
        errors.append(abs(r.joints["pivot"].coordinate[-1] - ref))
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    assert np.all(np.abs(ratios / RK4_RATIO - 1) < RK4_RATIO_TOL), ratios
