"""Paths on FE-reduced bodies (sidprep.reduction.paths): curves through points or ordered
node sets, resampled at equal arc length, with the mode shapes interpolated from the full FE
modes; against closed forms (arc lengths of a parabola and a circle, polynomial fields that P2
elements represent exactly) and the straight-segment path."""

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from sidprep.cli.main import main
from sidprep.errors import InputError
from sidprep.fe.mesh import read_mesh
from sidprep.reduction.paths import fe_path, located_paths, parse_path, path_samples, uniform_arc_length_samples

MESHES = Path(__file__).resolve().parents[1] / "data" / "meshes"
#: the parabola y = 0.025 + 0.04 x (1 - x) through 3 points (the not-a-knot spline is exactly it):
#: arc lengths against the closed form, m (measured 3.3e-16)
PARABOLA_S_TOL = 1e-13
#: a quarter circle R = 0.5 m through 13 points: the spline's length and the samples' angles
#: against R theta, relative / rad (measured 3.2e-7 and 6.7e-7: the spline's own error, O(h^4))
CIRCLE_RTOL = 1e-6
#: mode shapes interpolated along a path against the exact field / the straight path, fraction
#: of the largest value (measured: quadratic field 4.2e-16 phi, 1.3e-14 psi; edge nodes 1.5e-16)
SHAPE_RTOL = 1e-9
#: piston_rod.msh: its bores' mid-edge nodes lie up to 1.1 mm inside the nominal radius
#: (data/meshes/README.md), the most a surface point lies outside the facets
PISTON_FACET_GAP = 1.1e-3
#: piston_rod.msh big-end eye: outer radius, m (data/meshes/README.md)
EYE_RADIUS = 0.048


def parabola_length(x):
    """Closed-form arc length of y = 0.025 + 0.04 x (1 - x) from 0 to x."""
    def F(u):
        return 0.5 * (u * np.sqrt(1 + u * u) + np.arcsinh(u))
    return (F(0.04) - F(0.04 * (1 - 2 * x))) / 0.08


def quadratic_field(rng, nq=3):
    """u(x) (n, 3, nq) and 1/2 curl u (n, 3, nq) of a random quadratic polynomial field."""
    a, B, C = rng.normal(size=(3, nq)), rng.normal(size=(3, 3, nq)), rng.normal(size=(3, 3, 3, nq))

    def u(x):
        return a + np.einsum("cdq,nd->ncq", B, x) + np.einsum("cdeq,nd,ne->ncq", C, x, x)

    def half_curl(x):
        g = B[None] + np.einsum("cdeq,ne->ncdq", C + C.transpose(0, 2, 1, 3), x)      # d u_c / d x_d
        return 0.5 * np.stack([g[:, 2, 1] - g[:, 1, 2], g[:, 0, 2] - g[:, 2, 0], g[:, 1, 0] - g[:, 0, 1]], axis=1)
    return u, half_curl


def nodal(mesh, u):
    """Phi_fe (3 n_nodes, nq) of a field u."""
    values = u(mesh.points)
    return values.reshape(3 * mesh.n_nodes, values.shape[2])


@pytest.fixture(scope="module")
def bar():
    return read_mesh(MESHES / "bar.msh")


def test_a_three_point_path_is_the_parabola_sampled_at_equal_arc_length():
    s, x = uniform_arc_length_samples(parse_path("p:0,0.025,0.04:0.5,0.035,0.04:1,0.025,0.04:51").points, 51)
    np.testing.assert_allclose(x[:, 1], 0.025 + 0.04 * x[:, 0] * (1 - x[:, 0]), rtol=0, atol=1e-15)
    np.testing.assert_allclose(s, parabola_length(x[:, 0]), rtol=0, atol=PARABOLA_S_TOL)


