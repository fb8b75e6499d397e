"""Effects: parsing, the auto choice, and the report's estimates and warnings.

Each estimate (the change of the modal coordinates a left-out effect would make, computed from
the run alone) is checked against an independent reference: a second run that includes the
effect, at the same step."""

import json
from pathlib import Path

import numpy as np
import pytest
from test_solver_bodies import bar_sid

from sidprep.sid.io import read_sid
from sidprep.solver import FlexibleBody, SmoothStart, System
from sidprep.solver.effects import MEASURE, WARN_LEVEL
from sidprep.solver.model.effects import EFFECTS, parse_effects
from sidprep.solver.model.joints import ConstantSpeed, Driver, Revolute
from sidprep.solver.run import simulate
from sidprep.solver.scene import load_scene

SPIN = 10.0  # rad/s
FREQS = (5.0, 8.0, 12.0, 15.0)  # Hz: (SPIN / omega_1)^2 = 0.10


def with_k0omega(sid):
    """The same SID with a (symmetric, stiffening) K0omega added to Oe.M1."""
    rng = np.random.default_rng(0)
    a = rng.normal(size=(6, sid.nq, sid.nq))
    k0w = 0.5 * (a + a.transpose(0, 2, 1))
    oe1 = sid.Oe.M1 + k0w.transpose(1, 2, 0)
    from dataclasses import replace

    return replace(sid, Oe=replace(sid.Oe, M1=oe1), stiffening={**sid.stiffening, "K0omega": k0w})


def spinning_scene(sid, effects):
    """The bar driven about the inertial z axis at SPIN through its root node."""
    s = System(gravity=(0, 0, 0), effects=effects)
    bar = s.add(FlexibleBody(sid, name="rotor"))
    hub = s.add(Revolute(s.ground.marker(), bar.node_marker(0), name="hub"))
    s.add(Driver(hub, ConstantSpeed(SPIN)))
    return s


def entry(report, effect):
    return next(e for e in report.bodies["rotor"] if e.effect == effect)


def test_parse_effects():
    assert parse_effects("auto") == "auto" and parse_effects(None) == "auto"
    assert parse_effects("all") == set(EFFECTS)
    with pytest.raises(ValueError, match="centrifugal_stifening"):
        parse_effects(["centrifugal_stifening"])


#: the issue's acceptance (22, item 5): each left-out effect's estimate (from the run alone)
#: within this factor of what a second run that includes it changes, at the same step
ESTIMATE_FACTOR = 3.0
#: truths below this are not compared (both runs agree to it; far below WARN_LEVEL)
TRUTH_FLOOR = 1e-5
PENDULUM_SCENE = Path(__file__).resolve().parents[1] / "examples" / "flexible_pendulum" / "scene.toml"


def mass_norm(q, me):
    """|q(t)| = sqrt(q^T Me q) per sample, (nt,)."""
    return np.sqrt(np.einsum("ti,ij,tj->t", q, me, q))


def two_run_check(build, base, settings, effects=None):
    """{(body, effect): (estimate, truth)}: the report's estimate of each left-out effect of the
    run of ``build(base)`` and the change max |dq| / max |q| that a second run of
    ``build(base + [effect])`` at the same settings actually makes (the independent reference)."""
    system, t_end = build(base)
    first = simulate(system, t_end, **settings)
    out = {}
    for name, entries in first.effects.bodies.items():
        chosen = [e.effect for e in entries if e.included]
        for e in entries:
            if e.included or not e.available or (effects and e.effect not in effects):
                continue
            again = simulate(build(chosen + [e.effect])[0], t_end, **settings)
            me = next(b for b in system.bodies if b.name == name).sid.Me.M0
            q0, q1 = first.bodies[name].q, again.bodies[name].q
            out[name, e.effect] = (e.estimate, float(np.max(mass_norm(q1 - q0, me)) / np.max(mass_norm(q0, me))))
            assert e.measure == MEASURE
    return first, out


def assert_within_factor(pairs, measured):
    """Every estimate within ESTIMATE_FACTOR of its two-run truth (``measured``: the ratios
    estimate / truth seen when the test was written, for the record)."""
    for key, (estimate, truth) in pairs.items():
        if truth < TRUTH_FLOOR:
            assert estimate < WARN_LEVEL, (key, estimate, truth)
            continue
        assert truth / ESTIMATE_FACTOR <= estimate <= truth * ESTIMATE_FACTOR, (key, estimate, truth, measured)


