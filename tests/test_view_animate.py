"""``sidprep animate``: mechanism page and movie from a results file.

Independent reference: a rigid body turning about z at a known rate, x = r + Rz(w t) p in closed
form; the page must render in headless Chromium without console errors.
"""

from pathlib import Path

import numpy as np
import pytest

from sidprep.cli.main import main
from sidprep.sid.io.obj import write_obj
from sidprep.solver.effects import EffectsReport
from sidprep.solver.results import BodySource, write_results
from sidprep.solver import BodyHistory, Result
from test_view import assert_renders, browser

ROOT = Path(__file__).resolve().parents[1]
BAR_SID = ROOT / "examples" / "flexible_pendulum" / "bar.sid.h5"
RATE = 2.0          # rad/s about z
POSITION_TOL = 1e-12


def rz(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def history(name, t, nq, offset):
    nt = len(t)
    q = 1e-4 * np.outer(np.sin(40 * t), np.ones(nq))
    return BodyHistory(name, position=np.tile(offset, (nt, 1)), rotation=np.array([rz(RATE * x) for x in t]),
                       velocity=np.zeros((nt, 3)), omega=np.tile([0, 0, RATE], (nt, 1)), q=q, qd=np.zeros((nt, nq)),
                       acceleration=np.zeros((nt, 6 + nq)))


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    from sidprep.sid.io import read_sid

    folder = tmp_path_factory.mktemp("mech")
    box = np.array([[0, 0, 0], [0.2, 0, 0], [0, 0.1, 0], [0, 0, 0.05]])
    write_obj(folder / "block.obj", box, np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]))
    t = np.linspace(0, 0.5, 51)
    nq = read_sid(BAR_SID).nq
    result = Result(t=t, bodies={"bar": history("bar", t, nq, [0, 0, 0]), "block": history("block", t, 0, [0, 0.3, 0])},
                    joints={}, markers={}, energy={"total": np.zeros_like(t)}, constraint_error=np.zeros_like(t),
                    effects=EffectsReport(bodies={}, notes=()))
    path = folder / "run.results.h5"
    write_results(result, path, bodies={"bar": BodySource("flexible", str(BAR_SID)),
                                        "block": BodySource("rigid", str(folder / "block.obj"))})
    return path


def test_rigid_body_follows_closed_form(results):
    from sidprep.sid.surface import surface_motion
    from sidprep.view.mechanism import mechanism_surfaces

    rf, surfaces = mechanism_surfaces(results)
    b, s = rf.result.bodies["block"], surfaces["block"]
    x, u = surface_motion(s, b.position, b.rotation, b.q)
    expected = np.array([[np.array([0, 0.3, 0]) + rz(RATE * t) @ p for p in s.points] for t in rf.result.t])
    assert np.abs(x - expected).max() < POSITION_TOL and not u.any()


def test_animate_page_and_gif(results, tmp_path):
    page = tmp_path / "run.html"
    assert main(["animate", str(results), "-o", str(page)]) == 0
    assert "Plotly.newPlot" in page.read_text()
    gif = tmp_path / "run.gif"
    assert main(["animate", str(results), "-o", str(gif)]) == 0
    assert gif.read_bytes()[:6] in (b"GIF89a", b"GIF87a")


def test_animate_bad_output_type(results, tmp_path, capsys):
    assert main(["animate", str(results), "-o", str(tmp_path / "x.avi")]) == 2
    assert "use .html, .mp4 or .gif" in capsys.readouterr().err


@pytest.mark.skipif(browser() is None, reason="Chromium not installed (apt-get install chromium)")
def test_animate_page_renders_in_chromium(results, tmp_path):
    page = tmp_path / "run.html"
    assert main(["animate", str(results), "-o", str(page)]) == 0
    assert_renders(page, tmp_path / "run.png", "#t=30&exaggerated")