def test_a_circle_arc_through_many_points_has_length_r_theta():
    R, theta = 0.5, np.linspace(0.0, np.pi / 2, 13)
    s, x = uniform_arc_length_samples(np.c_[R * np.cos(theta), R * np.sin(theta), np.zeros(13)], 201)
    assert abs(s[-1] / (R * np.pi / 2) - 1) < CIRCLE_RTOL
    np.testing.assert_allclose(np.arctan2(x[:, 1], x[:, 0]), s / R, rtol=0, atol=CIRCLE_RTOL)


def test_two_points_and_collinear_points_give_the_straight_segment():
    a, b = np.array([0.1, 0.2, 0.3]), np.array([0.9, -0.2, 0.5])
    straight = a + np.outer(np.linspace(0, 1, 21), b - a)
    for inner in ([], [0.07], [0.3, 0.35, 0.9]):
        s, x = uniform_arc_length_samples(np.array([a] + [a + t * (b - a) for t in inner] + [b]), 21)
        np.testing.assert_allclose(x, straight, rtol=0, atol=1e-15)
        np.testing.assert_allclose(s, np.linspace(0, np.linalg.norm(b - a), 21), rtol=0, atol=1e-15)


def test_curved_path_shapes_are_the_exact_quadratic_field(bar):
    """P2 on straight-sided tet10 holds quadratic fields exactly: phi and psi along a wavy curve
    through the bar equal the field and half its curl at the samples."""
    u, half_curl = quadratic_field(np.random.default_rng(1))
    spec = parse_path("wave:0.05,0.025,0.04:0.3,0.04,0.05:0.6,0.01,0.03:0.95,0.025,0.06:81")
    path = fe_path(bar, nodal(bar, u), path_samples(bar, spec))
    exact = u(path.points)
    assert np.abs(path.phi - exact).max() < SHAPE_RTOL * np.abs(exact).max()
    assert np.abs(path.psi - half_curl(path.points)).max() < SHAPE_RTOL * np.abs(exact).max()
    np.testing.assert_allclose(path.points[[0, -1]], spec.points[[0, -1]], rtol=0, atol=0)


def test_nodes_of_an_edge_ordered_along_x_reproduce_the_straight_path(bar):
    edge = np.flatnonzero((np.abs(bar.points[:, 1]) < 1e-9) & (np.abs(bar.points[:, 2]) < 1e-9))
    mesh = replace(bar, node_sets={**bar.node_sets, "edge": edge})
    Phi = np.random.default_rng(2).normal(size=(3 * mesh.n_nodes, 4))
    by_nodes = fe_path(mesh, Phi, path_samples(mesh, parse_path("edge:nodes=edge:dir=x:101")))
    straight = fe_path(mesh, Phi, path_samples(mesh, parse_path("line:0,0,0:1,0,0:101")))
    assert len(edge) > 20
    np.testing.assert_allclose(by_nodes.points, straight.points, rtol=0, atol=1e-15)
    for name in ("phi", "psi"):
        a, b = getattr(by_nodes, name), getattr(straight, name)
        assert np.abs(a - b).max() < SHAPE_RTOL * np.abs(b).max()
    backwards = fe_path(mesh, Phi, path_samples(mesh, parse_path("back:nodes=edge:dir=-x:101")))
    np.testing.assert_allclose(backwards.phi, straight.phi[::-1], rtol=0, atol=SHAPE_RTOL * np.abs(Phi).max())


