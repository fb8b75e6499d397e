"""Elastic (biharmonic-spline) interpolation from simulation nodes to animation points.

Independent references: rigid-body motion u = a + omega x c (closed form), the interpolation
conditions at the nodes, the Heckmann et al. 2006 section 5 plate (1 x 1.3, corner 4 moving), and the exact FE
surface modes the SID stores (piston rod, when the bundled mesh reduces within the test budget).
"""

import numpy as np
import pytest

from sidprep.interpolation import elastic_interpolation

RIGID_TOL = 1e-12          # rigid motion reproduced to round-off
NODE_TOL = 1e-12           # interpolation conditions at the nodes

PLATE_CORNERS = np.array([[0, 0, 0], [1, 0, 0], [0, 1.3, 0], [1, 1.3, 0.0]])  # Heckmann et al. 2006 section 5.1


def plate_grid():
    """The seed's 165 animation points: an 11 x 15 grid on the 1 x 1.3 plate."""
    x, y = np.meshgrid(np.linspace(0, 1, 11), np.linspace(0, 1.3, 15))
    return np.c_[x.ravel(), y.ravel(), np.zeros(x.size)]


def scattered(n, seed):
    return np.random.default_rng(seed).uniform(-0.5, 0.5, (n, 3)) * [2.0, 0.3, 0.1]


@pytest.mark.parametrize("nodes", [scattered(9, 1), PLATE_CORNERS, np.c_[np.linspace(0, 2, 5), 0 * np.ones((5, 2))]],
                         ids=["3d", "plate", "beam"])
def test_rigid_motion_exact(nodes):
    """u = a + omega x c at the nodes gives u = a + omega x x everywhere the nodes fix it: all of
    space for 3-D nodes, their plane or line for a plate or a beam."""
    centre = nodes.mean(0)
    _, s, vt = np.linalg.svd(nodes - centre)
    span = vt[s > 1e-9 * s[0]]
    points = centre + (np.random.default_rng(2).uniform(-1, 1, (200, 3)) @ span.T) @ span
    a, omega = np.array([0.3, -0.2, 0.1]), np.array([0.02, -0.05, 0.07])
    u = elastic_interpolation(nodes, points)(a + np.cross(omega, nodes))
    assert np.abs(u - (a + np.cross(omega, points))).max() < RIGID_TOL


def test_exact_at_nodes():
    nodes = scattered(12, 3)
    u = np.random.default_rng(4).normal(size=(12, 3, 5))
    interp = elastic_interpolation(nodes, nodes)
    assert np.abs(interp(u) - u).max() < NODE_TOL


def test_plate_smooth_without_artefacts():
    """Seed 000 s. 5: corner 4 lifted by 1; the field stays within the data range (no peaks)
    and has no jumps (cracks) between neighbouring grid points."""
    grid = plate_grid()
    interp = elastic_interpolation(PLATE_CORNERS, grid)
    u = np.zeros((4, 3))
    u[3, 2] = 1.0
    w = interp(u)[:, 2].reshape(15, 11)
    assert w[-1, -1] == pytest.approx(1.0, abs=NODE_TOL)
    assert w.max() <= 1.0 + 1e-12 and w.min() > -0.02          # overshoot below 2 % of the lift
    assert np.abs(np.diff(w, axis=0)).max() < 0.15              # grid steps 0.093 m: no cracks
    assert np.abs(np.diff(w, axis=1)).max() < 0.15
    second = np.abs(np.diff(w, 2, axis=1)).max() + np.abs(np.diff(w, 2, axis=0)).max()
    assert second < 0.05                                         # curvature bounded: smooth


PISTON_ROD_NODES = 97          # Heckmann et al. 2006 section 5: 97 simulation nodes on the piston rod
PISTON_ROD_FIRST_MODES = 5     # the first eigenmodes (262-1120 Hz) must stay below the target
PISTON_ROD_TARGET = 0.05       # max error / peak displacement


def farthest_points(points, n):
    """n well-spread rows of points (farthest-point sampling from row 0)."""
    chosen, dist = [0], np.linalg.norm(points - points[0], axis=1)
    for _ in range(n - 1):
        chosen.append(int(dist.argmax()))
        dist = np.minimum(dist, np.linalg.norm(points - points[chosen[-1]], axis=1))
    return np.array(chosen)


@pytest.fixture(scope="module")
def piston_rod_sid(tmp_path_factory):
    from pathlib import Path

    from sidprep.cli.main import main
    from sidprep.sid.io import read_sid
    mesh = Path(__file__).resolve().parents[1] / "data" / "meshes" / "piston_rod.msh"
    out = tmp_path_factory.mktemp("rod") / "rod.sid.h5"
    assert main(["reduce", str(mesh), "-o", str(out), "-q", "--no-sid-fem", "--no-obj"]) == 0
    return read_sid(out)


def test_piston_rod_surface_modes_from_97_nodes(piston_rod_sid):
    """Interpolate the stored exact FE surface modes from 97 surface nodes onto all of them."""
    surface = piston_rod_sid.surface
    chosen = farthest_points(surface.points, PISTON_ROD_NODES)
    interp = elastic_interpolation(surface.points[chosen], surface.points)
    u = interp(surface.shapes[chosen])
    err = np.linalg.norm(u - surface.shapes, axis=1).max(0) / np.linalg.norm(surface.shapes, axis=1).max(0)
    assert err[:PISTON_ROD_FIRST_MODES].max() < PISTON_ROD_TARGET, err
