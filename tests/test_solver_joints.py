"""Joints, drivers and force elements: exact velocity rows, a closed loop, statics, friction."""

import numpy as np
import pytest
from test_solver_bodies import bar_sid

from sidprep.solver import (JOINT_TYPES, ConstantSpeed, Driver, FlexibleBody, JointFriction, PointForce, Prismatic,
                            Revolute, RigidBody, SmoothStart, SolverSettings, SpringDamper, System, Table, bump_stop)
from sidprep.solver.integrators.base import evaluate
from sidprep.solver.integrators.base import moved_pose
from sidprep.solver.integrators.initial import assemble_positions
from sidprep.solver.run import Run
from sidprep.solver.run import simulate

#: central-difference check of the velocity rows (step 1e-6)
FD_TOL = 1e-8
#: the same on a marker moving along a Beam's axis: the path's cubic splines and the central
#: differences of its frame (step 1e-6 m) leave ~1e-8
PATH_FD_TOL = 1e-7
#: position-level constraint drift of the index-3 integrator (m, rad)
DRIFT_TOL = 1e-10
#: quasi-static slider-crank: dynamic effects are ~1e-7 of the statics
STATICS_RTOL = 1e-4

ALONG_X = np.array([0.0, np.pi / 2, 0.0])  # rotation vector taking z to x


def rows_and_dg_dt(s, rng, frozen=slice(0, 0), t=0.5, eps=1e-6):
    """(dg/dt by central differences of the compiled g along the motion, B u + b_t, b_t) at the
    assembled positions of System s and random velocities u (zero at ``frozen``)."""
    run = Run(s, 1.0, SolverSettings())
    R, A, Q, _ = run.initial_positions()
    R, A, Q = assemble_positions(run.L, R, A, Q, t, run.refs, run.kept, run.weights, run.names, run.length)
    u = rng.normal(size=int(run.L.uoff[-1]))
    u[frozen] = 0.0
    lam = np.zeros(len(run.names))
    out = evaluate(run.L, R, A, Q, u, t, lam, run.refs)

    def g(sign):
        pose = moved_pose(run.L, R, A, Q, sign * eps * u)
        return evaluate(run.L, *pose, u, t + sign * eps, lam, run.refs)[2]

    return (g(1) - g(-1)) / (2 * eps), out[3] @ u + out[5], out[5]


@pytest.mark.parametrize("kind", sorted(JOINT_TYPES))
def test_constraint_rows_are_the_time_derivative_of_g(kind):
    """B u + b_t equals dg/dt along the motion (central differences of the compiled g); on_path:
    a rigid body sliding along the axis of a Beam (a path marker following it)."""
    rng = np.random.default_rng(7)
    s = System(gravity=(0, 0, 0))
    if kind == "on_path":
        from sidprep.reduction.beam import beam_options_from_table, beam_sid

        beam = s.add(FlexibleBody(beam_sid(beam_options_from_table(
            {"length": 2.0, "section": "rectangle:0.05,0.02", "bc": "pinned-pinned", "modes": "xz:1-3,xy:1"}, "t")),
            name="beam", q0=rng.normal(size=4) * 1e-3, rotation=rng.normal(size=3) * 0.3))
        marker1 = beam.path_marker("axis", rotation=ALONG_X)
        b2 = s.add(RigidBody(1.0, name="b2", position=beam.rotation0 @ np.array([0.7, 0.0, 0.0]),
                             rotation=rng.normal(size=3)))
    else:
        b1 = s.add(RigidBody(1.0, name="b1", position=rng.normal(size=3), rotation=rng.normal(size=3)))
        marker1 = b1.marker(rng.normal(size=3), rng.normal(size=3))
        b2 = s.add(RigidBody(1.0, name="b2", position=rng.normal(size=3), rotation=rng.normal(size=3)))
    joint = s.add(JOINT_TYPES[kind](marker1, b2.marker(rng.normal(size=3) * 0.01, rng.normal(size=3))))
    if joint.coordinate_kind and kind != "on_path":     # an on_path joint is moved by its path marker
        s.add(Driver(joint, ConstantSpeed(0.3)))
    dg_dt, rows, _ = rows_and_dg_dt(s, rng)
    assert np.allclose(dg_dt, rows, atol=FD_TOL)



