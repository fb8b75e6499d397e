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