def pendulum_scene(effects):
    scene = load_scene(PENDULUM_SCENE)
    scene.system.effects = effects
    return scene.system, scene.t_end


@pytest.mark.parametrize("h, measured", [(1e-3, 0.70), (2.5e-4, 1.04)])
def test_flexible_pendulum_estimate_against_a_second_run(h, measured):
    """The example's bar (Oe.M1 = Kom only: auto leaves centrifugal stiffening out).  Including
    it changes q by 3.2e-4 at the scene's step (3.0e-4; the force ratio said 5.5e-7)
    and 8.0e-4 at h / 4, where generalised-alpha resolves the phase of the 416 Hz in-plane
    bending (at omega h = 2.6 it shows 0.37 of a frequency shift); the estimate (2.2e-4, 8.3e-4)
    is mostly the free vibration's accumulated phase error."""
    run, pairs = two_run_check(pendulum_scene, "auto", dict(h=h, rho_inf=0.9, output_dt=1 / 200))
    assert pairs["bar", "centrifugal_stiffening"][1] > TRUTH_FLOOR
    assert_within_factor(pairs, measured)
    assert not any("centrifugal_stiffening" in w for w in run.effects.warnings)


def double_pendulum(effects):
    """Two of the example's bars, hinged about y at the ground and tip to root, released
    horizontally under gravity."""
    sid = read_sid(PENDULUM_SCENE.parent / "bar.sid.h5")
    s = System(gravity=(0, 0, -9.81), effects=effects)
    upper = s.add(FlexibleBody(sid, name="upper", position=(0.0, -0.025, -0.04)))
    lower = s.add(FlexibleBody(sid, name="lower", position=(1.0, -0.025, -0.04)))
    y = np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]])  # z axis -> y
    s.add(Revolute(s.ground.marker(rotation=y), upper.node_marker(node_id=1125, rotation=y), name="h1"))
    s.add(Revolute(upper.marker(position=(1.0, 0.025, 0.04), rotation=y), lower.node_marker(node_id=1125, rotation=y),
                   name="h2"))
    return s, 1.0


@pytest.mark.parametrize("h, measured", [(1e-3, {"upper": 0.62, "lower": 1.09}), (5e-4, {"upper": 0.78, "lower": 1.35})])
def test_double_pendulum_estimate_against_a_second_run(h, measured):
    """The issue's flexible double pendulum: centrifugal stiffening changes q by 1.9e-4 (upper)
    and 9.4e-5 (lower) at h = 1 ms (the force ratio said 4e-7), 3.8e-4 and 2.0e-4 at 0.5 ms;
    measured estimate / truth in the parameters."""
    _, pairs = two_run_check(double_pendulum, "auto", dict(h=h, rho_inf=0.9, output_dt=1 / 200))
    assert pairs["upper", "centrifugal_stiffening"][1] > TRUTH_FLOOR
    assert_within_factor(pairs, measured)


SPINNING_SCENE = PENDULUM_SCENE.parents[1] / "spinning_body" / "scene.toml"


def test_spinning_body_estimate_against_a_second_run():
    """The example's free bar tumbling at 10 rad/s for 10 s, centrifugal stiffening left out:
    its largest modal coordinate is the 2588 Hz axial mode, which generalised-alpha (omega h =
    16) damps within steps: the run shows 0.014 of a frequency shift there
    (``genalpha_phase_response``); measured 1.1e-6 against 8.5e-7 (without the integrator's
    response the estimate said 9.6e-6)."""
    def build(effects):
        scene = load_scene(SPINNING_SCENE)
        scene.system.effects = effects
        return scene.system, scene.t_end

    settings = load_scene(SPINNING_SCENE).settings
    _, pairs = two_run_check(build, "auto", dict(h=settings.h, rho_inf=settings.rho_inf, newton_tol=settings.newton_tol,
                                                 output_dt=settings.output_dt), effects=["centrifugal_stiffening"])
    assert pairs["bar", "centrifugal_stiffening"][1] > 0.0
    estimate, truth = pairs["bar", "centrifugal_stiffening"]
    assert truth / ESTIMATE_FACTOR <= estimate <= truth * ESTIMATE_FACTOR, (estimate, truth)


