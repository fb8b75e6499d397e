"""The pages as a person sees them: the colour bar clear of plotly's toolbar (layout measured in
headless Chromium), units on every quantity, the ground, joints and markers of a mechanism, and a
page whose size grows with the surface, not with surface x samples.

Independent references: the browser's own layout (bounding boxes), the results file's marker
positions and joint markers, and the SID's mass properties.
"""

import base64
import json
import subprocess
from pathlib import Path

import numpy as np
import plotly.io
import pytest

from sidprep.cli.main import main
from sidprep.solver import BodyHistory, Result
from sidprep.solver.effects import EffectsReport
from sidprep.solver.results import BodySource, JointHistory, write_results
from sidprep.view.page import page_data, page_part
from test_view import BROWSER_TIMEOUT_S, QUIET_BROWSER, browser

ROOT = Path(__file__).resolve().parents[1]
BAR_SID = ROOT / "examples" / "flexible_pendulum" / "bar.sid.h5"
#: a whole page (plotly.js, figure, data, all packed) is at most this many bytes: what a browser
#: opens smoothly (plotly.js alone is 4.8 MB, 1.96 MB packed)
PAGE_BYTES = 5_000_000
#: the figure and data of a page of a 4k-point, 20-mode surface, unpacked (the JSON the browser
#: parses): at most this many bytes, whatever the number of samples
PAGE_DATA_BYTES = 1_600_000
#: points of the large animation's surface, and its samples (more than a page shows)
LARGE_POINTS, LARGE_SAMPLES, LARGE_MODES = 4000, 3000, 20
#: the layout check runs this long after the page loaded (ms of the browser's virtual time)
LAYOUT_WAIT_MS = 2500


def layout_boxes(page: Path, tmp_path: Path, selectors: list[str]) -> list[dict]:
    """Bounding boxes (left, top, right, bottom in px) of the first element matching each CSS
    selector, measured by headless Chromium in a copy of ``page`` that writes them into its title."""
    probe = tmp_path / ("probe-" + page.name)
    script = ("<script>setTimeout(() => { document.title = JSON.stringify(%s.map(s => { "
              "const r = document.querySelector(s).getBoundingClientRect(); "
              "return {left: r.left, top: r.top, right: r.right, bottom: r.bottom}; })); }, %d);</script>"
              % (json.dumps(selectors), LAYOUT_WAIT_MS))
    probe.write_text(page.read_text().replace("</body>", script + "</body>"))
    run = subprocess.run([browser(), *QUIET_BROWSER, f"--user-data-dir={tmp_path / 'profile'}", "--window-size=1400,800",
                          f"--virtual-time-budget={2 * LAYOUT_WAIT_MS}", "--dump-dom", probe.resolve().as_uri()],
                         capture_output=True, text=True, timeout=BROWSER_TIMEOUT_S)
    title = run.stdout.split("<title>", 1)[1].split("</title>", 1)[0]
    return json.loads(title.replace("&quot;", '"'))


def values(data) -> np.ndarray:
    """An array of a plotly figure's JSON: a list, or plotly's typed array {"dtype", "bdata"
    (base64), "shape"}."""
    if isinstance(data, dict):
        array = np.frombuffer(base64.b64decode(data["bdata"]), dtype=data["dtype"])
        return array.reshape([int(n) for n in str(data["shape"]).split(",")]) if "shape" in data else array
    return np.asarray(data)


def overlap(a: dict, b: dict) -> bool:
    return a["left"] < b["right"] and b["left"] < a["right"] and a["top"] < b["bottom"] and b["top"] < a["bottom"]


