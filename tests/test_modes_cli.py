"""``sidprep modes``: JSON contract, units, clamping, rigid-mode count, errors."""

import json

import meshio
import numpy as np
import pytest

from sidprep.cli.main import main



@pytest.fixture(scope="module")
def bar_mesh(validation_dir):
    """The validation bar mesh (tests/data/validation)."""
    return validation_dir / "meshes" / "bar_h0.02_mesh.inp"

#: the same model given in mm-t-s and in SI gives the same frequencies up to round-off
UNITS_RTOL = 1e-9
#: AMG-LOBPCG vs shift-invert Lanczos (frequencies; eigenvalue error ~ square of the residual)
LOBPCG_RTOL = 1e-6
#: bar volume 1.0 x 0.05 x 0.08 m^3, steel 7850 kg/m^3
BAR_MASS_KG = 7850.0 * 1.0 * 0.05 * 0.08


def run_json(argv, capsys):
    assert main(["modes", *argv, "--json", "-q"]) == 0
    return json.loads(capsys.readouterr().out)


def test_json_summary_of_a_clamped_bar(capsys, bar_mesh):
    out = run_json([str(bar_mesh), "--material", "steel", "--clamp", "NX0", "--count", "4"], capsys)
    assert out["n_dof"] == 17058 and out["n_free_dof"] == 17058 - 3 * 79
    assert abs(out["mass_kg"] / BAR_MASS_KG - 1) < 1e-12
    assert out["rigid_modes"] == 0 and len(out["frequencies_hz"]) == 4 == len(out["residuals"])
    assert np.all(np.diff(out["frequencies_hz"]) > 0) and max(out["residuals"]) < 1e-6
    assert {"mesh", "factorize", "eigen", "assemble"} <= set(out["timings_s"]) and out["peak_memory_mb"] > 0
    assert out["units"]["input"] == "si" and out["material"]["name"] == "steel" and out["notes"] == []


def test_mm_t_s_input_gives_the_si_result(tmp_path, capsys, bar_mesh):
    m = meshio.read(bar_mesh)
    mm = tmp_path / "bar_mm.vtu"
    meshio.write(mm, meshio.Mesh(m.points * 1000.0, [("tetra10", m.cells_dict["tetra10"])]))
    si = run_json([str(bar_mesh), "--E", "210e9", "--nu", "0.3", "--rho", "7850", "--count", "3"], capsys)
    mts = run_json([str(mm), "--units", "mm-t-s", "--E", "210000", "--nu", "0.3", "--rho", "7.85e-9",
                    "--count", "3"], capsys)
    assert mts["rigid_modes"] == si["rigid_modes"] == 6
    assert np.allclose(mts["frequencies_hz"], si["frequencies_hz"], rtol=UNITS_RTOL, atol=0)
    assert abs(mts["mass_kg"] / BAR_MASS_KG - 1) < 1e-12


def test_two_disjoint_boxes_have_twelve_rigid_modes_and_default_material_note(tmp_path, capsys):
    geo = tmp_path / "two_boxes.geo"
    geo.write_text('SetFactory("OpenCASCADE");\nBox(1) = {0, 0, 0, 0.2, 0.05, 0.05};\n'
                   'Box(2) = {0, 0.1, 0, 0.3, 0.05, 0.04};\n')
    out = run_json([str(geo), "--size", "0.025", "--count", "3"], capsys)
    assert out["rigid_modes"] == 12 and len(out["frequencies_hz"]) == 3
    assert any("steel" in note for note in out["notes"])


def test_table_output_lists_rigid_and_elastic_modes(capsys, bar_mesh):
    assert main(["modes", str(bar_mesh), "--material", "aluminium", "--fmax", "500", "-q"]) == 0
    text = capsys.readouterr().out
    assert text.count(" rigid ") == 6 and text.count(" elastic ") >= 1 and "aluminium" in text


@pytest.mark.parametrize("argv, fragment", [
    (["--clamp", "nope"], "available: NBOTEDG, NX0, NXL, NY0, NYL"),
    (["--E", "210e9"], "missing"),
    (["--count", "0"], "--count"),
])
def test_bad_input_exits_2_with_one_line(argv, fragment, capsys, bar_mesh):
    assert main(["modes", str(bar_mesh), "-q", *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("sidprep: error:") and fragment in err and "\n" not in err


def test_lobpcg_backend_gives_the_direct_frequencies(tmp_path, capsys):
    geo = tmp_path / "block.geo"
    geo.write_text('SetFactory("OpenCASCADE");\nBox(1) = {0, 0, 0, 0.3, 0.05, 0.06};\n'
                   'Physical Surface("root") = {1};\n')
    common = [str(geo), "--size", "0.02", "--material", "titanium", "--count", "4"]
    for clamp in ([], ["--clamp", "root"]):
        direct = run_json(common + clamp, capsys)
        amg = run_json(common + clamp + ["--backend", "lobpcg"], capsys)
        assert amg["backend"] == "lobpcg" and amg["rigid_modes"] == direct["rigid_modes"] == (0 if clamp else 6)
        assert np.allclose(amg["frequencies_hz"], direct["frequencies_hz"], rtol=LOBPCG_RTOL, atol=0)
