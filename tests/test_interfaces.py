"""RBE2 / RBE3 interfaces: rigid patch motion, least-squares averaging, no added stiffness."""

from pathlib import Path

import numpy as np
import pytest

from sidprep.fe.assemble import mass_matrix, stiffness_matrix
from sidprep.errors import InputError
from sidprep.reduction.interfaces import (interface_model, make_interface, nodes_on_cylinder, nodes_on_plane,
                                rbe3_averaging, rigid_modes_model, rigid_rows)
from sidprep.fe.linalg import eigen_modes
from sidprep.fe.material import builtin_material
from sidprep.fe.mesh import read_mesh

BAR = Path(__file__).resolve().parents[1] / "data" / "meshes" / "bar.msh"
ROD = Path(__file__).resolve().parents[1] / "data" / "meshes" / "piston_rod.msh"
#: round-off level of the transformations
EXACT = 1e-10


@pytest.fixture(scope="module")
def bar():
    mesh = read_mesh(BAR)
    steel = builtin_material("steel")
    return mesh, stiffness_matrix(mesh, steel), mass_matrix(mesh, steel)


def test_rbe2_patch_follows_master_rigidly(bar):
    mesh, _, _ = bar
    itf = make_interface(mesh, "free_end", kind="rbe2")
    im = interface_model(mesh.n_nodes, [itf], mesh.points)
    z = np.zeros(im.n_model)
    z[im.master_dofs[0]] = [1e-3, -2e-3, 0.5e-3, 0.01, -0.02, 0.03]
    u = (im.T @ z).reshape(-1, 3)
    r = mesh.points[itf.nodes] - itf.master_point
    expected = z[im.master_dofs[0][:3]] + np.cross(z[im.master_dofs[0][3:]], r)
    np.testing.assert_allclose(u[itf.nodes], expected, atol=EXACT)
    others = np.setdiff1d(np.arange(mesh.n_nodes), itf.nodes)
    assert np.abs(u[others]).max() == 0.0


def test_master_at_patch_centroid(bar):
    mesh, _, _ = bar
    itf = make_interface(mesh, "free_end")
    np.testing.assert_allclose(itf.master_point, [1.0, 0.025, 0.04], atol=1e-12)


@pytest.mark.parametrize("kind", ["rbe2", "rbe3"])
def test_rigid_motion_in_model_dofs_maps_to_rigid_fe_motion(bar, kind):
    mesh, _, _ = bar
    itfs = [make_interface(mesh, "fixed_end", kind=kind), make_interface(mesh, "free_end", kind=kind)]
    im = interface_model(mesh.n_nodes, itfs, mesh.points)
    R_fe = rigid_rows(mesh.points).reshape(-1, 6)
    np.testing.assert_allclose(im.T @ rigid_modes_model(im, mesh.points), R_fe, atol=EXACT)


def test_rbe3_master_is_the_weighted_least_squares_rigid_fit():
    """Independent reference: numpy lstsq of min sum w_i |u_i - a - theta x (x_i - x_m)|^2."""
    rng = np.random.default_rng(1)
    x = rng.normal(size=(9, 3))
    w = rng.uniform(0.5, 2.0, 9)
    xm = np.array([0.3, -0.2, 0.1])
    u = rng.normal(size=(9, 3))
    A = rigid_rows(x - xm).reshape(-1, 6) * np.sqrt(np.repeat(w, 3))[:, None]
    ref = np.linalg.lstsq(A, u.ravel() * np.sqrt(np.repeat(w, 3)), rcond=None)[0]
    np.testing.assert_allclose(rbe3_averaging(x, w, xm) @ u.ravel(), ref, atol=1e-12)


def test_rbe3_uniform_patch_translation_is_master_translation(bar):
    mesh, _, _ = bar
    itf = make_interface(mesh, "free_end", kind="rbe3")
    W = rbe3_averaging(mesh.points[itf.nodes], itf.weights, itf.master_point)
    t = np.array([1.0, -2.0, 3.0])
    np.testing.assert_allclose(W @ np.tile(t, len(itf.nodes)), np.r_[t, 0, 0, 0], atol=EXACT)


def test_rbe3_adds_no_stiffness_rbe2_does(bar):
    """T is square and invertible for RBE3: the free-free spectrum is unchanged; RBE2 stiffens."""
    mesh, K, M = bar

    def elastic(K, M):
        ev = eigen_modes(K, M, count=6)
        return ev.eigenvalues[ev.n_rigid:]

    ref = elastic(K, M)
    for kind, same in (("rbe3", True), ("rbe2", False)):
        itfs = [make_interface(mesh, "fixed_end", kind=kind), make_interface(mesh, "free_end", kind=kind)]
        im = interface_model(mesh.n_nodes, itfs, mesh.points)
        lam = elastic(im.project(K), im.project(M))
        if same:
            np.testing.assert_allclose(lam, ref, rtol=1e-8)
        else:
            assert np.all(lam >= ref * (1 - 1e-10)) and (lam / ref - 1).max() > 1e-5


def test_geometric_selection_matches_node_sets(bar):
    mesh, _, _ = bar
    np.testing.assert_array_equal(nodes_on_plane(mesh.points, [1.0, 0, 0], [1, 0, 0], 1e-9),
                                  mesh.node_sets["free_end"])
    itf = make_interface(mesh, "tip", selection={"type": "plane", "point": [1, 0, 0], "normal": [1, 0, 0],
                                                 "tol": 1e-9})
    np.testing.assert_array_equal(itf.nodes, mesh.node_sets["free_end"])


def test_cylinder_selection_finds_the_big_end_bore():
    mesh = read_mesh(ROD)
    sel = nodes_on_cylinder(mesh.points, [0, 0, 0], [0, 0, 1], 0.030, 1.2e-3)
    big = mesh.node_sets["big_end"]
    assert np.isin(big, sel).all() and len(sel) == len(big)


@pytest.mark.parametrize("selection, message", [
    ({"type": "sphere", "center": [0.5, 0.025, 0.04], "radius": 1e-4, "tol": 1e-6}, "0 node"),
    ({"type": "cone"}, "valid: plane, cylinder, sphere"),
    ({"type": "plane", "point": [0, 0, 0]}, "missing normal, tol"),
    ("nowhere", "valid: fixed_end, free_end"),
])
def test_bad_patches_raise_one_line_errors(bar, selection, message):
    mesh, _, _ = bar
    with pytest.raises(InputError, match=message) as err:
        make_interface(mesh, "x", selection=selection)
    assert "\n" not in str(err.value)


def test_collinear_patch_cannot_carry_rotations(bar):
    mesh, _, _ = bar
    edge = np.flatnonzero((np.abs(mesh.points[:, 1]) < 1e-9) & (np.abs(mesh.points[:, 2]) < 1e-9))
    assert len(edge) >= 3
    mesh2 = type(mesh)(mesh.points, mesh.cells, mesh.node_ids, {"edge": edge})
    with pytest.raises(InputError, match="collinear"):
        make_interface(mesh2, "edge")


def test_overlapping_interfaces_are_rejected(bar):
    mesh, _, _ = bar
    a = make_interface(mesh, "free_end")
    with pytest.raises(InputError, match="share"):
        interface_model(mesh.n_nodes, [a, a], mesh.points)


def test_unknown_kind(bar):
    with pytest.raises(InputError, match="valid: rbe2, rbe3"):
        make_interface(bar[0], "free_end", kind="rbe9")