@pytest.mark.parametrize("kind", sorted(set(JOINT_TYPES) - {"on_path"}))
def test_rows_on_a_marker_moving_along_a_path_carry_its_motion_in_b_t(kind):
    """B u + b_t equals dg/dt along the motion when marker 1 travels along the deformed,
    twisted axis of a Beam at s(t) a carriage guided on a moving point): b_t
    holds the point's convective velocity s_dot dp/ds and its frame's turning rate.  (The frame's
    modal columns JR = A Psi are exact to first order in q only, like those of node markers: the
    SID's rotations are linear; here the modal rates are zero.)"""
    from sidprep.reduction.beam import beam_options_from_table, beam_sid

    rng = np.random.default_rng(11)
    s = System(gravity=(0, 0, 0))
    beam = s.add(FlexibleBody(beam_sid(beam_options_from_table(
        {"length": 2.0, "section": "rectangle:0.05,0.02", "bc": "pinned-pinned", "modes": "xz:1-3,xy:1,torsion:1"},
        "t")), name="beam", q0=rng.normal(size=5) * 3e-2, rotation=rng.normal(size=3) * 0.3))
    marker1 = beam.path_marker("axis", ConstantSpeed(0.7, 0.4), rotation=rng.normal(size=3))
    b2 = s.add(RigidBody(1.0, name="b2", position=rng.normal(size=3), rotation=rng.normal(size=3)))
    joint = s.add(JOINT_TYPES[kind](marker1, b2.marker(rng.normal(size=3) * 0.01, rng.normal(size=3))))
    if joint.coordinate_kind:
        s.add(Driver(joint, ConstantSpeed(0.3)))
    dg_dt, rows, bt = rows_and_dg_dt(s, rng, frozen=slice(6, 11))   # the beam's modal rates zero
    assert np.abs(bt).max() > 1e-2                                      # the motion is in b_t
    assert np.allclose(dg_dt, rows, atol=PATH_FD_TOL)


def slider_crank(crank=0.1, rod=0.3, theta0=0.5, speed=0.1, force=-100.0, flexible_rod=False):
    """Planar slider-crank of four 3D joints (3 rows redundant) driven at constant speed."""
    s = System(gravity=(0, 0, 0))
    pin = crank * np.array([np.cos(theta0), np.sin(theta0), 0.0])
    x_piston = pin[0] + np.sqrt(rod**2 - pin[1] ** 2)
    phi = np.arctan2(-pin[1], x_piston - pin[0])
    c = s.add(RigidBody(0.01, (crank / 2, 0, 0), [1e-6, 1e-6, 1e-6], name="crank", rotation=(0, 0, theta0)))
    if flexible_rod:
        r = s.add(FlexibleBody(bar_sid(length=rod, mass=0.01), name="rod", position=pin, rotation=(0, 0, phi)))
        m_big, m_small = r.node_marker(0), r.node_marker(1)
    else:
        r = s.add(RigidBody(0.01, (rod / 2, 0, 0), [1e-6, 1e-6, 1e-6], name="rod", position=pin,
                            rotation=(0, 0, phi)))
        m_big, m_small = r.marker(), r.marker((rod, 0, 0))
    p = s.add(RigidBody(0.01, (0, 0, 0), [1e-6, 1e-6, 1e-6], name="piston", position=(x_piston, 0, 0)))
    crank_joint = s.add(Revolute(s.ground.marker(), c.marker(), name="main"))
    s.add(Revolute(c.marker((crank, 0, 0)), m_big, name="crankpin"))
    s.add(Revolute(m_small, p.marker(), name="wristpin"))
    slide = s.add(Prismatic(s.ground.marker(rotation=ALONG_X), p.marker(rotation=ALONG_X), name="slide"))
    s.add(Driver(crank_joint, ConstantSpeed(speed, theta0), name="motor"))
    s.add(PointForce(p.marker(), (force, 0.0, 0.0)))
    return s, crank_joint, slide


