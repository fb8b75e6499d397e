"""SID invariants from the scalar mass matrix vs brute-force nodal double sums, Form A and a box.

References: sid-spec.md 4.3 Form A (St, Sr rigid-body matrices with M = Ms (x) E3), the defining
integrals of sections 3.3-3.10 summed node pair by node pair, and the closed-form inertia of a
rectangular block (linear tetrahedra integrate the quadratic position products exactly).
"""

import itertools

import numpy as np
import pytest

from sidprep.sid.model import (DIAGONAL, GENERAL, IDENTITY, ZERO, ge_tensor, gr_tensor, inertia_matrix,
                         sid_invariants, skew)

RTOL = 1e-12          # relative agreement of exact formulas evaluated two ways (round-off only)
N_NODES, NQ = 7, 4


def random_model(seed=0, n=N_NODES, nq=NQ):
    rng = np.random.default_rng(seed)
    X = rng.normal(size=(n, 3)) + [0.5, -0.2, 0.3]
    A = rng.normal(size=(n, n))
    Ms = A @ A.T / n + np.eye(n)                       # random SPD "consistent" scalar mass
    Phi = rng.normal(size=(3 * n, nq))
    return X, Ms, Phi


def pair_sum(Ms, f, g, op):
    """Brute-force mass integral of op(f, g): sum over node pairs Ms[n, m] op(f[n], g[m])."""
    return sum(Ms[a, b] * op(f[a], g[b]) for a in range(len(Ms)) for b in range(len(Ms)))


def close(a, b, rtol=RTOL):
    a, b = np.asarray(a, float), np.asarray(b, float)
    scale = max(np.max(np.abs(b)), 1e-300)
    return np.max(np.abs(a - b)) <= rtol * scale


@pytest.fixture(scope="module")
def model():
    X, Ms, Phi = random_model()
    nodes = [(11, X[2], Phi.reshape(-1, 3, NQ)[2], np.ones((3, NQ))), (12, X[5], Phi.reshape(-1, 3, NQ)[5])]
    Ke = np.diag(np.arange(1.0, NQ + 1))
    return X, Ms, Phi, sid_invariants(X, Ms, Phi, nodes, Ke=Ke)


def test_form_a_rigid_body_projections(model):
    X, Ms, Phi, sid = model
    n = len(X)
    M = np.kron(Ms, np.eye(3))
    St = np.tile(np.eye(3), (n, 1))
    Sr = np.vstack([-skew(x) for x in X])
    assert close(sid.mass * np.eye(3), St.T @ M @ St)
    assert close(skew(sid.mdCM.M0[:, 0]), Sr.T @ M @ St)
    assert close(inertia_matrix(sid.J.M0), Sr.T @ M @ Sr)
    assert close(sid.Ct.M0, Phi.T @ M @ St)
    assert close(sid.Cr.M0, Phi.T @ M @ Sr)
    assert close(sid.Me.M0, Phi.T @ M @ Phi)


def test_first_order_terms_against_pair_sums(model):
    """md(q), I(q) (central difference, exact for a quadratic), Cr(q) from r = c + Phi q."""
    X, Ms, Phi, sid = model
    n = len(X)
    Phi3 = Phi.reshape(n, 3, NQ)
    rng = np.random.default_rng(1)
    q = rng.normal(size=NQ)
    r = X + Phi3 @ q

    assert close(sid.mdCM(q)[:, 0], pair_sum(Ms, r, np.ones(n), lambda a, b: a * b))
    cross = [pair_sum(Ms, r, Phi3[:, :, k], np.cross) for k in range(NQ)]
    assert close(sid.Cr(q), np.array(cross))

    def inertia(qq):
        rr = X + Phi3 @ qq
        return pair_sum(Ms, rr, rr, lambda a, b: a @ b * np.eye(3) - np.outer(a, b))

    h = 0.5
    for k in range(NQ):
        e = np.eye(NQ)[k] * h
        I1 = (inertia(e) - inertia(-e)) / (2 * h)
        assert close(inertia_matrix(sid.J.M1[:, k, 0]), I1, 1e-11)


