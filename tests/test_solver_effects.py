"""Effects: parsing, the auto choice, and the report's size estimates and warnings."""

import json
from pathlib import Path

import numpy as np
import pytest
from test_solver_bodies import bar_sid

from sidprep.solver.effects import WARN_LEVEL
from sidprep.solver.model.effects import EFFECTS, parse_effects
from sidprep.solver.model.joints import ConstantSpeed, Driver, Revolute
from sidprep.solver import FlexibleBody, System
from sidprep.solver.run import simulate

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


#: run-based size estimate of a left-out effect against its actual effect (a second run with it),
#: quasi-static spin-up: measured 0.0113 against 0.0124
RUN_ESTIMATE_RTOL = 0.25


def test_report_estimates_a_left_out_effect_from_the_run():
    """A damped bar spun up smoothly to SPIN without centrifugal stiffening: the report's size of
    the left-out effect (its modal force sampled on the run, relative to |Ke q|) matches the
    relative change of the modal coordinates when a second run includes it, and warns."""
    from sidprep.solver import SmoothStart

    def scene(effects):
        s = System(gravity=(0, 0, 0), effects=effects)
        bar = s.add(FlexibleBody(bar_sid(freqs=FREQS, damping=0.3), name="rotor"))
        hub = s.add(Revolute(s.ground.marker(), bar.node_marker(0), name="hub"))
        s.add(Driver(hub, SmoothStart(SPIN, 1.0)))
        return s

    named = ["coupling", "coriolis", "centrifugal", "inertia_change", "damping"]
    without = simulate(scene(named), 2.0, h=2e-3, output_dt=0.01)
    with_it = simulate(scene(named + ["centrifugal_stiffening"]), 2.0, h=2e-3, output_dt=0.01)
    q0, q1 = without.bodies["rotor"].q, with_it.bodies["rotor"].q
    actual = np.max(np.abs(q1 - q0)) / np.max(np.abs(q0))
    e = entry(without.effects, "centrifugal_stiffening")
    assert not e.included and e.available and "sampled on the run" in e.measure
    assert e.estimate == pytest.approx(actual, rel=RUN_ESTIMATE_RTOL)
    assert e.warning and any("centrifugal_stiffening" in w for w in without.effects.warnings)
    assert "WARNING" in without.effects.text()
    json.dumps(without.effects.as_dict())  # serialisable for the results file


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
    h_ext,e = phi(q)^T F), checked against the linear modal ODE; left out, the report warns."""
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
    left_out = run(["coupling"], 1e-3)
    e = entry(left_out.effects, "load_stiffening")
    w1sq = (2 * np.pi * FREQS[0]) ** 2
    assert e.estimate == pytest.approx(load * np.linalg.norm(g, 2) / w1sq, rel=1e-6) and e.warning


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