#: generalised-alpha's phase response at rho_inf = 1 against the trapezoidal rule's closed form
#: d/d(omega) [(2 / h) atan(omega h / 2)] = 1 / (1 + (omega h / 2)^2) (finite differences)
PHASE_RESPONSE_RTOL = 1e-6


def test_genalpha_phase_response_is_the_trapezoidal_rule_at_rho_inf_1():
    from sidprep.solver.effects import genalpha_phase_response

    omega, h = 2 * np.pi * np.array([1.0, 100.0, 263.6, 2588.0]), 1e-3
    expected = 1.0 / (1.0 + (omega * h / 2) ** 2)
    assert np.allclose(genalpha_phase_response(omega, h, 1.0), expected, rtol=PHASE_RESPONSE_RTOL)
    damped = genalpha_phase_response(omega, h, 0.9)
    assert damped[0] == pytest.approx(1.0, abs=1e-4) and np.all(np.diff(damped) < 0)


def spin_up(sid, gravity=(0.0, 0.0, 0.0)):
    """The bar driven about the inertial z axis from rest to SPIN over 1 s (SmoothStart)."""
    def build(effects):
        s = System(gravity=gravity, effects=effects)
        bar = s.add(FlexibleBody(sid, name="rotor"))
        hub = s.add(Revolute(s.ground.marker(), bar.node_marker(0), name="hub"))
        s.add(Driver(hub, SmoothStart(SPIN, 1.0)))
        return s, 2.0
    return build


def test_spin_up_estimates_against_second_runs():
    """An undamped bar spun up from rest keeping only the coupling: each left-out effect against
    a second run with it.  Measured estimate / truth: coriolis 1.25 (gyroscopic coupling of the
    in-plane modes: the pairwise frequency shift), centrifugal 1.00 (quasi-static), inertia_change
    0.98, centrifugal_stiffening 1.19 (phase of the free vibration: 0.13 of max |q|)."""
    run, pairs = two_run_check(spin_up(bar_sid(freqs=FREQS)), ["coupling"], dict(h=2e-3, output_dt=0.01))
    for effect in ("coriolis", "centrifugal", "centrifugal_stiffening"):  # truths 0.16, 1.8, 0.13
        assert pairs["rotor", effect][1] > WARN_LEVEL and entry(run.effects, effect).warning
    assert pairs["rotor", "inertia_change"][1] < WARN_LEVEL and not entry(run.effects, "inertia_change").warning
    assert_within_factor(pairs, {"coriolis": 1.25, "centrifugal": 1.0, "inertia_change": 0.98,
                                 "centrifugal_stiffening": 1.19})
    assert "WARNING" in run.effects.text()
    json.dumps(run.effects.as_dict())  # serialisable for the results file


@pytest.mark.parametrize("damping, measured", [
    (True, {"centrifugal_stiffening": 1.13, "acceleration_stiffening": 1.46}),
    (False, {"centrifugal_stiffening": 1.09, "acceleration_stiffening": 1.04, "damping": 1.60})])
def test_damped_spin_up_and_acceleration_stiffening_against_second_runs(damping, measured):
    """A damped bar (zeta = 0.3: quasi-static response) with K0omega and K0t, spun up under
    gravity along -z: centrifugal and acceleration stiffening left out (measured 0.048 against
    0.042 and 7.4e-4 against 5.0e-4), and with the damping left out as well (then the modes
    vibrate: 0.20 against 0.18, 5.7e-3 against 5.5e-3; damping 0.73 against 0.46), each against
    a second run that includes it."""
    rng = np.random.default_rng(1)
    a = rng.normal(size=(3, 4, 4))
    sid = with_k0omega(bar_sid(freqs=FREQS, damping=0.3, stiffening={"K0t": 0.05 * (a + a.transpose(0, 2, 1))}))
    named = ["gravity", "coupling", "coriolis", "centrifugal", "inertia_change"] + (["damping"] if damping else [])
    _, pairs = two_run_check(spin_up(sid, gravity=(0.0, 0.0, -9.81)), named, dict(h=2e-3, output_dt=0.01))
    assert pairs["rotor", "acceleration_stiffening"][1] > TRUTH_FLOOR
    assert_within_factor(pairs, measured)