def test_velocity_terms_against_pair_sums(model):
    """Gr0, Ge and Oe(q) reproduce the defining integrals of sections 3.8-3.10 for random states."""
    X, Ms, Phi, sid = model
    n = len(X)
    Phi3 = Phi.reshape(n, 3, NQ)
    rng = np.random.default_rng(2)
    q, qd, w = rng.normal(size=NQ), rng.normal(size=NQ), rng.normal(size=3)
    ud = Phi3 @ qd
    r = X + Phi3 @ q

    rot = pair_sum(Ms, X, ud, lambda c, v: np.cross(c, 2 * np.cross(w, v)))
    G = gr_tensor(sid.Gr.M0, NQ)
    assert close(np.einsum("k,kia,a->i", qd, G, w), rot)

    elastic = np.array([pair_sum(Ms, Phi3[:, :, k], ud, lambda p, v: p @ (2 * np.cross(w, v)))
                        for k in range(NQ)])
    assert close(np.einsum("a,akj,j->k", w, ge_tensor(sid.Ge.M0, NQ), qd), elastic)

    W = skew(w)
    centrifugal = np.array([pair_sum(Ms, Phi3[:, :, k], r, lambda p, rr: p @ W @ W @ rr)
                            for k in range(NQ)])
    omega_hat = np.array([w[0] ** 2, w[1] ** 2, w[2] ** 2, w[0] * w[1], w[1] * w[2], w[0] * w[2]])
    assert close(sid.Oe(q) @ omega_hat, centrifugal)


def test_section_4_8_identities(model):
    X, Ms, Phi, sid = model
    G = gr_tensor(sid.Gr.M0, NQ)
    for node in sid.nodes:
        assert np.array_equal(node.origin.M1[:, :, 0], node.phi.M0)
        for k in range(NQ):
            assert np.array_equal(node.AP.M1[:, k, :], skew(node.psi.M0[:, k]))
    assert np.array_equal(sid.mdCM.M1[:, :, 0], sid.Ct.M0.T)
    oe = sid.Oe.M0
    for k in range(NQ):
        I1 = inertia_matrix(sid.J.M1[:, k, 0])
        assert close(0.5 * (G[k] + G[k].T), I1)
        assert close(sid.J.M1[:, k, 0], -np.array([2 * oe[k, 0], 2 * oe[k, 1], 2 * oe[k, 2],
                                                   oe[k, 3], oe[k, 5], oe[k, 4]]))
        assert close(G[k] - G[k].T, -2 * skew(sid.Cr.M0[k]))
    Ge = ge_tensor(sid.Ge.M0, NQ)
    assert close(Ge, 2 * sid.Cr.M1.transpose(2, 0, 1))
    assert close(Ge, -Ge.transpose(0, 2, 1))
    Oe1 = sid.Oe.M1
    assert close(Oe1, Oe1.transpose(1, 0, 2))
    assert close(Oe1[:, :, 0] + Oe1[:, :, 1] + Oe1[:, :, 2], -2 * sid.Me.M0)


def test_stiffening_parts_are_placed_and_kept(model):
    X, Ms, Phi, _ = model
    rng = np.random.default_rng(3)
    sym = lambda r: (lambda A: A + A.transpose(0, 2, 1))(rng.normal(size=(r, NQ, NQ)))  # noqa: E731
    parts = {"K0t": sym(3), "K0r": sym(3), "K0omega": sym(6), "K0F/0": sym(3), "K0M/0": sym(3)}
    Phi3 = Phi.reshape(-1, 3, NQ)
    plain = sid_invariants(X, Ms, Phi, [(1, X[0], Phi3[0])], Ke=np.eye(NQ))
    stiff = sid_invariants(X, Ms, Phi, [(1, X[0], Phi3[0])], Ke=np.eye(NQ), stiffening=parts)
    k, j = 1, 3
    for a in range(3):
        assert stiff.Ct.M1[k, j, a] == parts["K0t"][a, k, j]
        assert stiff.Cr.M1[k, j, a] == plain.Cr.M1[k, j, a] + parts["K0r"][a, k, j]
        assert stiff.nodes[0].phi.M1[a, j, k] == parts["K0F/0"][a, k, j]
        assert stiff.nodes[0].psi.M1[a, j, k] == parts["K0M/0"][a, k, j]
    for i in range(6):
        assert stiff.Oe.M1[k, j, i] == plain.Oe.M1[k, j, i] + parts["K0omega"][i, k, j]
    assert plain.Ct.M1 is None and plain.nodes[0].phi.M1 is None
    assert set(stiff.stiffening) == set(parts) | {"Kom", "Kr"}
    assert np.array_equal(stiff.stiffening["Kr"], plain.Cr.M1.transpose(2, 0, 1))


