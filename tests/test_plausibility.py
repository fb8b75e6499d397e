"""Unit plausibility warnings a mesh in mm run as SI must not pass silently.

References: the bundled meshes' geometry (bar 1.0 x 0.05 x 0.08 m, piston rod 0.494 m long) and
the frequencies in data/meshes/README.md computed with plain scikit-fem.
"""

from pathlib import Path

import pytest

from sidprep.fe.material import builtin_material
from sidprep.fe.mesh import read_mesh
from sidprep.fe.topology import cell_volumes
from sidprep.fe.plausibility import unit_warnings

MESHES = Path(__file__).resolve().parents[1] / "data" / "meshes"
STEEL = builtin_material("steel")
#: first frequency of the piston rod with both bores held (data/meshes/README.md, scikit-fem P2)
PISTON_ROD_F1_HZ = 808.4
#: first cantilever bending frequency of bar.msh (data/meshes/README.md, scikit-fem P2)
BAR_CANTILEVER_F1_HZ = 41.93


def points_and_mass(name, scale=1.0):
    mesh = read_mesh(MESHES / name)
    points = mesh.points * scale
    return points, float(cell_volumes(points, mesh.cells[:, :4]).sum() * STEEL.rho)


def test_bar_drawn_in_mm_run_as_si_warns_and_names_units_option():
    points, mass = points_and_mass("bar.msh", scale=1e3)      # 1000 mm read as 1000 m
    assert mass == pytest.approx(3.14e10, rel=1e-3)           # the 3.14e10 kg
    warnings = unit_warnings(points, STEEL, mass, BAR_CANTILEVER_F1_HZ / 1e3)
    assert len(warnings) >= 2 and all("--units mm-t-s" in w for w in warnings)


@pytest.mark.parametrize("name, f1", [("piston_rod.msh", PISTON_ROD_F1_HZ),
                                      ("bar.msh", BAR_CANTILEVER_F1_HZ)])
def test_bundled_parts_in_si_give_no_warning(name, f1):
    points, mass = points_and_mass(name)
    assert unit_warnings(points, STEEL, mass, f1) == []


def test_si_mesh_scaled_as_mm_warns():
    points, mass = points_and_mass("piston_rod.msh", scale=1e-3)
    assert any("drop --units mm-t-s" in w for w in unit_warnings(points, STEEL, mass))


def test_frequency_far_from_wave_speed_estimate_warns():
    points, mass = points_and_mass("piston_rod.msh")
    warnings = unit_warnings(points, STEEL, mass, PISTON_ROD_F1_HZ * 1e3)
    assert len(warnings) == 1 and "wave-speed estimate" in warnings[0]


def test_modes_and_reduce_warn_end_to_end(tmp_path, capsys):
    """`sidprep modes` and `sidprep reduce` of the bar drawn in millimetres but run as SI print the
    warning (stderr) naming --units mm-t-s; run with --units mm-t-s they do not."""
    import meshio

    from sidprep.cli.main import main

    m = meshio.read(MESHES / "bar.msh")
    m.points = m.points * 1000.0
    mm = tmp_path / "bar_mm.msh"
    meshio.write(mm, m, file_format="gmsh22", binary=False)
    assert main(["modes", str(mm), "--count", "2", "--json"]) == 0
    assert "--units mm-t-s" in capsys.readouterr().err
    assert main(["reduce", str(mm), "--modes", "2", "--no-frm", "-o", str(tmp_path / "bar.sid.h5")]) == 0
    assert "--units mm-t-s" in capsys.readouterr().err
    assert main(["modes", str(mm), "--count", "2", "--units", "mm-t-s", "--json"]) == 0
    assert "--units" not in capsys.readouterr().err