def test_a_path_on_the_curved_surface_of_the_piston_rod_eye_is_accepted():
    """Points on the eye's outer cylinder lie outside the faceted tet10 mesh (by up to the
    sagitta of the facets); they take the nearest element's shapes. A linear field is then off
    by at most its gradient times that gap."""
    mesh = read_mesh(MESHES / "piston_rod.msh")
    angle = np.radians(np.linspace(45.0, 315.0, 9))
    points = np.c_[EYE_RADIUS * np.cos(angle), EYE_RADIUS * np.sin(angle), np.full(9, 0.005)]
    spec = parse_path("rim:" + ":".join(",".join(f"{v:.17g}" for v in p) for p in points))
    samples = path_samples(mesh, spec)
    corners = mesh.points[mesh.cells[samples.element, :4]]
    at = np.einsum("na,nac->nc", samples.L, corners)
    gap = np.linalg.norm(at - samples.points, axis=1)
    assert 0.1 * PISTON_FACET_GAP < gap.max() < PISTON_FACET_GAP    # samples outside (0.59 mm), all taken
    B = np.random.default_rng(3).normal(size=(3, 3))
    path = fe_path(mesh, (mesh.points @ B.T).reshape(-1, 1), samples)
    assert np.abs(path.phi[:, :, 0] - samples.points @ B.T).max() <= np.linalg.norm(B, 2) * gap.max() + 1e-12


def test_a_point_1_cm_outside_the_piston_rod_is_a_one_line_error(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    r = EYE_RADIUS + 0.01
    argv = ["reduce", str(MESHES / "piston_rod.msh"), "-q", "--path", f"out:0,{r},0.005:-{r},0,0.005:0,-{r},0.005"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("sidprep: error: path 'out': the point") and "outside the mesh" in err and "\n" not in err
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("spec, message", [
    ("p:0,0,0", "needs two or more points"),
    ("p:0,0,0:0,0,0:1,0,0", "two consecutive points are the same"),
    ("p:nodes=free_end", "needs exactly nodes=SET and dir"),
    ("p:nodes=free_end:dir=w", "dir=w is not a direction"),
    ("p:nodes=rail:dir=x", "no node set 'rail'"),
    ("p:nodes=free_end:dir=y", "lie at the same position along dir"),
    ("p:nodes=one:dir=x", "has 1 node"),
    ("p:0,0.025,0.04:1.5,0.025,0.04", "outside the mesh"),
])
def test_bad_paths_are_one_line_errors_before_the_fe_work(bar, spec, message):
    mesh = replace(bar, node_sets={**bar.node_sets, "one": bar.node_sets["free_end"][:1]})
    with pytest.raises(InputError, match=message) as info:
        path_samples(mesh, parse_path(spec))
    assert "\n" not in str(info.value)


def test_a_path_name_given_twice_is_an_error(bar):
    with pytest.raises(InputError, match="path 'p' is given twice"):
        located_paths(bar, ["p:0,0.025,0.04:1,0.025,0.04", "q:0,0,0:1,0,0", "p:0,0,0:1,0,0"])


def test_path_coordinates_are_in_the_jobs_units():
    np.testing.assert_array_equal(parse_path("p:0,0,0:1000,0,0", 1e-3).points, [[0, 0, 0], [1, 0, 0]])


def test_a_job_file_curved_path_ends_at_the_rigid_end_faces(tmp_path, capsys):
    """`paths` in a job file: the parabola from the centre of the fixed_end face to that of
    free_end; both faces are RBE2, so the path's end shapes are the masters' (nodal shapes)."""
    import sidprep

    job = tmp_path / "bar.toml"
    job.write_text(f'mesh = "{MESHES / "bar.msh"}"\nmodes = 4\ncheck_frequencies = false\nobj = false\n'
                   'sid_fem = false\noutput = "bar.sid.h5"\n'
                   'paths = ["wave:0,0.025,0.04:0.5,0.035,0.04:1,0.025,0.04:41"]\n')
    assert main(["reduce", str(job), "-q"]) == 0
    sid = sidprep.read_sid(tmp_path / "bar.sid.h5")
    path = sid.paths["wave"]
    scale = np.abs(path.phi).max()
    assert np.abs(path.phi[0] - sid.nodes[0].phi.M0).max() < SHAPE_RTOL * scale
    assert np.abs(path.phi[-1] - sid.nodes[1].phi.M0).max() < SHAPE_RTOL * scale
    np.testing.assert_allclose(path.s, parabola_length(path.points[:, 0]), rtol=0, atol=PARABOLA_S_TOL)
