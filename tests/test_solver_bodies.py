"""Solver bodies: SID -> BodyTerms, markers on nodes, rigid bodies; test-model builders.

The builders here (``random_nodal_sid``, ``bar_sid``) are imported by the other solver tests.
"""

from pathlib import Path

import numpy as np
import pytest

from sidprep.sid.model import sid_invariants
from sidprep.solver.model.bodies import FlexibleBody, RigidBody, mode_pairs_from_kom_kr
from sidprep.solver.core.constraints import marker_kinematics
from sidprep.solver.compile.layout import body_matrices
from sidprep.solver.core.rotations import rotation_matrix, skew_matrix

CARTOP = Path(__file__).resolve().parents[1] / ".." / "shared" / "reference" / "sid_fem" / "cartopPragV32.SID_FEM"

#: agreement of quantities computed two exact ways (round-off level)
EXACT = 1e-10


def random_nodal_sid(n=7, nq=4, seed=0, node_count=3, stiffness_scale=100.0):
    """SID of a random consistent-mass nodal model; returns (sid, points, Ms, Phi)."""
    rng = np.random.default_rng(seed)
    X = rng.normal(size=(n, 3))
    R = rng.normal(size=(n, n)) * 0.1
    Ms = np.diag(rng.uniform(0.5, 1.5, n)) + R @ R.T
    Phi = rng.normal(size=(3 * n, nq)) * 0.3
    Kr = rng.normal(size=(nq, nq))
    Ke = stiffness_scale * (Kr @ Kr.T + nq * np.eye(nq))
    Phi3 = Phi.reshape(n, 3, nq)
    nodes = [(i + 1, X[i], Phi3[i]) for i in range(node_count)]
    return sid_invariants(X, Ms, Phi, nodes, Ke=Ke), X, Ms, Phi


def bar_sid(length=1.0, mass=2.0, sections=11, width=0.02, freqs=(500.0, 800.0, 1200.0, 1500.0),
            damping=0.0, stiffening=None):
    """Lumped-mass bar along x from the origin: 4 points (+-width/2, +-width/2) per section.

    Modes vanish at x = 0: (x/L)^2 in z and y, (x/L)^3 in z, x/L axial, mass-orthonormalised;
    Ke = diag(w^2), De = diag(2 zeta w).  SID nodes: the root (x = 0, on the axis, id 1) and
    the tip (id 2), added as massless points; ``stiffening`` is passed to sid_invariants.
    """
    x = np.repeat(np.linspace(0.0, length, sections), 4)
    c = 0.5 * width * np.array([[1, 1], [1, -1], [-1, 1], [-1, -1]] * sections)
    X = np.column_stack([x, c])
    m = np.full(len(x), mass / (4 * (sections - 1)))
    m[:4] *= 0.5
    m[-4:] *= 0.5
    X = np.vstack([X, [[0.0, 0, 0], [length, 0, 0]]])
    m = np.append(m, [0.0, 0.0])
    n = len(X)
    s = X[:, 0] / length
    shapes = np.zeros((n, 3, 4))
    shapes[:, 2, 0] = s**2
    shapes[:, 1, 1] = s**2
    shapes[:, 2, 2] = s**3
    shapes[:, 0, 3] = s
    Phi = shapes.reshape(3 * n, 4)
    L = np.linalg.cholesky(Phi.T @ np.kron(np.diag(m), np.eye(3)) @ Phi)
    Phi = Phi @ np.linalg.inv(L).T
    w = 2 * np.pi * np.asarray(freqs)
    Phi3 = Phi.reshape(n, 3, 4)
    nodes = [(1, X[n - 2], Phi3[n - 2]), (2, X[n - 1], Phi3[n - 1])]
    return sid_invariants(X, np.diag(m), Phi, nodes, Ke=np.diag(w**2), De=np.diag(2 * damping * w),
                          stiffening=stiffening)


def test_mode_pairs_recovered_from_kom_and_kr():
    sid, X, Ms, Phi = random_nodal_sid()
    n, nq = len(X), sid.nq
    Phi3 = Phi.reshape(n, 3, nq)
    direct = np.einsum("iak,ij,jbl->abkl", Phi3, Ms, Phi3)
    got = mode_pairs_from_kom_kr(sid.stiffening["Kom"], sid.stiffening["Kr"])
    assert np.max(np.abs(got - direct)) <= EXACT * np.max(np.abs(direct))


def test_node_marker_kinematics_match_nodal_motion():
    """Marker position / velocity Jacobians on a SID node equal the nodal motion r + A(c + Phi q)."""
    sid, X, Ms, Phi = random_nodal_sid()
    body = FlexibleBody(sid, name="b")
    mk = body.node_marker(1)
    rng = np.random.default_rng(3)
    r, A, q = rng.normal(size=3), rotation_matrix(rng.normal(size=3)), rng.normal(size=sid.nq) * 0.1
    u = rng.normal(size=6 + sid.nq)
    def kinematics(r, A, q):
        return marker_kinematics(r, A, q, mk.position, mk.rotation, mk.phi, mk.psi)

    p, Am, jt, jr, d = kinematics(r, A, q)
    phi_n = Phi.reshape(len(X), 3, sid.nq)[1]
    assert np.allclose(p, r + A @ (X[1] + phi_n @ q), atol=1e-14)
    # time derivative along u by central differences
    eps = 1e-6

    def pos(sign):
        return kinematics(r + sign * eps * u[:3], A @ rotation_matrix(sign * eps * u[3:6]), q + sign * eps * u[6:])[0]

    assert np.allclose((pos(1) - pos(-1)) / (2 * eps), jt @ u, rtol=1e-8, atol=1e-9)
    assert np.allclose(jr @ u, A @ (u[3:6]), atol=1e-14)  # psi = 0 for these nodes


def test_rigid_body_inertia_about_origin():
    m, c = 3.0, np.array([0.2, -0.1, 0.4])
    icm = np.diag([1.0, 2.0, 3.0])
    body = RigidBody(m, c, icm)
    expected = icm + m * (c @ c * np.eye(3) - np.outer(c, c))
    terms = body.terms(set(), gravity=False)
    assert np.allclose(terms.I0, expected, rtol=1e-15)
    mk = body_matrices(terms, np.zeros(0), np.zeros(0), np.zeros(3), np.zeros(3))[0]
    assert np.allclose(mk[3:6, :3], m * skew_matrix(c))


def test_effect_switches_drop_terms():
    """A body without first-order effects has a constant mass matrix; with them it changes."""
    sid = random_nodal_sid()[0]
    body = FlexibleBody(sid)
    terms = body.terms({"coupling"}, gravity=False)
    assert terms.constant_mass and terms.Oe0 is None and terms.Gr0 is None
    terms = body.terms({"coupling", "inertia_change"}, gravity=False)
    assert not terms.constant_mass
    q = np.full(sid.nq, 0.1)

    def mass(q):
        return body_matrices(terms, q, 0 * q, np.zeros(3), np.zeros(3))[0]

    assert not np.allclose(mass(q), mass(0 * q))


@pytest.mark.skipif(not CARTOP.is_file(), reason="needs the third-party file cartopPragV32.SID_FEM (licensed, ../shared/reference/sid_fem)")
def test_cartop_reads_as_flexible_body():
    body = FlexibleBody(CARTOP, name="cartop")
    assert body.nq == 3 and abs(body.sid.mass - 9.0824) < 1e-12
    avail = body.available()
    assert avail["damping"] and avail["centrifugal_stiffening"]
    assert body.node_marker(0).position.shape == (3,)
