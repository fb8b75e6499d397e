"""``sidprep view``: the self-contained mode page, checked as a person would (headless Chromium).

Independent references: the page must not need the network (no http(s) script source), the
surface interpolated onto the cartop hull must pass through its nodes' mode shapes (the SID's own
phi), and the browser must render a non-blank picture without console errors.
"""

import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from sidprep.cli.main import main

ROOT = Path(__file__).resolve().parents[1]
# ../shared beside the clone (CI), or two levels up (a worktree under wt/)
CARTOP = next((p / "shared" / "reference" / "sid_fem" / "cartopPragV32.SID_FEM" for p in (ROOT.parent, ROOT.parent.parent)
               if (p / "shared").is_dir()), ROOT.parent / "shared" / "reference" / "sid_fem" / "cartopPragV32.SID_FEM")
BROWSER_TIMEOUT_S = 90
BLANK_STD = 0.02       # a blank or single-colour screenshot has pixel standard deviation ~0
COLOURED = 0.3         # a pixel whose RGB channels differ this much is coloured (the surface, not axes)
DRAWN_FRACTION = 0.002  # at least this share of the 3-D view is coloured surface


@pytest.fixture(scope="module")
def rod_sid(tmp_path_factory):
    out = tmp_path_factory.mktemp("rod") / "rod.sid.h5"
    assert main(["reduce", str(ROOT / "data/meshes/piston_rod.msh"), "-o", str(out), "-q",
                 "--no-sid-fem", "--no-obj"]) == 0
    return out


#: headless Chromium without its background connections (sync, component updates, QUIC, first-run
#: pages), which a machine without network refuses or lets time out, in a profile of its own
QUIET_BROWSER = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--disable-quic", "--no-first-run"]


def browser():
    return shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")


def render(page: Path, png: Path, fragment: str = "") -> str:
    """Screenshot ``page`` in headless Chromium; returns its console log (stderr)."""
    profile = png.with_suffix(".profile")
    run = subprocess.run([browser(), *QUIET_BROWSER, f"--user-data-dir={profile}", "--enable-logging=stderr",
                          "--v=0", "--window-size=1400,800", "--virtual-time-budget=3000",
                          f"--screenshot={png}", page.resolve().as_uri() + fragment],
                         capture_output=True, text=True, timeout=BROWSER_TIMEOUT_S)
    return run.stderr


def assert_renders(page: Path, png: Path, fragment: str = "") -> None:
    import matplotlib.image as mpimg

    log = render(page, png, fragment)
    errors = [line for line in log.splitlines() if "Uncaught" in line or "ERROR:CONSOLE" in line]
    assert not errors, errors
    image = mpimg.imread(png)[..., :3]
    assert image.std() > BLANK_STD, "blank screenshot"
    plot = image[40:780, :1000]            # the 3-D view: coloured surface pixels, not only grey axes
    colourful = np.ptp(plot, axis=2) > COLOURED
    assert colourful.mean() > DRAWN_FRACTION


def offline(page: Path) -> bool:
    text = page.read_text()
    return not re.search(r"<script[^>]+src=\"https?:", text) and "Plotly.newPlot" in text


def test_view_rod_page_is_self_contained(rod_sid, tmp_path, capsys):
    page = tmp_path / "rod.html"
    assert main(["view", str(rod_sid), "-o", str(page)]) == 0
    assert offline(page)
    text = page.read_text()
    assert "262" in text or "Hz" in text and "mass" in text and "checks" in text


def test_view_bad_obj_is_one_line_error(rod_sid, tmp_path, capsys):
    assert main(["view", str(rod_sid), "--surface", str(tmp_path / "missing.obj")]) == 2
    assert "no such OBJ file" in capsys.readouterr().err


@pytest.mark.skipif(not CARTOP.is_file(), reason="third-party cartop SID_FEM file not present")
def test_cartop_hull_follows_its_nodes():
    from sidprep.sid.io import read_sid
    from sidprep.sid.surface import node_points
    from sidprep.view.modes import body_surface

    sid = read_sid(CARTOP)
    surface = body_surface(sid, "cartop")
    nodes, phi = node_points(sid)
    assert len(surface.points) > 20 * len(nodes)
    # hull vertices at node positions (slab faces) move exactly with the nodes' phi
    for c, shape in zip(nodes, phi):
        d = np.linalg.norm(surface.points - c, axis=1)
        if d.min() < 1e-12:
            assert np.abs(surface.shapes[d.argmin()] - shape).max() < 1e-10


@pytest.mark.skipif(browser() is None, reason="Chromium not installed (apt-get install chromium)")
def test_rod_page_renders_in_chromium(rod_sid, tmp_path):
    page = tmp_path / "rod.html"
    assert main(["view", str(rod_sid), "-o", str(page)]) == 0
    assert_renders(page, tmp_path / "rod.png", "#mode=1")


@pytest.mark.skipif(browser() is None or not CARTOP.is_file(),
                    reason="Chromium not installed (apt-get install chromium) or cartop file absent")
def test_cartop_page_renders_in_chromium(tmp_path):
    page = tmp_path / "cartop.html"
    assert main(["view", str(CARTOP), "-o", str(page)]) == 0
    assert_renders(page, tmp_path / "cartop.png", "#mode=2")
