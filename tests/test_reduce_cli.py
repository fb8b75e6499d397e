"""``sidprep reduce`` end to end: defaults on the piston rod, job files, one-line errors."""

import json
from pathlib import Path

import numpy as np
import pytest

from sidprep.cli.main import main
from sidprep.sid.io.sid_fem import read_sid_fem
from sidprep.sid.checks import failed_checks
from sidprep.sid.io.sid_hdf5 import read_checks, read_sid_hdf5
from sidprep.jobs.options import DEFAULT_MODES

MESHES = Path(__file__).resolve().parents[1] / "data" / "meshes"


def test_defaults_on_the_piston_rod_write_three_files_and_pass_the_checks(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["reduce", str(MESHES / "piston_rod.msh"), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    files = {k: Path(v) for k, v in summary["files"].items()}
    assert sorted(p.name for p in files.values()) == ["piston_rod.SID_FEM", "piston_rod.obj", "piston_rod.sid.h5"]
    assert all((tmp_path / p).is_file() for p in files.values())
    checks = summary["checks"]
    assert checks["passed"] and checks["zero_energy_modes"] == 6
    assert checks["eigen_frequency_max_rel_error"] < 1e-3
    stored = read_checks(tmp_path / files["hdf5"])
    assert stored["FE mass"].passed and stored["FE eigenfrequencies"].passed
    assert not failed_checks(stored)                                       # sid-spec 4.8 identities too
    sid = read_sid_hdf5(tmp_path / files["hdf5"])
    assert [n.name for n in sid.nodes] == ["big_end", "small_end"]
    assert sid.mode_kinds[:6] == ("eigen",) * 6 and "frm" in sid.mode_kinds
    assert sid.labels[0].startswith("Eigen Mode    7 :")
    np.testing.assert_allclose(sid.Me.M0, np.eye(sid.nq), atol=1e-9)
    np.testing.assert_allclose(sid.Ct.M0, 0, atol=1e-9 * sid.mass)       # free frame: mean axes
    assert sid.surface is not None and sid.surface.shapes.shape[2] == sid.nq
    ascii_sid = read_sid_fem(tmp_path / files["sid_fem"])
    np.testing.assert_allclose(ascii_sid.Ke.M0, sid.Ke.M0, rtol=1e-10)
    assert (tmp_path / files["obj"]).read_text().count("\nf ") == len(sid.surface.triangles)


def test_job_file_with_rbe3_attached_frame_and_stiffening(tmp_path, capsys):
    job = tmp_path / "bar.toml"
    job.write_text(f'mesh = "{MESHES / "bar.msh"}"\ninterfaces = ["fixed_end:rbe2", {{name = "tip", kind = "rbe3", '
                   'type = "plane", point = [1.0, 0, 0], normal = [1, 0, 0], tol = 1e-6}]\n'
                   'frame = "fixed_end"\nfmax = 300.0\nstiffening = true\nobj = false\n'
                   f'output = "{tmp_path / "out" / "bar.sid.h5"}"\ndamping = [0.01, 0.02, 0.03]\n')
    assert main(["reduce", str(job), "--quiet", "--no-frm", "--json", "--rayleigh", "2.0", "4e-5"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert set(summary["files"]) == {"hdf5", "sid_fem"}
    sid = read_sid_hdf5(tmp_path / "out" / "bar.sid.h5")
    np.testing.assert_allclose(sid.frequencies_hz[:3], [41.93, 66.77, 259.97], rtol=2e-3)
    assert "K0F/1" in sid.stiffening and sid.Ct.M1 is not None
    assert [n.name for n in sid.nodes] == ["fixed_end", "tip"]
    np.testing.assert_allclose(sid.nodes[1].origin.M0.ravel(), [1.0, 0.025, 0.04], atol=1e-12)
    np.testing.assert_allclose(sid.nodes[0].phi.M0, 0, atol=1e-15)         # the frame master is held
    w = 2 * np.pi * sid.frequencies_hz                                      # --rayleigh overrides the file
    np.testing.assert_allclose(np.diag(sid.De.M0), 2.0 + 4e-5 * w ** 2, rtol=1e-12)


@pytest.mark.parametrize("argv, message", [
    (["--frame", "nowhere"], "--frame nowhere: no such interface; valid: free, fixed_end, free_end"),
    (["--interface", "free_end:rbe9"], "expected NAME[:rbe2|rbe3]"),
    (["--interface", "tip"], "valid: fixed_end, free_end"),
    (["--modes", "0"], "--modes 0: must be >= 1"),
    (["--material", "cheese"], "unknown material"),
    (["--cutoff-factor", "0.5"], "must be >= 1"),
])
def test_bad_options_give_one_line_errors(tmp_path, monkeypatch, capsys, argv, message):
    monkeypatch.chdir(tmp_path)
    assert main(["reduce", str(MESHES / "bar.msh"), "-q"] + argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("sidprep: error:") and message in err and "\n" not in err
    assert not list(tmp_path.iterdir())                                     # nothing written


def test_bad_job_files(tmp_path, capsys):
    job = tmp_path / "job.toml"
    job.write_text('mesh = "bar.msh"\nmodez = 3\n')
    assert main(["reduce", str(job)]) == 2
    assert "unknown key(s) modez; valid:" in capsys.readouterr().err
    job.write_text('frame = "free"\n')
    assert main(["reduce", str(job)]) == 2
    assert "needs mesh" in capsys.readouterr().err


def test_mm_t_s_units_and_a_body_without_interfaces(tmp_path, capsys):
    """The bar in mm with MPa and t/mm^3 gives the SI body; no node sets: 3-2-1 CB boundary, no FRMs."""
    import meshio

    from sidprep.fe.mesh import read_mesh

    bar = read_mesh(MESHES / "bar.msh")
    labels = {}
    for units, scale, material in (("si", 1.0, ["--material", "steel"]),
                                   ("mm-t-s", 1e3, ["--E", "210000", "--nu", "0.3", "--rho", "7.85e-9"])):
        path = tmp_path / f"bar_{units}.vtu"
        meshio.write(path, meshio.Mesh(bar.points * scale, [("tetra10", bar.cells)]))
        assert main(["reduce", str(path), "--units", units, *material, "-q", "--json", "--no-obj", "--no-sid-fem",
                     "-o", str(tmp_path / f"{units}.sid.h5")]) == 0
        summary = json.loads(capsys.readouterr().out)
        assert summary["checks"]["passed"] and summary["kinds"] == ["eigen"] * DEFAULT_MODES
        labels[units] = read_sid_hdf5(tmp_path / f"{units}.sid.h5")
    si, mm = labels["si"], labels["mm-t-s"]
    assert mm.mass == pytest.approx(31.4, rel=1e-12) and mm.mass == pytest.approx(si.mass, rel=1e-12)
    np.testing.assert_allclose(mm.frequencies_hz, si.frequencies_hz, rtol=1e-8)


def test_bad_interface_table(tmp_path, capsys):
    job = tmp_path / "job.toml"
    job.write_text(f'mesh = "{MESHES / "bar.msh"}"\ninterfaces = [{{name = "x", type = "plane", bogus = 1}}]\n')
    assert main(["reduce", str(job)]) == 2
    err = capsys.readouterr().err
    assert "unknown key(s) bogus" in err and "valid:" in err and not list(tmp_path.glob("*.h5"))


def test_mesh_repairs_and_the_default_material_are_reported(tmp_path, capsys):
    """What read_mesh repaired (here: an unused node dropped) reaches the user and the file."""
    import meshio

    from sidprep.fe.mesh import read_mesh

    bar = read_mesh(MESHES / "bar.msh")
    path = tmp_path / "bar_extra_node.vtu"
    points = np.vstack([bar.points, [[5.0, 5.0, 5.0]]])
    meshio.write(path, meshio.Mesh(points, [("tetra10", bar.cells)]))
    out = tmp_path / "b.sid.h5"
    assert main(["reduce", str(path), "--json", "--no-obj", "--no-sid-fem", "-o", str(out)]) == 0
    captured = capsys.readouterr()
    notes = json.loads(captured.out)["notes"]
    assert any("1 nodes not used by any tetrahedron were dropped" in n for n in notes)
    assert any("steel used" in n for n in notes)
    assert "note: 1 nodes not used" in captured.err
    assert read_sid_hdf5(out).metadata["notes"] == notes
