"""The bundled meshes: documented groups, sizes, geometry, frequencies and reproducibility."""

import importlib.util
import sys
from pathlib import Path

import gmsh
import numpy as np
import pytest

from sidprep.fe.mesh import read_mesh
from sidprep.fe.topology import TET10_EDGES, connected_parts

MESHES = Path(__file__).resolve().parents[1] / "data" / "meshes"
#: the paper's (Heckmann et al. 2006, section 6.4) lowest piston-rod modes and the accepted gap
PAPER_PISTON_ROD_HZ = (809.0, 1040.0, 1244.0)
PAPER_RTOL = 0.15
#: the frequencies documented in data/meshes/README.md, to the printed digits
README_PISTON_ROD_HZ = (808.4, 1046.9, 1251.8)
README_DIGITS_ATOL_HZ = 0.05
#: the committed files must stay small
MAX_FILE_BYTES = 3_000_000


def _load(name):
    """Import a generator script the way it runs: with its own folder on the import path."""
    if str(MESHES) not in sys.path:
        sys.path.insert(0, str(MESHES))
    spec = importlib.util.spec_from_file_location(name, MESHES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def rod():
    return read_mesh(MESHES / "piston_rod.msh")


@pytest.fixture(scope="module")
def bar():
    return read_mesh(MESHES / "bar.msh")


def _straight_edged(mesh):
    p, c = mesh.points, mesh.cells
    return all(np.allclose(p[c[:, 4 + k]], (p[c[:, a]] + p[c[:, b]]) / 2, atol=1e-12) for k, (a, b) in enumerate(TET10_EDGES))


def test_piston_rod_groups_and_size(rod):
    assert (MESHES / "piston_rod.msh").stat().st_size < MAX_FILE_BYTES
    assert rod.order == 2 and (rod.n_nodes, len(rod.cells), rod.n_dof) == (5343, 2546, 16029)
    assert set(rod.node_sets) == {"big_end", "small_end"} and set(rod.cell_sets) == {"rod"}
    assert len(rod.cell_sets["rod"]) == len(rod.cells)
    assert rod.notes == () and connected_parts(rod)[0] == 1 and _straight_edged(rod)
    # the node sets are the bores: at the nominal radius (mid-edge nodes on chords of the
    # 12 mm elements: sag h^2 / 8r < 1.2 mm), over the whole eye width
    for name, centre_x, radius in [("big_end", 0.0, 0.030), ("small_end", 0.42, 0.014)]:
        x = rod.points[rod.node_sets[name]]
        r = np.hypot(x[:, 0] - centre_x, x[:, 1])
        assert r.max() <= radius + 1e-9 and r.min() > radius - 0.0012
        assert np.isclose(x[:, 2].min(), -0.013) and np.isclose(x[:, 2].max(), 0.013)


def test_piston_rod_frequencies_match_the_paper(rod):
    """Both bores held, steel: the README's numbers, within 15 % of Heckmann et al. 2006's 809/1040/1244 Hz."""
    check = _load("_modal_check")
    f = check.clamped_frequencies_hz(rod, ["big_end", "small_end"], **_load("make_piston_rod").STEEL)
    assert np.allclose(f, README_PISTON_ROD_HZ, atol=README_DIGITS_ATOL_HZ)
    assert np.allclose(f, PAPER_PISTON_ROD_HZ, rtol=PAPER_RTOL)


def test_bar_groups_and_size(bar):
    assert (MESHES / "bar.msh").stat().st_size < MAX_FILE_BYTES
    assert bar.order == 2 and (bar.n_nodes, bar.n_dof) == (1124, 3372) and _straight_edged(bar)
    assert set(bar.node_sets) == {"fixed_end", "free_end"} and set(bar.cell_sets) == {"bar"}
    assert np.allclose(bar.points.min(axis=0), 0) and np.allclose(bar.points.max(axis=0), [1.0, 0.05, 0.08])
    for name, x in [("fixed_end", 0.0), ("free_end", 1.0)]:
        on_face = np.flatnonzero(np.abs(bar.points[:, 0] - x) < 1e-12)
        assert np.array_equal(bar.node_sets[name], on_face)


def test_bar_first_bending_matches_euler_bernoulli(bar):
    """Slender cantilever: 3D P2 first bending about both axes vs Euler-Bernoulli within 1 %."""
    make_bar = _load("make_bar")
    f = _load("_modal_check").clamped_frequencies_hz(bar, ["fixed_end"], count=2, **make_bar.STEEL)
    eb = make_bar.euler_bernoulli_first_hz(1.0, 0.05, 0.08, make_bar.STEEL["E"], make_bar.STEEL["rho"])
    assert np.allclose(f, eb, rtol=0.01)


@pytest.mark.skipif(not gmsh.__version__.startswith("4.15"), reason="bytes are gmsh-version specific")
def test_bar_script_reproduces_the_committed_file(tmp_path):
    out = tmp_path / "bar.msh"
    _load("make_bar").mesh_and_write(_load("make_bar").parse_args(["--out", str(out)]))
    assert out.read_bytes() == (MESHES / "bar.msh").read_bytes()
