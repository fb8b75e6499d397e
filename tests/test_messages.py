"""Messages that explain themselves: hints that fit the input and the options given, one fix per
message, warnings in the one form of every command."""

import subprocess
import sys
from pathlib import Path

from sidprep.reduction.fe_checks import static_advice

ROOT = Path(__file__).resolve().parents[1]


def sidprep(*args, cwd=ROOT):
    return subprocess.run([sys.executable, "-m", "sidprep.cli.main", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True)


def test_a_sid_passed_to_simulate_is_told_to_write_a_scene():
    r = sidprep("simulate", "examples/flexible_pendulum/bar.sid.h5")
    assert r.returncode == 2 and r.stderr.count("\n") == 1
    assert "a SID file is one body" in r.stderr and "sidprep reduce" not in r.stderr


def test_a_mistyped_mesh_is_not_reported_done():
    r = sidprep("reduce", "data/meshes/no_such_bar.msh")
    assert r.returncode == 2 and "done in" not in r.stderr and "file not found" in r.stderr


def test_static_advice_fits_the_options():
    assert "--cutoff-factor" in static_advice({"frequency_response_modes": True})
    without = static_advice({"frequency_response_modes": False})
    assert "--no-frm" in without and "--cutoff-factor" not in without


def test_a_results_file_passed_to_simulate_is_pointed_to_plot_and_animate():
    r = sidprep("simulate", "run.results.h5")
    assert r.returncode == 2 and "sidprep plot run.results.h5" in r.stderr and "sidprep animate" in r.stderr


def test_a_damaged_sid_in_a_scene_is_named_with_one_fix(tmp_path):
    """The SID reader's message (file, problem, fix) reaches the user once, with the scene's place."""
    import shutil

    import h5py
    import numpy as np

    for f in (ROOT / "examples" / "flexible_pendulum").iterdir():
        shutil.copy(f, tmp_path / f.name)
    with h5py.File(tmp_path / "bar.sid.h5", "r+") as f:
        f["refmod"].attrs["mass"] = np.nan
    r = sidprep("simulate", "scene.toml", "-q", cwd=tmp_path)
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert r.stderr.count("regenerate") == 1 and r.stderr.count("bar.sid.h5") == 2, r.stderr   # the file, and check's
    assert "[bodies.bar] sid: bar.sid.h5: not a physically possible body: non-finite number mass" in r.stderr


def test_library_warnings_print_as_warnings_not_notes():
    from sidprep.errors import WARNING_PREFIX, note_line

    assert note_line(WARNING_PREFIX + "rotation off by 2 %") == "sidprep: warning: rotation off by 2 %"
    assert note_line("material: steel used") == "note: material: steel used"
    assert note_line(WARNING_PREFIX + "a\nb") == "sidprep: warning: a\\nb"


def test_no_command_prints_a_note_that_is_a_warning():
    """Every place a command prints library notes goes through sidprep.errors.note_line (no "note: WARNING:")."""
    import re

    for path in (ROOT / "sidprep" / "cli").glob("*.py"):
        text = path.read_text()
        assert not re.search(r'f"note: \{note\}"', text), path
        assert 'print(f"WARNING' not in text, path