def box_mesh(a, b, c, nx=3, ny=2, nz=2):
    """Linear tetrahedra (6 per hexahedron) filling [0,a]x[0,b]x[0,c]; points, cells."""
    grid = np.stack(np.meshgrid(np.linspace(0, a, nx + 1), np.linspace(0, b, ny + 1),
                                np.linspace(0, c, nz + 1), indexing="ij"), -1).reshape(-1, 3)
    idx = lambda i, j, k: (i * (ny + 1) + j) * (nz + 1) + k  # noqa: E731
    cells = []
    for i, j, k in itertools.product(range(nx), range(ny), range(nz)):
        v = [idx(i + di, j + dj, k + dk) for di, dj, dk in itertools.product((0, 1), repeat=3)]
        # Kuhn split along the main diagonal v0 -> v7
        for path in itertools.permutations((4, 2, 1)):
            corners, cur = [v[0]], 0
            for step in path:
                cur += step
                corners.append(v[cur])
            cells.append(corners)
    return grid, np.array(cells)


def scalar_mass_tet4(points, cells, rho):
    """Consistent scalar mass of linear tetrahedra: rho V / 20 (1 + delta_ij) (sid-spec.md 4.2)."""
    Ms = np.zeros((len(points), len(points)))
    local = (np.ones((4, 4)) + np.eye(4)) / 20
    for cell in cells:
        V = abs(np.linalg.det(points[cell[1:]] - points[cell[0]])) / 6
        Ms[np.ix_(cell, cell)] += rho * V * local
    return Ms


def test_box_mass_centre_and_inertia_closed_form():
    a, b, c, rho = 0.6, 0.3, 0.2, 7850.0
    X, cells = box_mesh(a, b, c)
    Ms = scalar_mass_tet4(X, cells, rho)
    rng = np.random.default_rng(4)
    Phi = rng.normal(size=(3 * len(X), 2))
    sid = sid_invariants(X, Ms, Phi, [], frequencies_hz=[10.0, 20.0])
    m = rho * a * b * c
    assert sid.mass == pytest.approx(m, rel=RTOL)
    assert np.allclose(sid.mdCM.M0[:, 0], m * np.array([a, b, c]) / 2, rtol=RTOL, atol=0)
    second = m * np.array([a * a, b * b, c * c]) / 3              # integral of x_a^2 dm
    I_corner = np.diag([second[1] + second[2], second[0] + second[2], second[0] + second[1]])
    prod = -m * np.array([a * b, a * c, b * c]) / 4               # -integral of x_a x_b dm
    I_corner[0, 1] = I_corner[1, 0] = prod[0]
    I_corner[0, 2] = I_corner[2, 0] = prod[1]
    I_corner[1, 2] = I_corner[2, 1] = prod[2]
    assert close(inertia_matrix(sid.J.M0), I_corner)


def test_structure_codes_labels_and_frequencies():
    X, Ms, Phi = random_model(5, nq=3)
    # mass-orthonormalise so that Me = E and Ke diagonal
    L = np.linalg.cholesky(Phi.T @ np.kron(Ms, np.eye(3)) @ Phi)
    Phi = Phi @ np.linalg.inv(L).T
    f = np.array([1.5, 2.5, 4.0])
    sid = sid_invariants(X, Ms, Phi, [(7, np.zeros(3), np.zeros((3, 3)))], frequencies_hz=f)
    assert sid.Me.structure == IDENTITY
    assert sid.Ke.structure == DIAGONAL and sid.De.structure == ZERO
    assert sid.ksigma.structure == ZERO and sid.Cr.structure == GENERAL
    assert sid.nodes[0].origin.structure == ZERO
    assert np.allclose(np.sqrt(np.diag(sid.Ke.M0)) / (2 * np.pi), f, rtol=1e-12)
    assert sid.labels[1] == "Eigen Mode    2 :        2.500 Hz"
    assert sid.mode_kinds == ("eigen",) * 3
    again = sid_invariants(X, Ms, Phi, [], Ke=sid.Ke.M0)
    assert np.allclose(again.frequencies_hz, f, rtol=1e-10)
