"""``sidprep simulate --step --method --rtol --rate`` override the scene's [solver] / [output] rate:
the run equals the one of the scene file with the same settings written into it."""

import contextlib
import io
import json
from pathlib import Path

import numpy as np

from sidprep.cli.main import main
from sidprep.solver.results import read_results

ROOT = Path(__file__).resolve().parents[1]
PENDULUM = ROOT / "examples/flexible_pendulum/scene.toml"


def simulate(*argv):
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(["simulate", *map(str, argv), "--json", "-q"])
    assert code == 0
    return json.loads(out.getvalue())


def test_overrides_equal_the_same_settings_in_the_scene(tmp_path):
    text = PENDULUM.read_text().replace("step = 1e-3", "step = 2e-3").replace("rate = 200", "rate = 50")
    edited = tmp_path / "scene.toml"
    edited.write_text(text.replace('sid = "bar.sid.h5"', f'sid = "{PENDULUM.parent / "bar.sid.h5"}"'))
    a = simulate(PENDULUM, "--t-end", "0.2", "--step", "2e-3", "--rate", "50", "-o", tmp_path / "a.h5")
    b = simulate(edited, "--t-end", "0.2", "-o", tmp_path / "b.h5")
    assert a["steps"] == b["steps"] == 100
    ra, rb = read_results(tmp_path / "a.h5").result, read_results(tmp_path / "b.h5").result
    assert len(ra.t) == 11 and np.array_equal(ra.t, rb.t)
    assert np.array_equal(ra.joints["hinge"].coordinate, rb.joints["hinge"].coordinate)


def test_method_and_rtol_reach_the_solver(tmp_path):
    s = simulate(PENDULUM, "--t-end", "0.05", "--method", "rk45", "--rtol", "1e-6", "-o", tmp_path / "c.h5")
    fixed = simulate(PENDULUM, "--t-end", "0.05", "--method", "rk45", "--rtol", "1e-9", "-o", tmp_path / "d.h5")
    assert 0 < s["steps"] < fixed["steps"]                  # the tolerance chooses the steps


def test_bad_values_are_refused_by_the_parser(capsys):
    for argv in (["--step", "0"], ["--method", "euler"], ["--rate", "-5"]):
        try:
            main(["simulate", str(PENDULUM), *argv])
        except SystemExit as exc:
            assert exc.code == 2
        assert "error" in capsys.readouterr().err