def rz(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def pendulum_results(folder: Path, nt: int, sid: Path = BAR_SID) -> Path:
    """A results file of a bar (the SID ``sid``) turning about the ground's z axis at its hinge
    marker, with a joint 'hinge' between the markers 'pivot' (ground) and 'root' (bar)."""
    from sidprep.sid.io import read_sid

    t = np.linspace(0.0, 1.0, nt)
    nq = read_sid(sid).nq
    z3 = np.zeros((nt, 3))
    bar = BodyHistory("bar", position=z3.copy(), rotation=np.array([rz(x) for x in t]), velocity=z3.copy(),
                      omega=np.tile([0, 0, 1.0], (nt, 1)), q=1e-4 * np.outer(np.sin(30 * t), np.ones(nq)),
                      qd=np.zeros((nt, nq)), acceleration=np.zeros((nt, 6 + nq)))
    tip = np.array([rz(x) @ [1.0, 0.0, 0.0] for x in t])
    hinge = JointHistory("hinge", "revolute", *(np.zeros((nt, 3)) for _ in range(4)), *(np.zeros(nt) for _ in range(3)),
                         markers=("pivot", "root"))
    result = Result(t=t, bodies={"bar": bar}, joints={"hinge": hinge},
                    markers={"pivot": z3.copy(), "root": z3.copy(), "tip": tip}, energy={"total": np.zeros(nt)},
                    constraint_error=np.zeros(nt), effects=EffectsReport(bodies={}, notes=()))
    path = folder / "pendulum.results.h5"
    write_results(result, path, bodies={"bar": BodySource("flexible", str(sid))},
                  scene={"path": "", "text": "[scene]\ngravity = [0.0, -9.81, 0.0]\n"})
    return path


def test_mechanism_page_draws_ground_joints_and_markers(tmp_path):
    results = pendulum_results(tmp_path, 101)
    page = tmp_path / "pendulum.html"
    assert main(["animate", str(results), "-o", str(page)]) == 0
    figure = plotly.io.from_json(page_part(page, "figure"))
    traces = {t.name: t for t in figure.data}
    assert {"ground", "markers", "ground x", "ground y", "ground z"} <= set(traces)
    ground = traces["ground"]
    # the ground lies across gravity (-y here): all its corners at one y, below every marker
    assert np.ptp(values(ground.y)) == 0.0 and values(ground.y)[0] < -1e-3
    data = page_data(page)
    names = data["markers"]["names"]
    assert names == ["pivot", "root", "tip"]
    symbols = dict(zip(names, traces["markers"].marker.symbol))
    assert symbols == {"pivot": "diamond", "root": "diamond", "tip": "circle"}     # the hinge's markers drawn as joints
    positions = np.array(data["markers"]["P"]).reshape(len(data["t"]), len(names), 3)
    expected = np.array([[np.cos(x), np.sin(x), 0.0] for x in data["t"]])
    assert np.abs(positions[:, 2] - expected).max() < 1e-4                         # 5 digits of the largest coordinate
    assert figure.layout.scene.xaxis.title.text == "x (m)"


def test_large_animation_stays_small(tmp_path):
    """A 4k-point surface with 20 modes over 3000 samples: the page carries the surface once and
    r, A, q per shown sample, so its data stay under PAGE_DATA_BYTES and the whole page under
    PAGE_BYTES.  (Not rendered here: software WebGL takes 30-50 s over its 8000 random triangles;
    tests/test_stress.py renders the engine's stress page, 3726 surface points.)"""
    from dataclasses import replace

    from sidprep.sid.io import read_sid, write_sid
    from sidprep.sid.model import SurfaceModes

    rng = np.random.default_rng(0)
    sid = read_sid(BAR_SID)
    surface = SurfaceModes(points=rng.uniform(0.0, 1.0, (LARGE_POINTS, 3)),
                           triangles=rng.integers(0, LARGE_POINTS, (2 * LARGE_POINTS, 3)),
                           shapes=1e-3 * rng.normal(size=(LARGE_POINTS, 3, sid.nq)), node_ids=np.arange(LARGE_POINTS))
    big = tmp_path / "big.sid.h5"
    write_sid(replace(sid, surface=surface), big)
    results = pendulum_results(tmp_path, LARGE_SAMPLES, big)
    page = tmp_path / "big.html"
    assert main(["animate", str(results), "-o", str(page)]) == 0
    assert len(page_part(page, "data").encode()) + len(page_part(page, "figure").encode()) < PAGE_DATA_BYTES
    assert page.stat().st_size <= PAGE_BYTES


@pytest.mark.skipif(browser() is None, reason="Chromium not installed (apt-get install chromium)")
def test_colour_bar_clear_of_the_toolbar(tmp_path):
    page = tmp_path / "pendulum.html"
    assert main(["animate", str(pendulum_results(tmp_path, 51)), "-o", str(page)]) == 0
    toolbar, title, bar = layout_boxes(page, tmp_path, [".modebar", ".cbtitle", ".cbbg"])
    assert toolbar["right"] > toolbar["left"] and title["right"] > title["left"]     # both laid out
    assert not overlap(toolbar, title) and not overlap(toolbar, bar)


def test_mode_page_states_units(tmp_path):
    page = tmp_path / "bar.html"
    assert main(["view", str(BAR_SID), "-o", str(page)]) == 0
    text = page.read_text()
    for label in ("mass (kg)", "CM (m, body frame)", "inertia at O (kg m^2)"):
        assert label in text
    figure = plotly.io.from_json(page_part(page, "figure"))
    assert figure.layout.scene.zaxis.title.text == "z (m)"


def test_study_plot_has_integer_ticks_for_integer_parameters(tmp_path):
    from sidprep.jobs.batch import BatchReport, study_figure

    records = [{"status": "ok", "params": {"modes": n}, "frequencies_hz": [10.0 + n, 20.0 + n]} for n in (4, 6, 8)]
    fig = study_figure(BatchReport(records=records, outdir=str(tmp_path)))
    ticks = fig.axes[0].get_xticks()
    assert len(ticks) >= 2 and np.allclose(ticks, np.round(ticks))
