"""Guyan / Craig-Bampton against the full FE model of the bundled cantilever bar."""

from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

from sidprep.fe.assemble import mass_matrix, stiffness_matrix
from sidprep.errors import InputError
from sidprep.reduction.interfaces import interface_model, make_interface
from sidprep.fe.linalg import eigen_modes, factorize
from sidprep.fe.material import builtin_material
from sidprep.fe.mesh import read_mesh
from sidprep.reduction.modes import eigen_pairs, hz
from sidprep.reduction.craig_bampton import craig_bampton, guyan

BAR = Path(__file__).resolve().parents[1] / "data" / "meshes" / "bar.msh"
#: Guyan condensation is exact for loads at the boundary: round-off only
GUYAN_STATIC_RTOL = 1e-8
#: Rayleigh-Ritz bound: reduced frequencies may not fall below the full ones beyond round-off
RITZ_SLACK = 1e-9


@pytest.fixture(scope="module")
def model():
    """Bar with RBE2 masters on both end faces, in model DOFs; the fixed_end master is clamped."""
    mesh = read_mesh(BAR)
    steel = builtin_material("steel")
    im = interface_model(mesh.n_nodes, [make_interface(mesh, "fixed_end"), make_interface(mesh, "free_end")],
                         mesh.points)
    K, M = im.project(stiffness_matrix(mesh, steel)), im.project(mass_matrix(mesh, steel))
    keep = np.setdiff1d(np.arange(im.n_model), im.master_dofs[0])
    K, M = K[keep][:, keep], M[keep][:, keep]
    tip = np.flatnonzero(np.isin(keep, im.master_dofs[1]))
    return K, M, tip


def test_craig_bampton_converges_from_above(model):
    K, M, tip = model
    full = eigen_modes(K, M, count=5).frequencies_hz
    previous = np.full(5, np.inf)
    for n in (2, 5, 10, 20, 40):
        r = craig_bampton(K, M, tip, n_modes=n)
        f = hz(eigen_pairs(r.K, r.M)[0])[:5]
        assert np.all(f >= full * (1 - RITZ_SLACK)), n
        assert np.all(f <= previous * (1 + RITZ_SLACK)), n
        previous = f
    np.testing.assert_allclose(previous, full, rtol=1e-4)


def test_guyan_static_deflection_at_the_masters_is_exact(model):
    K, M, tip = model
    g = guyan(K, M, tip)
    u_full = factorize(sp.csc_matrix(K)).solve(np.eye(K.shape[0])[:, tip].copy())[tip]
    np.testing.assert_allclose(np.linalg.inv(g.K), u_full, rtol=GUYAN_STATIC_RTOL,
                               atol=GUYAN_STATIC_RTOL * np.abs(u_full).max())
    assert g.basis.shape == (K.shape[0], 6) and len(g.fixed_interface_hz) == 0


def test_fixed_interface_modes_up_to_fmax(model):
    K, M, tip = model
    r = craig_bampton(K, M, tip, fmax=1500.0)
    assert r.fixed_interface_hz.max() <= 1500.0 and len(r.fixed_interface_hz) >= 4
    np.testing.assert_allclose(r.basis[tip][:, :6], np.eye(6))
    # fixed-interface modes vanish at the boundary and are M-normalised
    assert np.abs(r.basis[tip][:, 6:]).max() == 0
    np.testing.assert_allclose(np.diag(r.M)[6:], 1.0, rtol=1e-10)


def test_singular_interior_is_an_input_error():
    K = sp.csr_matrix(np.array([[1.0, -1, 0], [-1, 1, 0], [0, 0, 1]]))
    with pytest.raises(InputError, match="interfaces do not hold the body"):
        craig_bampton(K, sp.identity(3, format="csr"), [2], n_modes=1)


def test_static_condensation_through_the_cb_factor_is_exact(model):
    """ReducedModel.static_solve vs a direct sparse solve, interior and boundary loads, partial supports."""
    K, M, tip = model
    r = craig_bampton(K, M, tip, n_modes=3)
    P = np.random.default_rng(0).normal(size=(K.shape[0], 2))
    supports = tip[:3]                 # the tip master's translations held: the model stays regular
    P[supports] = 0.0
    free = np.setdiff1d(np.arange(K.shape[0]), supports)
    ref = np.zeros_like(P)
    ref[free] = factorize(sp.csc_matrix(K[free][:, free])).solve(P[free].copy())
    np.testing.assert_allclose(r.static_solve(P, supports), ref, rtol=1e-8, atol=1e-8 * np.abs(ref).max())
