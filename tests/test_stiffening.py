"""Geometric stiffening of the bundled cantilever bar (1.0 x 0.05 x 0.08 m steel, tet10, clamped at
x = 0 through the fixed_end RBE2 master): Euler buckling and the Southwell coefficient."""

from pathlib import Path

import numpy as np
import pytest
import scipy.linalg as sla

from sidprep.fe.assemble import mass_matrix, stiffness_matrix
from sidprep.reduction.interfaces import make_interface
from sidprep.fe.material import builtin_material
from sidprep.fe.mesh import read_mesh
from sidprep.jobs.reduce import reduce_body
from sidprep.reduction.stiffening import centrifugal_fields, stiffening_parts

BAR = Path(__file__).resolve().parents[1] / "data" / "meshes" / "bar.msh"
L, B, H = 1.0, 0.05, 0.08
#: linearised buckling of the coarse 3D bar (h = 0.04 m, 1 element across) vs Euler: measured -0.3 %
EULER_RTOL = 0.01
#: Southwell coefficient of the first flapwise mode of a uniform cantilever, spinning about an
#: axis through the root (../shared/validation/README.md 1.4, Rayleigh quotient): measured -0.05 %
SOUTHWELL_K1 = 1.1933
SOUTHWELL_RTOL = 0.02


@pytest.fixture(scope="module")
def bar():
    mesh = read_mesh(BAR)
    steel = builtin_material("steel")
    K, M = stiffness_matrix(mesh, steel), mass_matrix(mesh, steel)
    red = reduce_body(mesh, K, M, [make_interface(mesh, "fixed_end"), make_interface(mesh, "free_end")],
                      frame="fixed_end", n_modes=6)
    parts = stiffening_parts(mesh, steel, M, red.im, red.static_solve, red.Phi_fe)
    return mesh, steel, red, parts


def test_all_slots_present_and_symmetric(bar):
    _, _, red, parts = bar
    nq = len(red.basis.kinds)
    shapes = {k: v.shape for k, v in parts.items()}
    assert shapes == {"K0t": (3, nq, nq), "K0r": (3, nq, nq), "K0omega": (6, nq, nq),
                      "K0F/0": (3, nq, nq), "K0M/0": (3, nq, nq), "K0F/1": (3, nq, nq), "K0M/1": (3, nq, nq)}
    for v in parts.values():
        np.testing.assert_allclose(v, v.transpose(0, 2, 1), atol=1e-12 * np.abs(v).max())
    # the clamped master carries its loads into the support: no stress, no stiffening
    assert np.abs(parts["K0F/0"]).max() < 1e-9 * np.abs(parts["K0F/1"]).max()


def test_axial_tip_force_stiffens_in_tension_softens_in_compression(bar):
    _, _, red, parts = bar
    Ke = np.diag((2 * np.pi * red.basis.frequencies_hz) ** 2)
    K0F = parts["K0F/1"][0]                         # axial unit force at the tip master
    f1 = {F: np.sqrt(sla.eigvalsh(Ke - F * K0F)[0]) / (2 * np.pi) for F in (-1e5, 0.0, 1e5)}
    assert f1[-1e5] < f1[0.0] < f1[1e5]
    assert f1[0.0] == pytest.approx(red.basis.frequencies_hz[0], rel=1e-9)


def test_linearised_buckling_load_matches_euler(bar):
    _, steel, red, parts = bar
    Ke = np.diag((2 * np.pi * red.basis.frequencies_hz) ** 2)
    mu = np.real(sla.eigvals(Ke, -parts["K0F/1"][0]))   # Ke + P K0F singular, P = compressive load
    p_cr = mu[mu > 0].min()
    euler = np.pi ** 2 * steel.E * (H * B ** 3 / 12) / (4 * L ** 2)
    assert p_cr == pytest.approx(euler, rel=EULER_RTOL)


def test_southwell_coefficient_of_the_rotating_cantilever(bar):
    """Spin about z through the root: flapwise (z) bending gets Ke + Omega^2 K0omega_zz (sid-spec 6.2/6.3)."""
    mesh, _, red, parts = bar
    nq = len(red.basis.kinds)
    Phi = red.Phi_fe.reshape(mesh.n_nodes, 3, nq)
    flap = [k for k in range(nq) if np.abs(Phi[:, 2, k]).sum() > 3 * np.abs(Phi[:, 1:2, k]).sum()][0]
    assert red.basis.frequencies_hz[flap] == pytest.approx(66.8, rel=0.01)
    assert parts["K0omega"][2][flap, flap] == pytest.approx(SOUTHWELL_K1, rel=SOUTHWELL_RTOL)


def test_centrifugal_fields_are_omega_tilde_squared_x():
    x = np.array([[0.3, -0.7, 1.1]])
    w = np.array([0.4, -1.3, 0.9])
    W = np.array([w[0] ** 2, w[1] ** 2, w[2] ** 2, w[0] * w[1], w[1] * w[2], w[0] * w[2]])
    np.testing.assert_allclose(centrifugal_fields(x) @ W, np.cross(w, np.cross(w, x[0])), atol=1e-14)


def test_free_body_cases_superpose_to_the_equilibrated_stress_state():
    """Free bar pulled axially at the tip: a K0t_x - F K0F_x (3-2-1 supports, sid-spec 6.4) equals the
    projected K_G of the equilibrated state (F at the tip against m a, a = F/m) solved on a DIFFERENT
    support (the tip master clamped): the support reactions of the single cases cancel."""
    from sidprep.reduction.stiffening import projected_geometric_stiffness

    mesh = read_mesh(BAR)
    steel = builtin_material("steel")
    K, M = stiffness_matrix(mesh, steel), mass_matrix(mesh, steel)
    red = reduce_body(mesh, K, M, [make_interface(mesh, "fixed_end"), make_interface(mesh, "free_end")], n_modes=4)
    parts = stiffening_parts(mesh, steel, M, red.im, red.static_solve, red.Phi_fe)
    F = 1.0e4
    mass = np.ones(mesh.n_nodes) @ (M[0::3, 0::3] @ np.ones(mesh.n_nodes))
    combined = (F / mass) * parts["K0t"][0] - F * parts["K0F/1"][0]
    p = np.zeros(red.im.n_model)
    p[red.im.master_dofs[1][0]] = F                                     # tip force
    p -= (F / mass) * (red.im.T.T @ (M @ np.tile([1.0, 0, 0], mesh.n_nodes)))   # d'Alembert of a = F/m
    assert not np.isin(red.im.master_dofs[1], red.supports).all()
    u = red.im.T @ red.cb.static_solve(p[:, None], red.im.master_dofs[1])
    reference = projected_geometric_stiffness(mesh, steel, u, red.Phi_fe)[0]
    np.testing.assert_allclose(combined, reference, atol=1e-8 * np.abs(reference).max())
    assert np.trace(combined) > 0                                       # tension stiffens
