"""``sidprep plot RESULTS.h5 [SIGNALS...] [-o OUT.png]`` on a results file of the flexible pendulum."""

import contextlib
import io
from pathlib import Path

import matplotlib.image
import numpy as np
import pytest

from sidprep.cli.main import main
from sidprep.solver.results import default_signals, read_results

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    out = tmp_path_factory.mktemp("plot") / "pendulum.results.h5"
    with contextlib.redirect_stdout(io.StringIO()):
        assert main(["simulate", str(ROOT / "examples/flexible_pendulum/scene.toml"), "--t-end", "0.05", "-q",
                     "-o", str(out)]) == 0
    return out


def run(capsys, *argv):
    code = main(list(map(str, argv)))
    out, err = capsys.readouterr()
    return code, out, err


def test_without_signals_it_draws_the_default_figure_and_lists_them(results, capsys, tmp_path, monkeypatch):
    """The energy, the bar's main position component and modal coordinate, the hinge angle."""
    monkeypatch.chdir(tmp_path)
    code, out, err = run(capsys, "plot", results)
    assert code == 0 and out.strip() == "wrote pendulum.png"
    assert {"hinge.coordinate", "bar.q.1", "energy.total", "root.position.z"} <= set(err.split())
    signals = default_signals(read_results(results).result)
    assert signals[:2] == ["energy.kinetic", "energy.total"] and "hinge.coordinate" in signals
    assert "bar.position.x" in signals or "bar.position.z" in signals      # the bar swings in x-z
    assert any(s.startswith("bar.q.") for s in signals)
    image = matplotlib.image.imread(tmp_path / "pendulum.png")
    assert image.shape[0] > 600 and np.std(image) > 0.01                  # four panels (J, m, 1, rad)


def test_it_writes_the_png_into_the_working_folder_by_the_results_stem(results, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, _ = run(capsys, "plot", results, "hinge.coordinate", "bar.q.2")
    assert code == 0 and out.strip() == "wrote pendulum.png"
    image = matplotlib.image.imread(tmp_path / "pendulum.png")
    assert image.shape[0] > 300 and np.std(image) > 0.01          # two panels drawn, not blank
    code, out, _ = run(capsys, "plot", results, "energy.total", "-o", tmp_path / "e.png")
    assert code == 0 and (tmp_path / "e.png").stat().st_size > 1000


def test_an_unknown_signal_is_one_line_before_any_file(results, capsys, tmp_path):
    code, _, err = run(capsys, "plot", results, "hinge.angle", "-o", tmp_path / "x.png")
    assert code == 2 and "unknown signal 'hinge.angle'" in err and not (tmp_path / "x.png").exists()
    code, _, err = run(capsys, "plot", tmp_path / "missing.h5", "energy.total")
    assert code == 2 and "no such results file" in err
    assert read_results(results).result.t[-1] == pytest.approx(0.05)
