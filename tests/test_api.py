"""The Python API (``import sidprep``): lazy import, reduce / modal_analysis / read_sid / write_sid.

References: the CLI's files for the same job (bit for bit: the API must be what the CLI runs), and
the bar's free-free frequencies from a full-model eigen solve for the reduced body's eigen modes.
"""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import sidprep
from sidprep.cli.main import main

ROOT = Path(__file__).resolve().parents[1]
BAR = ROOT / "data" / "meshes" / "bar.msh"
#: reduced vs full first elastic frequency of the bar (the FE check tolerance, sidprep.reduction.fe_checks)
FREQ_RTOL = 1e-3


def test_import_sidprep_loads_no_fe_module_and_no_solver():
    code = ("import sys, sidprep; bad = [m for m in sys.modules if m.split('.')[0] in ('solver', 'skfem', 'scipy')"
            " or m in ('sidprep.fe.mesh', 'sidprep.fe.linalg', 'sidprep.jobs.reduce')]; print(bad)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT,
                         env={"PYTHONPATH": str(ROOT), "PATH": ""}).stdout.strip()
    assert out == "[]"


def test_api_reproduces_the_cli_sid_bit_for_bit(tmp_path, capsys):
    opts = sidprep.ReduceOptions(modes=3)
    result = sidprep.reduce_model(BAR, opts)
    assert main(["reduce", str(BAR), "--modes", "3", "-o", str(tmp_path / "cli.sid.h5"), "-q"]) == 0
    capsys.readouterr()
    sidprep.write_sid(result.sid, tmp_path / "api.sid.h5")
    sidprep.write_sid(result.sid, tmp_path / "api.SID_FEM", comment=f"sidprep reduce {BAR.name}")
    a, c = sidprep.read_sid(tmp_path / "api.sid.h5"), sidprep.read_sid(tmp_path / "cli.sid.h5")
    for name in ("mdCM", "J", "Ct", "Cr", "Me", "Gr", "Ge", "Oe", "Ke", "De"):
        np.testing.assert_array_equal(getattr(a, name).M0, getattr(c, name).M0)
    np.testing.assert_array_equal(a.frequencies_hz, c.frequencies_hz)
    assert a.metadata["options"] == c.metadata["options"]
    assert (tmp_path / "api.SID_FEM").read_bytes() == (tmp_path / "cli.SID_FEM").read_bytes()
    assert result.passed and result.n_dof == 3372


def test_modal_analysis_and_the_reduced_body_agree_on_the_bar():
    modal = sidprep.modal_analysis(BAR, sidprep.ModalOptions(count=3))
    assert modal.n_rigid == 6 and modal.modes.shape == (3372, 9)
    assert np.all(modal.residuals[6:] < 1e-8) and set(modal.timings_s) >= {"assemble"}
    red = sidprep.reduce_model(sidprep.read_mesh(BAR), sidprep.ReduceOptions(modes=3, check_frequencies=False))
    eigen = red.sid.frequencies_hz[np.array(red.sid.mode_kinds) == "eigen"]
    np.testing.assert_allclose(eigen[:3], modal.frequencies_hz[6:9], rtol=FREQ_RTOL)


def test_library_errors_name_settings_not_flags():
    with pytest.raises(sidprep.errors.InputError, match=r"^damping = -1: a modal damping ratio must be >= 0 and < 1"):
        sidprep.reduce_model(BAR, sidprep.ReduceOptions(damping=-1.0))
    with pytest.raises(sidprep.errors.InputError, match=r"^modes = 5000: the model has 3372 DOF"):
        sidprep.reduce_model(BAR, sidprep.ReduceOptions(modes=5000))


def test_the_readme_python_section_runs_as_written(tmp_path, monkeypatch):
    text = (ROOT / "README.md").read_text()
    start = text.index("## Python")
    block = text[text.index("```python", start) + len("```python"):text.index("```", text.index("```python", start) + 9)]
    monkeypatch.chdir(ROOT)
    exec(compile(block.replace('"scratch', f'"{tmp_path}'), "README.md", "exec"), {})     # its scratch folder
    assert (tmp_path / "bar.sid.h5").is_file() and (tmp_path / "pendulum.results.h5").is_file()


def test_sid_info_gives_the_bar_mass_and_centre(tmp_path):
    """Closed form: 1.0 x 0.05 x 0.08 m steel (7850 kg/m^3) box: 31.4 kg, centre (0.5, 0.025, 0.04) m."""
    result = sidprep.reduce_model(BAR, sidprep.ReduceOptions(modes=2, check_frequencies=False))
    sidprep.write_sid(result.sid, tmp_path / "bar.sid.h5")
    info = sidprep.sid_info(tmp_path / "bar.sid.h5")
    assert info["mass_kg"] == pytest.approx(7850 * 1.0 * 0.05 * 0.08, rel=1e-12)
    np.testing.assert_allclose(info["center_of_mass"], [0.5, 0.025, 0.04], rtol=1e-9)