def piston_rate(theta, crank, rod):
    """ds/dtheta of the slider-crank."""
    sn, cs = np.sin(theta), np.cos(theta)
    return -crank * sn - crank**2 * sn * cs / np.sqrt(rod**2 - crank**2 * sn**2)


@pytest.mark.parametrize("flexible_rod", [False, True])
def test_slider_crank_closed_loop_statics(flexible_rod):
    """Rigid: the kinematic statics exactly.  Flexible rod (stiff, started in quasi-static
    equilibrium): its compliance changes the geometry by ~1e-3 relative."""
    s, main, slide = slider_crank(flexible_rod=flexible_rod)
    r = simulate(s, 2.0, h=1e-2, output_dt=0.1, static_start=flexible_rod, rho_inf=0.5)
    rtol = 5e-3 if flexible_rod else STATICS_RTOL
    assert np.max(r.constraint_error) < DRIFT_TOL
    if not flexible_rod:
        assert len(r.stats.dropped_constraint_rows) == 3
    theta = r.joints["main"].coordinate
    assert np.allclose(theta, 0.5 + 0.1 * r.t, atol=1e-9)
    # virtual work: motor torque dtheta + F ds = 0
    torque = r.joints["motor"].effort
    expected = 100.0 * piston_rate(theta, 0.1, 0.3)
    assert np.allclose(torque, expected, rtol=rtol, atol=rtol * 100 * 0.1)
    # whole mechanism in equilibrium: ground reactions balance the piston force
    total = r.joints["main"].force + r.joints["slide"].force + np.array([-100.0, 0, 0])
    assert np.max(np.abs(total)) < rtol * 100


def test_prismatic_friction_decelerates_at_mu_n_over_m():
    m, mu, normal, v0 = 2.0, 0.3, 50.0, 1.0
    s = System(gravity=(0, 0, 0))
    block = s.add(RigidBody(m, name="block", velocity=(v0, 0, 0)))
    slide = s.add(Prismatic(s.ground.marker(rotation=ALONG_X), block.marker(rotation=ALONG_X)))
    s.add(JointFriction(slide, mu, preload=normal, regularisation=1e-4))
    r = simulate(s, 0.1, h=1e-3)
    v = r.bodies["block"].velocity[:, 0]
    assert np.allclose(v, v0 - mu * normal / m * r.t, rtol=1e-6)
    assert r.energy["dissipated"][-1] == pytest.approx(0.5 * m * (v0**2 - v[-1] ** 2), rel=1e-4)


def test_revolute_friction_torque_decelerates_a_wheel():
    inertia, mu, normal, radius, w0 = 0.05, 0.2, 100.0, 0.02, 5.0
    s = System(gravity=(0, 0, 0))
    wheel = s.add(RigidBody(1.0, inertia=[inertia, inertia, inertia], name="wheel", omega=(0, 0, w0)))
    hub = s.add(Revolute(s.ground.marker(), wheel.marker()))
    s.add(JointFriction(hub, mu, radius=radius, preload=normal, regularisation=1e-4))
    r = simulate(s, 0.2, h=1e-3)
    assert np.allclose(r.joints[hub.name].rate, w0 - mu * normal * radius / inertia * r.t, rtol=1e-6)


