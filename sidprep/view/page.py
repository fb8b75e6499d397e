"""One self-contained HTML page (plotly.js inlined, opens offline by double-click): the layout
shared by the mode page (modes.py) and the mechanism page (mechanism.py), its side tables, the
colour bar placed clear of plotly's toolbar, and the compact number arrays the pages' scripts read.
"""

from __future__ import annotations

import functools
import html
import json
from pathlib import Path

import numpy as np

from sidprep.sid.io.atomic import atomic_path

#: the pages show stresses in MPa
PA_PER_MPA = 1e6
PLOT_ID = "sidprep-plot"
#: significant digits of the numbers a page's script reads (positions, shapes, stresses, q):
#: 1e-5 of each array's largest magnitude, below what a screen shows
PAGE_DIGITS = 5
#: the colour bar spans this fraction of the plot's height, centred below plotly's toolbar (which
#: takes the plot's top right corner), with its title beside it, not above it
COLORBAR_LENGTH = 0.75
COLORBAR_CENTRE = 0.45

_PAGE = """<!DOCTYPE html>
<html><head><meta charset="utf-8"><title>{title}</title>
<style>
body {{ font-family: sans-serif; margin: 0; display: flex; height: 100vh; }}
#main {{ flex: 1; min-width: 0; display: flex; flex-direction: column; }}
#controls {{ padding: 6px; background: #eee; }}
#side {{ flex: 0 0 360px; overflow: auto; padding: 8px; font-size: 12px; border-left: 1px solid #ccc; }}
table {{ border-collapse: collapse; width: 100%; }} th, td {{ text-align: left; padding: 2px 4px;
vertical-align: top; border-bottom: 1px solid #ddd; }}
.ok {{ color: green; }} .FAIL {{ color: red; font-weight: bold; }} .info {{ color: grey; }}
#{plot_id} {{ flex: 1; min-height: 0; }}
</style></head><body>
<div id="main"><div id="controls">{controls}</div><div id="{plot_id}"></div></div>
<div id="side"><h3>{title}</h3>{side}</div>
<script type="application/json" id="figure">{figure}</script>
<script type="application/json" id="data">{data}</script>
"""

#: plotly.js inline, then the figure drawn from its JSON and the page's own script run as
#: start(D, gd) with its data D and the plot element gd
_LOADER = """<script>{plotly}</script>
<script>
function start(D, gd) {
{script}
}
(() => {
  const F = JSON.parse(document.getElementById('figure').textContent);
  const gd = document.getElementById('{plot_id}');
  Plotly.newPlot(gd, F.data, F.layout, {responsive: true}).then(
    () => start(JSON.parse(document.getElementById('data').textContent), gd));
})();
</script>
</body></html>
"""


def inline_json(text: str) -> str:
    """JSON text safe inside a <script> element ("</" written as the equal JSON escape "<\\/")."""
    return text.replace("</", "<\\/")


@functools.lru_cache(maxsize=1)
def plotly_js() -> str:
    """plotly.js, inlined into every page (4.8 MB)."""
    from plotly.offline import get_plotlyjs  # deferred: 0.25 s import, pages only

    return get_plotlyjs()


def colorbar(title: str) -> dict:
    """plotly colour-bar settings: ``title`` beside the bar, the bar clear of the toolbar."""
    return dict(title=dict(text=title, side="right"), len=COLORBAR_LENGTH, y=COLORBAR_CENTRE, yanchor="middle")


def frame_axes(length: float, label: str) -> list:
    """plotly traces of a frame's x, y, z axes (red, green, blue) of ``length`` from the origin,
    tipped with their names (e.g. "K x" for the body frame, "ground x" for the inertial frame)."""
    import plotly.graph_objects as go  # deferred: 0.25 s import, pages only

    traces = []
    for a, colour in enumerate(("red", "green", "blue")):
        end = np.zeros(3)
        end[a] = length
        traces.append(go.Scatter3d(x=[0, end[0]], y=[0, end[1]], z=[0, end[2]], mode="lines+text",
                                   text=["", "xyz"[a]], line=dict(color=colour, width=6), name=f"{label} {'xyz'[a]}",
                                   hoverinfo="name"))
    return traces


def axis_titles(length_unit: str) -> dict:
    """The 3-D scene's axis titles with the length unit, e.g. "x (m)"."""
    return {f"{a}axis": dict(title=dict(text=f"{a} ({length_unit})")) for a in "xyz"}


def table(rows: list[tuple[str, str]]) -> str:
    """An HTML table of (heading, cell) rows; headings are escaped, cells are HTML."""
    return "<table>" + "".join(f"<tr><th>{html.escape(k)}</th><td>{v}</td></tr>" for k, v in rows) + "</table>"


def js_array(values, digits: int = PAGE_DIGITS) -> str:
    """A flat JavaScript array literal of ``values`` (any shape, C order) to ``digits`` significant
    digits of the array's largest magnitude (fixed step, so small entries cost few characters)."""
    a = np.asarray(values, float).ravel()
    if not np.isfinite(a).all():
        raise ValueError("a page array holds non-finite values")
    peak = float(np.abs(a).max()) if a.size else 0.0
    if peak == 0.0:
        return "[" + ",".join(["0"] * a.size) + "]"
    step = 10.0 ** (np.floor(np.log10(peak)) - digits + 1)
    counts = np.rint(a / step).astype(np.int64)
    exponent = int(round(np.log10(step)))
    # integers times 10**exponent, written as e.g. 1234e-7: exact decimal, no float repr noise
    suffix = f"e{exponent}" if exponent else ""
    return "[" + ",".join(f"{c}{suffix}" if c else "0" for c in counts.tolist()) + "]"


def js_object(members: dict[str, str]) -> str:
    """A JavaScript object literal of members already written as JavaScript values."""
    return "{" + ",".join(f"{json.dumps(k)}:{v}" for k, v in members.items()) + "}"


def page_part(path, part: str) -> str:
    """The JSON text of one part of a page written by ``write_page``: "figure" (the plotly
    figure) or "data" (its D)."""
    text = Path(path).read_text(encoding="utf-8")
    opening = f'<script type="application/json" id="{part}">'
    start = text.index(opening) + len(opening)
    return text[start:text.index("</script>", start)]


def page_data(path) -> dict:
    """The data object D of a page written by ``write_page`` (for scripts and tests)."""
    return json.loads(page_part(path, "data"))


def write_page(path, title: str, figure, controls: str, side: str, script: str, data: str) -> Path:
    """Write one self-contained HTML page atomically (plotly.js inlined: it opens offline by
    double-click); returns the path.

    figure : a plotly Figure; controls, side : HTML of the control bar and the side panel;
    script : JavaScript run as start(D, gd) once the figure is drawn; data : the JSON text of D.
    """
    text = _PAGE.format(title=html.escape(title), plot_id=PLOT_ID, controls=controls, side=side,
                        figure=inline_json(figure.to_json()), data=inline_json(data))
    text += _LOADER.replace("{script}", script).replace("{plot_id}", PLOT_ID).replace("{plotly}", plotly_js())
    path = Path(path)
    with atomic_path(path) as tmp:
        Path(tmp).write_text(text, encoding="utf-8")
    return path