def test_spin_up_keeping_only_the_centrifugal_load_against_second_runs():
    """The damped bar with K0omega and K0t spun up under gravity keeping only the centrifugal
    load (and damping): gravity (with its coupling Ct0 g), coupling, coriolis, inertia change and
    centrifugal stiffening left out, each against a second run.  Measured estimate / truth:
    gravity 0.81 (1.26 against 1.56), coupling 1.00, coriolis 1.22, inertia_change 0.99,
    centrifugal_stiffening 1.00 (acceleration stiffening: 5.7e-7 against 4.9e-8, below
    TRUTH_FLOOR)."""
    rng = np.random.default_rng(1)
    a = rng.normal(size=(3, 4, 4))
    sid = with_k0omega(bar_sid(freqs=FREQS, damping=0.3, stiffening={"K0t": 0.05 * (a + a.transpose(0, 2, 1))}))
    _, pairs = two_run_check(spin_up(sid, gravity=(0.0, 0.0, -9.81)), ["centrifugal", "damping"],
                             dict(h=2e-3, output_dt=0.01))
    for effect in ("gravity", "coupling", "coriolis", "inertia_change", "centrifugal_stiffening"):
        assert pairs["rotor", effect][1] > TRUTH_FLOOR
    assert_within_factor(pairs, {"gravity": 0.81, "coupling": 1.0, "coriolis": 1.22, "inertia_change": 0.99,
                                 "centrifugal_stiffening": 1.0})


def test_auto_includes_centrifugal_stiffening_when_complete():
    sid = with_k0omega(bar_sid(freqs=FREQS, damping=0.02))
    r = simulate(spinning_scene(sid, "auto"), 0.2, h=2e-3)
    e = entry(r.effects, "centrifugal_stiffening")
    assert e.included and not e.warning
    assert "rotate" in e.reason
    assert not any("centrifugal_stiffening" in w for w in r.effects.warnings)


def test_auto_refuses_kom_without_k0omega_and_warns():
    """Oe.M1 = Kom only (no K0omega): auto leaves the pair out, and says so loudly."""
    r = simulate(spinning_scene(bar_sid(freqs=FREQS), "auto"), 0.2, h=2e-3)
    e = entry(r.effects, "centrifugal_stiffening")
    assert not e.included and "K0omega" in e.reason and e.warning


def test_centrifugal_stiffening_raises_the_spinning_frequency():
    """Kom + K0omega switched as one changes the modal response; dropping it changes q."""
    sid = with_k0omega(bar_sid(freqs=FREQS, damping=0.05))
    base = ["coupling", "coriolis", "centrifugal", "inertia_change", "damping"]
    q_without = simulate(spinning_scene(sid, base), 0.5, h=2e-3).bodies["rotor"].q[-1]
    q_with = simulate(spinning_scene(sid, base + ["centrifugal_stiffening"]), 0.5, h=2e-3).bodies["rotor"].q[-1]
    assert np.linalg.norm(q_with - q_without) > WARN_LEVEL * np.linalg.norm(q_without)


def test_only_named_terms_are_assembled():
    body = FlexibleBody(with_k0omega(bar_sid(freqs=FREQS, damping=0.02)))
    m = body.terms({"coupling"}, gravity=False)
    assert m.Oe0 is None and m.Oe1 is None and m.Gr0 is None and m.De is None and m.constant_mass
    m = body.terms({"coupling", "centrifugal_stiffening"}, gravity=False)
    assert m.Oe1 is not None and m.Oe0 is None


