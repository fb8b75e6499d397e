"""Effects: parsing, the auto choice, and the report's size estimates and warnings."""

import json

import numpy as np
import pytest
from test_solver_bodies import bar_sid

from sidprep.sid import sid_invariants
from solver.effects import EFFECTS, WARN_LEVEL, parse_effects
from solver.joints import ConstantSpeed, Driver, Revolute
from solver.system import FlexibleBody, System

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


def test_report_warns_when_spinning_body_leaves_out_centrifugal_stiffening():
    sid = with_k0omega(bar_sid(freqs=FREQS, damping=0.02))
    named = ["coupling", "coriolis", "centrifugal", "inertia_change", "damping"]
    r = spinning_scene(sid, named).simulate(0.2, h=2e-3)
    e = entry(r.effects, "centrifugal_stiffening")
    assert not e.included and e.available
    ratio = SPIN**2 / (2 * np.pi * FREQS[0]) ** 2
    assert e.estimate == pytest.approx(ratio, rel=1e-3)
    assert e.warning and any("centrifugal_stiffening" in w for w in r.effects.warnings)
    assert "WARNING" in r.effects.text()
    json.dumps(r.effects.as_dict())  # serialisable for the results file


def test_auto_includes_centrifugal_stiffening_when_complete():
    sid = with_k0omega(bar_sid(freqs=FREQS, damping=0.02))
    r = spinning_scene(sid, "auto").simulate(0.2, h=2e-3)
    e = entry(r.effects, "centrifugal_stiffening")
    assert e.included and not e.warning
    assert "rotate" in e.reason
    assert not any("centrifugal_stiffening" in w for w in r.effects.warnings)


def test_auto_refuses_kom_without_k0omega_and_warns():
    """Oe.M1 = Kom only (no K0omega): auto leaves the pair out, and says so loudly."""
    r = spinning_scene(bar_sid(freqs=FREQS), "auto").simulate(0.2, h=2e-3)
    e = entry(r.effects, "centrifugal_stiffening")
    assert not e.included and "K0omega" in e.reason and e.warning


def test_centrifugal_stiffening_raises_the_spinning_frequency():
    """Kom + K0omega switched as one changes the modal response; dropping it changes q."""
    sid = with_k0omega(bar_sid(freqs=FREQS, damping=0.05))
    base = ["coupling", "coriolis", "centrifugal", "inertia_change", "damping"]
    q_without = spinning_scene(sid, base).simulate(0.5, h=2e-3).bodies["rotor"].q[-1]
    q_with = spinning_scene(sid, base + ["centrifugal_stiffening"]).simulate(0.5, h=2e-3).bodies["rotor"].q[-1]
    assert np.linalg.norm(q_with - q_without) > WARN_LEVEL * np.linalg.norm(q_without)


def test_only_named_terms_are_assembled():
    body = FlexibleBody(with_k0omega(bar_sid(freqs=FREQS, damping=0.02)))
    body.configure({"coupling"}, gravity=False)
    m = body.model
    assert m.Oe0 is None and m.Oe1 is None and m.Gr0 is None and m.De is None and m.constant_mass
    body.configure({"coupling", "centrifugal_stiffening"}, gravity=False)
    assert body.model.Oe1 is not None and body.model.Oe0 is None


def test_load_stiffening_by_a_tip_force():
    """A compressive tip force with K0F: the modal stiffness becomes Ke - P K0F_x (sid-spec 5.2
    h_ext,e = phi(q)^T F), checked against the linear modal ODE; left out, the report warns."""
    from scipy.integrate import solve_ivp

    from solver.forces import PointForce
    from solver.joints import Fixed

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
        return s.simulate(0.3, h=h, rho_inf=1.0, output_dt=0.01)

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