def test_spring_mass_frequency_and_bump_stop():
    m, k = 0.5, 200.0
    s = System(gravity=(0, 0, 0))
    mass = s.add(RigidBody(m, name="mass", position=(1.0, 0, 0), velocity=(0.1, 0, 0)))
    s.add(Prismatic(s.ground.marker(rotation=ALONG_X), mass.marker(rotation=ALONG_X)))
    s.add(SpringDamper(s.ground.marker(), mass.marker(), stiffness=k, length=1.0))
    r = simulate(s, 1.0, h=1e-3, rho_inf=1.0)
    x = r.bodies["mass"].position[:, 0] - 1.0
    omega = np.sqrt(k / m)
    assert np.allclose(x, 0.1 / omega * np.sin(omega * r.t), atol=2e-3 * 0.1 / omega)
    assert np.ptp(r.energy["total"]) < 1e-6 * r.energy["kinetic"][0]
    # without a length the spring is unstretched at the start distance (1 m here): the same motion
    s1 = System(gravity=(0, 0, 0))
    mass1 = s1.add(RigidBody(m, name="mass", position=(1.0, 0, 0), velocity=(0.1, 0, 0)))
    s1.add(Prismatic(s1.ground.marker(rotation=ALONG_X), mass1.marker(rotation=ALONG_X)))
    spring = s1.add(SpringDamper(s1.ground.marker(), mass1.marker(), stiffness=k))
    r1 = simulate(s1, 1.0, h=1e-3, rho_inf=1.0)
    assert spring.length is None and np.array_equal(r1.bodies["mass"].position, r.bodies["mass"].position)
    # a stiff stop 2 mm short of the amplitude limits the compression
    s2 = System(gravity=(0, 0, 0))
    mass2 = s2.add(RigidBody(m, name="mass", position=(1.0, 0, 0), velocity=(-0.1, 0, 0)))
    s2.add(Prismatic(s2.ground.marker(rotation=ALONG_X), mass2.marker(rotation=ALONG_X)))
    s2.add(SpringDamper(s2.ground.marker(), mass2.marker(), stiffness=k, length=1.0,
                        law=bump_stop(0.1 / omega - 2e-3, 1e6)))
    x2 = simulate(s2, 0.1, h=1e-4).bodies["mass"].position[:, 0] - 1.0
    assert -0.1 / omega + 1.5e-3 < x2.min() < -0.1 / omega + 2e-3


def test_gas_force_over_crank_angle_and_smooth_start():
    """A tabulated force vs the crank angle; the motor's quasi-static torque follows it."""
    s, main, slide = slider_crank(force=0.0, speed=0.2)
    piston = next(b for b in s.bodies if b.name == "piston")
    table = Table([0.0, 1.0, 2.0], [-50.0, -150.0, -50.0], period=2.0)
    s.add(PointForce(piston.marker(), table, direction=(1.0, 0, 0), argument=main))
    s.drivers[0].motion = SmoothStart(0.2, 0.5, 0.5)
    r = simulate(s, 1.5, h=1e-2, output_dt=0.1)
    theta = r.joints["main"].coordinate
    expected = -np.array([table(t) for t in theta]) * piston_rate(theta, 0.1, 0.3)
    assert np.allclose(r.joints["motor"].effort, expected, rtol=STATICS_RTOL, atol=1e-3)
    assert theta[-1] == pytest.approx(0.5 + 0.2 * (1.5 - 0.25), abs=1e-9)


def test_simulating_a_driven_system_twice_gives_identical_results():
    """A System is a description: a second run starts from the same state as the first (the
    driven crank turns 7.2 rad, more than a turn in the first run; its angle reference must not leak into the
    second). Reference: the first run itself, to machine precision."""
    s, crank_joint, _ = slider_crank(speed=12.0)
    first = simulate(s, 0.6, h=2e-3)
    second = simulate(s, 0.6, h=2e-3)
    assert np.array_equal(first.t, second.t)
    for name in first.joints:
        for field in ("coordinate", "force", "torque"):
            assert np.allclose(getattr(first.joints[name], field), getattr(second.joints[name], field),
                               rtol=0, atol=1e-12, equal_nan=True), (name, field)