def test_load_stiffening_by_a_tip_force():
    """A compressive tip force with K0F: the modal stiffness becomes Ke - P K0F_x (sid-spec 5.2
    h_ext,e = phi(q)^T F), checked against the linear modal ODE; left out, the report's estimate
    against a second run with it (measured 0.132 against 0.113), and it warns."""
    from scipy.integrate import solve_ivp

    from sidprep.solver.model.forces import PointForce
    from sidprep.solver.model.joints import Fixed

    nq, load = 4, 300.0
    rng = np.random.default_rng(2)
    a = rng.normal(size=(nq, nq))
    g = a @ a.T / nq  # symmetric positive: the softening per newton of compression
    k0f = np.zeros((3, nq, nq))
    k0f[0] = -g  # sid-spec 6.2 sign rule: a unit tension (+x) gives a negative K0F_x (stiffening)
    sid = bar_sid(freqs=FREQS, stiffening={"K0F/1": k0f})
    q0 = np.array([1e-3, 0.0, 5e-4, 0.0])

    def run(effects, h):
        s = System(gravity=(0, 0, 0), effects=effects)
        bar = s.add(FlexibleBody(sid, name="rotor", q0=q0))
        s.add(Fixed(s.ground.marker(), bar.node_marker(0)))
        s.add(PointForce(bar.node_marker(1), (-load, 0.0, 0.0)))
        return simulate(s, 0.3, h=h, rho_inf=1.0, output_dt=0.01)

    keff = sid.Ke.M0 - load * g
    phi_tip = sid.nodes[1].phi.M0
    rhs = phi_tip.T @ np.array([-load, 0.0, 0.0])
    ode = solve_ivp(lambda t, y: np.concatenate([y[nq:], rhs - keff @ y[:nq]]), (0, 0.3),
                    np.concatenate([q0, np.zeros(nq)]), t_eval=np.arange(31) * 0.01, rtol=1e-10, atol=1e-14)
    r = run(["coupling", "load_stiffening"], 2.5e-4)
    q = r.bodies["rotor"].q
    assert np.max(np.abs(q - ode.y[:nq].T)) < 2e-3 * np.max(np.abs(ode.y[:nq]))
    left_out, with_it = run(["coupling"], 1e-3), run(["coupling", "load_stiffening"], 1e-3)
    q0, q1, me = left_out.bodies["rotor"].q, with_it.bodies["rotor"].q, sid.Me.M0
    truth = np.max(mass_norm(q1 - q0, me)) / np.max(mass_norm(q0, me))
    e = entry(left_out.effects, "load_stiffening")
    assert_within_factor({("rotor", "load_stiffening"): (e.estimate, truth)}, 1.17)
    assert e.warning


MESH = Path(__file__).resolve().parents[1] / "data" / "meshes" / "bar.msh"
#: Southwell coefficient of the first flapwise mode of a uniform cantilever, hub radius 0
SOUTHWELL = 1.193
#: the 3D tet bar and a 4-mode basis against Euler-Bernoulli theory
SOUTHWELL_RTOL = 0.03


@pytest.mark.skipif(not MESH.is_file(), reason="bundled bar mesh missing")
def test_spinning_cantilever_flapwise_frequency_follows_southwell(tmp_path):
    """End to end: `sidprep reduce --stiffening` on the bundled bar (clamped frame), spun about z
    at 20 Hz through its clamped face: f^2 = f0^2 + K Omega^2 (K = 1.193) with centrifugal
    stiffening (Kom + K0omega), K = 0 without it (the flapwise mode has no Kom part)."""
    from sidprep.cli.main import main

    out = tmp_path / "bar.sid.h5"
    assert main(["reduce", str(MESH), "--interface", "fixed_end:rbe2", "--frame", "fixed_end", "--modes", "4",
                 "--no-frm", "--stiffening", "--no-check-frequencies", "--no-obj", "--no-sid-fem", "-q",
                 "-o", str(out)]) == 0
    from sidprep.sid.io import read_sid

    sid = read_sid(out)
    flap = int(np.argmax(np.abs(sid.Ct.M0[:, 2])))  # the first mode moving along z
    spin = 2 * np.pi * 20.0

    def flapwise_frequency(effects):
        s = System(gravity=(0, 0, 0), effects=effects)
        q0 = np.zeros(sid.nq)
        q0[flap] = 1e-4
        beam = s.add(FlexibleBody(sid, name="beam", q0=q0, omega=(0, 0, spin)))
        hub = s.add(Revolute(s.ground.marker(position=sid.nodes[0].origin.M0[:, 0]), beam.node_marker(0)))
        s.add(Driver(hub, ConstantSpeed(spin)))
        r = simulate(s, 0.3, h=2.5e-4)
        x = r.bodies["beam"].q[:, flap] - np.mean(r.bodies["beam"].q[:, flap])
        up = np.flatnonzero((x[:-1] < 0) & (x[1:] >= 0))
        tz = r.t[up] - x[up] * (r.t[up + 1] - r.t[up]) / (x[up + 1] - x[up])
        return (len(tz) - 1) / (tz[-1] - tz[0])

    base = ["coupling", "coriolis", "centrifugal", "inertia_change"]
    f0 = flapwise_frequency(base)  # same step size: the integrator's period error cancels
    f = flapwise_frequency(base + ["centrifugal_stiffening"])
    k = (f**2 - f0**2) / (spin / (2 * np.pi)) ** 2
    assert k == pytest.approx(SOUTHWELL, rel=SOUTHWELL_RTOL)
    assert f0 == pytest.approx(float(sid.frequencies_hz[flap]), rel=2e-3)


