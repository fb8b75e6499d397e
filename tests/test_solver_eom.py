"""The SID equations of motion (sid-spec 5.2) against brute-force nodal integration (5.3).

Exact particle accelerations a_P = a_O + w_dot x r + w x (w x r) + 2 w x Phi qd + Phi qdd,
r = c + Phi q, summed with the scalar mass matrix (exact bilinear forms).  The solver's body
model with every kinetic term ON (coupling, coriolis, centrifugal, inertia_change and
second_order_inertia, i.e. I2 and Gr1 included, and Oe.M1 = Kom which is exact kinematics for
a SID without K0omega) must reproduce force, moment about O and modal force to round-off.
A first-order model (no I2/Gr1) is compared with the brute force linearised in q.
"""

import numpy as np
import pytest
from test_solver_bodies import random_nodal_sid

from sidprep.solver.compile.layout import body_matrices
from sidprep.solver.model.bodies import FlexibleBody

#: relative agreement with the brute force (round-off)
EOM_RTOL = 1e-10

EXACT_KINETICS = {"coupling", "coriolis", "centrifugal", "inertia_change", "second_order_inertia",
                  "centrifugal_stiffening"}


def brute_force(X, Ms, Phi, q, qd, qdd, w, wd, a0):
    """(force, moment about O, modal force) of the inertia forces, summed over the nodes."""
    n, nq = len(X), len(q)
    Phi3 = Phi.reshape(n, 3, nq)
    r = X + Phi3 @ q
    u_dot = Phi3 @ qd
    acc = (a0 + np.cross(wd, r) + np.cross(w, np.cross(w, r)) + 2 * np.cross(w, u_dot) + Phi3 @ qdd)
    macc = Ms @ acc
    force = macc.sum(axis=0)
    moment = np.cross(r, macc).sum(axis=0)
    modal = np.einsum("iak,ia->k", Phi3, macc)
    return force, moment, modal


def sid_side(terms, q, qd, qdd, w, wd, a0):
    mk, h = body_matrices(terms, q, qd, w, np.zeros(3))
    h[6:] += terms.Ke @ q  # remove the elastic force: compare the kinetic terms only
    lhs = mk @ np.concatenate([a0, wd, qdd]) - h
    return lhs[:3], lhs[3:6], lhs[6:]


@pytest.mark.parametrize("seed", [0, 1])
def test_sid_equations_match_brute_force_exactly(seed):
    sid, X, Ms, Phi = random_nodal_sid(seed=seed)
    terms = FlexibleBody(sid).terms(EXACT_KINETICS, gravity=False)
    rng = np.random.default_rng(10 + seed)
    q, qd, qdd = (rng.normal(size=sid.nq) * s for s in (0.3, 1.0, 2.0))
    w, wd, a0 = rng.normal(size=3), rng.normal(size=3), rng.normal(size=3)
    ref = brute_force(X, Ms, Phi, q, qd, qdd, w, wd, a0)
    got = sid_side(terms, q, qd, qdd, w, wd, a0)
    for r, g in zip(ref, got):
        assert np.linalg.norm(g - r) <= EOM_RTOL * np.linalg.norm(r)


def test_first_order_model_matches_brute_force_to_first_order():
    """Without I2/Gr1 the error is O(q^2): halving q divides it by ~4."""
    sid, X, Ms, Phi = random_nodal_sid(seed=2)
    terms = FlexibleBody(sid).terms(EXACT_KINETICS - {"second_order_inertia"}, gravity=False)
    rng = np.random.default_rng(5)
    q0, qd, qdd = (rng.normal(size=sid.nq) for _ in range(3))
    w, wd, a0 = rng.normal(size=3), rng.normal(size=3), rng.normal(size=3)
    errors = []
    for s in (1e-2, 5e-3):
        ref = brute_force(X, Ms, Phi, s * q0, s * qd, qdd, w, wd, a0)
        got = sid_side(terms, s * q0, s * qd, qdd, w, wd, a0)
        errors.append(np.linalg.norm(got[1] - ref[1]))
    assert 3.5 < errors[0] / errors[1] < 4.5


def test_gravity_enters_as_mass_matrix_column():
    """Gravity equals a uniform acceleration -g of every particle (sid-spec 5.2)."""
    sid, X, Ms, Phi = random_nodal_sid(seed=3)
    terms = FlexibleBody(sid).terms(EXACT_KINETICS | {"gravity"}, gravity=True)
    q = np.random.default_rng(1).normal(size=sid.nq) * 0.2
    g = np.array([0.3, -1.0, -9.81])
    zero = np.zeros(sid.nq)
    h = body_matrices(terms, q, zero, np.zeros(3), g)[1]
    h[6:] += terms.Ke @ q
    ref = brute_force(X, Ms, Phi, q, zero, zero, np.zeros(3), np.zeros(3), g)
    for r, got in zip(ref, (h[:3], h[3:6], h[6:])):
        assert np.linalg.norm(got - r) <= EOM_RTOL * np.linalg.norm(r)