def test_a_loop_placed_micrometres_out_of_plane_assembles():
    """The closed slider-crank loop with the rod and piston placed 2.6 um out of plane and 1 mm
    off their pins (a nearly singular loop of 3D revolute joints) assembles to 1e-12 and then
    runs as the exactly placed one (reference: the exact placement, same statics)."""
    exact, _, _ = slider_crank(flexible_rod=True)
    moved, _, _ = slider_crank(flexible_rod=True)
    for body in moved.bodies[1:]:
        body.position0 = body.position0 + np.array([1e-3, -1e-3, 2.6e-6])
    a = simulate(exact, 0.2, h=1e-2, output_dt=0.1, static_start=True, rho_inf=0.5)
    b = simulate(moved, 0.2, h=1e-2, output_dt=0.1, static_start=True, rho_inf=0.5)
    assert np.max(b.constraint_error) < DRIFT_TOL
    assert np.allclose(b.joints["slide"].coordinate, a.joints["slide"].coordinate, atol=1e-9)
    assert np.allclose(b.joints["motor"].effort, a.joints["motor"].effort, rtol=1e-6, atol=1e-9)


def test_a_mechanism_starts_from_a_crank_angle_and_a_crank_speed():
    """The slider crank (built at 0.5 rad, no motor) started at crank angle 1.2 rad and 10 rad/s:
    the assembly turns it there, the piston starts at the closed-form position and velocity
    x = r cos(theta) + sqrt(l^2 - r^2 sin^2(theta)), x_dot = dx/dtheta * omega."""
    s, main, slide = slider_crank()
    s.drivers.clear()
    main.initial, main.initial_rate = 1.2, 10.0
    r = simulate(s, 0.01, h=1e-3)
    crank, rod = 0.1, 0.3
    assert r.joints["main"].coordinate[0] == pytest.approx(1.2, abs=1e-10)
    assert r.joints["main"].rate[0] == pytest.approx(10.0, rel=1e-10)
    x = r.bodies["piston"].position[0, 0]
    assert x == pytest.approx(crank * np.cos(1.2) + np.sqrt(rod**2 - crank**2 * np.sin(1.2) ** 2), abs=1e-10)
    assert r.bodies["piston"].velocity[0, 0] == pytest.approx(piston_rate(1.2, crank, rod) * 10.0, rel=1e-9)
    assert main.initial == 1.2 and simulate(s, 0.01, h=1e-3).joints["main"].coordinate[0] == pytest.approx(1.2)


def test_a_rigid_loop_whose_pins_are_not_coplanar_assembles_and_says_so():
    """Rigid slider crank whose wrist pin sits 2.6 um out of the plane on the rod (the bundled
    rod's eye nodes): the redundant out-of-plane rows contradict the others, so they are dropped,
    the in-plane motion is the exact kinematics (x = r cos + sqrt(l^2 - r^2 sin^2)) and the report
    says how far the dropped rows miss.  5 mm out of plane (> 1e-4 of the system length) stays an input error."""
    from sidprep.errors import InputError

    s, main, slide = slider_crank()
    s.drivers.clear()
    main.initial = 1.2
    s.joints[2].marker1.position = np.array([0.3, 0.0, 2.6e-6])
    r = simulate(s, 0.01, h=1e-3)
    x = r.bodies["piston"].position[0, 0]
    assert x == pytest.approx(0.1 * np.cos(1.2) + np.sqrt(0.3**2 - 0.01 * np.sin(1.2) ** 2), abs=1e-8)
    assert any("contradict" in n and "2.6e-06 m" in n for n in r.effects.notes)
    s.joints[2].marker1.position = np.array([0.3, 0.0, 5e-3])
    with pytest.raises(InputError, match="cannot satisfy"):
        simulate(s, 0.01, h=1e-3)