#: a clamped Beam's tip deflection under its own weight against q L^4 / (8 EI) (five forms:
#: measured 1.5e-5)
SELF_WEIGHT_RTOL = 2e-3


def test_gravity_alone_loads_the_modes():
    """effects = ["gravity"] without "coupling" still loads the modes with Ct0 g (it used to
    drop the modal gravity force, which is assembled from the coupling matrix)."""
    from sidprep.reduction.beam import beam_options_from_table, beam_sid
    from sidprep.solver import Fixed

    length, ei, mu = 2.0, 2.1e11 * 0.02 * 0.05**3 / 12, 7850.0 * 0.02 * 0.05
    sid = beam_sid(beam_options_from_table({"length": length, "section": "rectangle:0.02,0.05", "bc": "clamped-free",
                                            "modes": "xz:1-5", "frames": [1.0]}, "t"))
    s = System(gravity=(0.0, 0.0, -9.81))
    beam = s.add(FlexibleBody(sid, name="beam", effects=["gravity"]))
    s.add(Fixed(s.ground.marker(), beam.marker()))
    beam.node_marker(1, name="tip")
    r = simulate(s, 1e-3, h=1e-3, static_start=True)
    coupling = next(e for e in r.effects.bodies["beam"] if e.effect == "coupling")
    assert coupling.included and "gravity's modal force" in coupling.reason
    expected = -mu * 9.81 * length**4 / (8 * ei)
    assert abs(r.markers["tip"][0, 2] / expected - 1) < SELF_WEIGHT_RTOL


#: the signal-weighted left-out terms against the body equations evaluated directly (round-off)
RECONSTRUCTION_RTOL = 1e-9


def test_left_out_terms_reproduce_the_body_equations():
    """The estimate weights per-signal coefficients by the run's signals; at a random state they
    give the same modal force as the compiled body equations with and without each effect (so
    the elastic rows are affine in q, qd and linear in the 19 signals, as ``signals`` says)."""
    from sidprep.solver.effects import LeftOutTerms, free_modes, packed, signals
    from sidprep.solver.core.body import body_matrices

    rng = np.random.default_rng(3)
    a = rng.normal(size=(3, 4, 4))
    sid = with_k0omega(bar_sid(freqs=FREQS, damping=0.05, stiffening={"K0t": a + a.transpose(0, 2, 1)}))
    body = FlexibleBody(sid, name="rotor")
    chosen = {"coupling"}
    terms = packed(body, chosen)[1]
    omega, modes = free_modes(terms.Ke, terms.Me)
    q, qd, w, acc, wdot, g = (rng.normal(size=n) for n in (4, 4, 3, 3, 3, 3))
    ud = np.concatenate([acc, wdot, rng.normal(size=4)])
    left_out = LeftOutTerms(body, chosen, modes)
    x = signals(w[None], acc[None], wdot[None], g[None])[0]
    for effect in ("gravity", "coriolis", "centrifugal", "inertia_change", "centrifugal_stiffening",
                   "acceleration_stiffening", "damping"):
        f, k, c = left_out.coefficients(effect)
        eta, eta_dot = modes.T @ sid.Me.M0 @ q, modes.T @ sid.Me.M0 @ qd
        rebuilt = x @ f + np.einsum("i,ikj,j->k", x, k, eta) + np.einsum("i,ikj,j->k", x, c, eta_dot)
        (m0, h0), (m1, h1) = (body_matrices(*packed(body, e)[0], q, qd, w, g) for e in (chosen, chosen | {effect}))
        direct = modes.T @ ((m1 - m0) @ ud - (h1 - h0))[6:]
        assert np.max(np.abs(rebuilt - direct)) <= RECONSTRUCTION_RTOL * np.max(np.abs(direct)), effect
    assert left_out.coefficients("second_order_inertia") is None  # I2, Gr1: rigid-body rows only


def test_json_summary_keeps_the_estimates():
    """`sidprep simulate --json`: effects.estimates[body][effect] with the measure beside it."""
    from sidprep.solver.simulate_scene import effects_summary

    r = simulate(spinning_scene(bar_sid(freqs=FREQS), "auto"), 0.2, h=2e-3)
    est = effects_summary(r.effects)["estimates"]["rotor"]
    assert set(est) == {e.effect for e in r.effects.bodies["rotor"] if e.available and not e.included}
    assert est["centrifugal_stiffening"] == {"value": entry(r.effects, "centrifugal_stiffening").estimate,
                                             "measure": MEASURE}
    json.dumps(est)


#: the pairwise (two-level) frequency shifts against the exact eigenvalues of the perturbed modal
#: system, relative to the exact shift (measured 7.9 %, 2.1 %, 0.07 %: a close pair coupled
#: strongly, |dK| up to 8 % of omega^2)
SHIFT_RTOL = 0.1


def test_frequency_shifts_against_the_exact_eigenvalues():
    """A close pair (10 and 10.5 rad/s) and a third mode, perturbed by a symmetric stiffness
    and a gyroscopic (antisymmetric) velocity coupling: the shifted frequencies
    sqrt(omega^2 + d(omega^2)) against the eigenvalues of the first-order state matrix."""
    from sidprep.solver.effects import frequency_shifts

    omega = np.array([10.0, 10.5, 30.0])
    rng = np.random.default_rng(4)
    a = rng.normal(size=(3, 3))
    dk = 2.0 * (a + a.T)
    g = np.array([[0.0, 1.5, 0.4], [-1.5, 0.0, -0.8], [-0.4, 0.8, 0.0]])
    shift, decay = frequency_shifts(dk[None], g[None], omega)
    state = np.block([[np.zeros((3, 3)), np.eye(3)], [-(np.diag(omega**2) + dk), -g]])
    exact = np.sort(np.abs(np.linalg.eigvals(state).imag))[::2]
    approx = np.sort(np.sqrt(omega**2 + shift[0]))
    assert np.max(np.abs(approx - exact) / np.abs(exact - omega)) < SHIFT_RTOL
    assert np.max(np.abs(decay)) < 1e-12  # gyroscopic coupling conserves energy


def test_an_effect_that_would_deform_an_undeformed_body_warns():
    """Gravity left out of a clamped bar at rest: the run leaves q = 0, gravity would bend it
    (an infinite relative change): the report says so and the JSON value is null."""
    from sidprep.solver.simulate_scene import effects_summary
    from sidprep.solver.model.joints import Fixed

    s = System(gravity=(0.0, 0.0, -9.81), effects=["coupling"])
    bar = s.add(FlexibleBody(bar_sid(freqs=FREQS), name="rotor"))
    s.add(Fixed(s.ground.marker(), bar.node_marker(0)))
    r = simulate(s, 0.05, h=1e-3)
    assert np.max(np.abs(r.bodies["rotor"].q)) == 0.0
    e = entry(r.effects, "gravity")
    assert e.estimate == np.inf and e.warning
    assert any("gravity" in w and "leaves undeformed" in w for w in r.effects.warnings)
    assert effects_summary(r.effects)["estimates"]["rotor"]["gravity"] == {"value": None, "measure": MEASURE}
    assert entry(r.effects, "centrifugal").estimate == 0.0 and not entry(r.effects, "centrifugal").warning


def test_load_stiffening_left_out_without_node_loads_is_zero():
    """K0F at the tip node, but the bar is held by a marker on its frame and has no node marker:
    auto leaves load stiffening out, and with no node loads in the run its estimate is 0 (it
    used to fail on the empty load list: the moving-mass example)."""
    from sidprep.solver.model.joints import Fixed

    k0f = np.zeros((3, 4, 4))
    k0f[0] = -np.eye(4)
    s = System(gravity=(0.0, 0.0, -9.81))
    bar = s.add(FlexibleBody(bar_sid(freqs=FREQS, stiffening={"K0F/1": k0f}), name="rotor"))
    s.add(Fixed(s.ground.marker(), bar.marker()))
    r = simulate(s, 0.05, h=2e-3)
    e = entry(r.effects, "load_stiffening")
    assert e.available and not e.included and e.estimate == 0.0 and not e.warning
