"""The mode page of a SID body (``sidprep view``): its surface (the stored FE surface modes, or an
OBJ / the convex hull of its nodes deformed by ``sidprep.interpolation`` for SID files with few
nodes), its interface nodes and body frame, each mode animated on demand with an adjustable scale,
and a side table (mass, CM, inertia with units, frequencies, checks).

Append ``#mode=N`` (1-based) to the address to show mode N at its peak, ``#mode=N&stress`` to
colour it by von Mises stress.
"""

from __future__ import annotations

import html
import json
from pathlib import Path

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from sidprep.errors import InputError
from sidprep.sid.checks import sid_checks
from sidprep.sid.io import read_sid
from sidprep.sid.io.obj import read_obj
from sidprep.sid.model import inertia_matrix
from sidprep.sid.stress import stress_on_points, von_mises
from sidprep.sid.surface import Surface, interpolated_surface, node_points, stored_surface
from sidprep.view.page import PA_PER_MPA, axis_titles, colorbar, frame_axes, js_array, js_object, table, write_page

#: the largest mode displacement is drawn as this fraction of the body's bounding-box diagonal
DISPLAY_FRACTION = 0.1
#: thickness of the hull slab made for nodes in a plane, relative to the body size
HULL_THICKNESS = 0.02
#: the hull surface is refined to edges of at most body size / HULL_EDGES
HULL_EDGES = 40


def hull_surface(points: np.ndarray, name: str) -> tuple[np.ndarray, np.ndarray]:
    """Fallback surface: the convex hull of the node points, as a slab of ``HULL_THICKNESS`` times
    the body size when the nodes lie in a plane or on a line, refined to ``HULL_EDGES`` edges per
    body size so that the interpolated deformation shows; (vertices, triangles)."""
    import trimesh  # deferred: 1.8 s import, OBJ only

    centre = points.mean(axis=0)
    _, s, vt = np.linalg.svd(points - centre, full_matrices=False)
    size = float(np.linalg.norm(np.ptp(points, axis=0)))
    if len(points) < 2 or size == 0:
        raise InputError(f"{name}: its nodes coincide, so no surface can be made from them; "
                         "give one with --obj SURFACE.obj")
    flat = [vt[a] for a in range(3) if a >= len(s) or s[a] <= 1e-9 * s[0]]
    cloud = points
    for normal in flat:
        offset = 0.5 * HULL_THICKNESS * size * normal
        cloud = np.vstack([cloud + offset, cloud - offset])
    try:
        hull = ConvexHull(cloud)
    except (QhullError, ValueError) as exc:
        raise InputError(f"{name}: no surface can be made from its nodes ({exc}); give one with --obj SURFACE.obj")
    mesh = trimesh.Trimesh(cloud, hull.simplices, process=True)
    mesh.fix_normals()
    vertices, faces = trimesh.remesh.subdivide_to_size(mesh.vertices, mesh.faces, size / HULL_EDGES)
    return np.asarray(vertices, float), np.asarray(faces, np.int64)


def body_surface(sid, name: str, obj_path=None) -> Surface:
    """The surface to animate: stored FE surface modes, else an OBJ (or the hull of the nodes)
    whose points follow the nodes by the elastic interpolation."""
    stored = stored_surface(sid)
    if stored is not None and obj_path is None:
        return stored
    nodes, _ = node_points(sid)
    if obj_path is not None:
        points, triangles = read_obj(obj_path)
        return interpolated_surface(sid, points, triangles, f"{Path(obj_path).name}, interpolated from {len(nodes)} nodes")
    points, triangles = hull_surface(nodes, name)
    return interpolated_surface(sid, points, triangles, f"convex hull of the {len(nodes)} nodes (no OBJ given), interpolated")


def unit_names(units: str) -> dict[str, str]:
    """Unit of mass, length and inertia in a SID's unit system ("SI": kg, m, kg m^2; another
    system is named as the file names it)."""
    if units == "SI":
        return {"mass": "kg", "length": "m", "inertia": "kg m^2"}
    return {kind: units for kind in ("mass", "length", "inertia")}


def properties_rows(sid) -> list[tuple[str, str]]:
    """Side-table rows of a SID's mass properties, each with its unit."""
    cm = sid.mdCM.M0[:, 0] / sid.mass if sid.mass else np.zeros(3)
    inertia = inertia_matrix(np.asarray(sid.J.M0, float).ravel())
    unit = unit_names(str(sid.units))
    fmt = lambda v: " ".join(f"{x:.4g}" for x in v)  # noqa: E731
    return [("units", html.escape(str(sid.units))), (f"mass ({unit['mass']})", f"{sid.mass:.6g}"),
            (f"CM ({unit['length']}, body frame)", fmt(cm)),
            (f"inertia at O ({unit['inertia']})", "<br>".join(fmt(r) for r in inertia)),
            ("nodes", str(len(sid.nodes))), ("modes", str(sid.nq))]


def checks_rows(sid) -> list[tuple[str, str]]:
    """Side-table rows of the SID's model checks: ok / FAIL / info and the value."""
    rows = []
    for name, c in sid_checks(sid).items():
        flag = "info" if c.severity == "info" else "ok" if c.passed else "FAIL"
        value = c.value
        shown = f"{value:.2e}" if isinstance(value, (int, float)) else html.escape(str(value))
        rows.append((name, f"<span class='{flag}'>{flag}</span> {shown}"))
    return rows


def mode_names(sid) -> list[str]:
    """'k: f Hz kind' of every modal coordinate."""
    kinds = list(getattr(sid, "mode_kinds", ()) or ()) + [""] * sid.nq
    freqs = np.asarray(getattr(sid, "frequencies_hz", None) if getattr(sid, "frequencies_hz", None) is not None
                       else np.full(sid.nq, np.nan), float)
    return [f"{k + 1}: {freqs[k]:.4g} Hz {kinds[k]}".strip() for k in range(sid.nq)]


def mode_figure(surface: Surface, nodes: np.ndarray, size: float, units: str):
    """The plotly figure of the mode page: surface, interface nodes and the body frame K."""
    import plotly.graph_objects as go  # deferred: 0.25 s import, pages only

    p, t = surface.points, surface.triangles
    traces = [go.Mesh3d(x=p[:, 0], y=p[:, 1], z=p[:, 2], i=t[:, 0], j=t[:, 1], k=t[:, 2],
                        intensity=np.zeros(len(p)), colorscale="Viridis", cmin=0, cmax=1, flatshading=False,
                        colorbar=colorbar("|u| / max"), name="surface", showscale=True),
              go.Scatter3d(x=nodes[:, 0], y=nodes[:, 1], z=nodes[:, 2], mode="markers",
                           marker=dict(size=4, color="red"), name="nodes")]
    traces += frame_axes(0.25 * size, "K")
    fig = go.Figure(traces)
    fig.update_layout(scene=dict(aspectmode="data", **axis_titles(units)), margin=dict(l=0, r=0, t=0, b=0),
                      showlegend=False)
    return fig


_MODE_SCRIPT = """
const sel = document.getElementById('mode'), scl = document.getElementById('scale');
const n = D.x.length;
let playing = false, t0 = performance.now(), last = 0;
function show(phase) {
  const k = +sel.value;
  if (k < 0) { Plotly.restyle(gd, {x: [D.x], y: [D.y], z: [D.z], intensity: [new Array(n).fill(0)]}, [0]); return; }
  const S = D.shapes[k], c = phase * (+scl.value) * D.amp[k];
  const x = new Array(n), y = new Array(n), z = new Array(n), I = new Array(n);
  let peak = 0;
  for (let i = 0; i < n; i++) {
    const ux = c * S[3*i], uy = c * S[3*i+1], uz = c * S[3*i+2];
    x[i] = D.x[i] + ux; y[i] = D.y[i] + uy; z[i] = D.z[i] + uz;
    I[i] = Math.hypot(S[3*i], S[3*i+1], S[3*i+2]);
    peak = Math.max(peak, I[i]);
  }
  for (let i = 0; i < n; i++) I[i] = peak > 0 ? I[i] / peak : 0;
  const vm = D.vm && document.getElementById('colour').value === 'vm';
  Plotly.restyle(gd, {x: [x], y: [y], z: [z], intensity: [vm ? D.vm[k] : I],
                      'colorbar.title.text': [vm ? 'von Mises / max' : '|u| / max']}, [0]);
  document.getElementById('factor').textContent = (phase * (+scl.value) * D.amp[k]).toPrecision(3);
  if (D.vm) document.getElementById('vmpeak').textContent = vm ? 'max von Mises ' + (D.vm_peak[k] / 1e6).toPrecision(4) + ' MPa per unit q' : '';
}
function tick(now) {
  if (playing && now - last > 50) { last = now; show(Math.sin(2 * Math.PI * (now - t0) / 1500)); }
  requestAnimationFrame(tick);
}
document.getElementById('play').onclick = function () { playing = !playing; this.textContent = playing ? 'stop' : 'animate'; if (!playing) show(1); };
sel.onchange = () => show(1); scl.oninput = () => show(1);
if (D.vm) document.getElementById('colour').onchange = () => show(1);
const m = /mode=(\\d+)/.exec(location.hash);
if (m) { sel.value = String(+m[1] - 1); }
if (D.vm && /stress/.test(location.hash)) document.getElementById('colour').value = 'vm';
show(1);
requestAnimationFrame(tick);
"""


def write_mode_page(sid_path, out_path=None, obj_path=None) -> Path:
    """Write the mode viewer page of a SID file; returns its path (default: next to the SID, .html).

    Parameters
    ----------
    sid_path : .sid.h5 or .SID_FEM file.
    out_path : the .html page to write.
    obj_path : optional OBJ surface (body-frame coordinates in the SID's units); with it, or
        when the SID stores no surface modes, the surface follows the nodes by elastic interpolation.
    """

    sid_path = Path(sid_path)
    sid = read_sid(sid_path)
    if sid.nq == 0:
        raise InputError(f"{sid_path}: the SID has no modes to show")
    out_path = Path(out_path) if out_path else sid_path.with_name(sid_path.name.split(".")[0] + ".html")
    surface = body_surface(sid, str(sid_path), obj_path)
    nodes, _ = node_points(sid)
    size = float(np.linalg.norm(np.ptp(np.vstack([surface.points, nodes]), axis=0))) or 1.0
    peaks = np.linalg.norm(surface.shapes, axis=1).max(axis=0)
    amp = np.where(peaks > 0, DISPLAY_FRACTION * size / np.where(peaks > 0, peaks, 1), 0.0)
    data = {"x": js_array(surface.points[:, 0]), "y": js_array(surface.points[:, 1]),
            "z": js_array(surface.points[:, 2]),
            "shapes": "[" + ",".join(js_array(surface.shapes[:, :, k] * amp[k]) for k in range(sid.nq)) + "]",
            "amp": json.dumps([1.0] * sid.nq)}
    stress_rows = []
    if sid.stress is not None:
        modes = surface.stress if surface.stress is not None else stress_on_points(sid.stress, surface.points)
        vm = von_mises(modes.transpose(0, 2, 1))                                 # (ns, nq) Pa/[q]
        vm_peak = vm.max(axis=0)
        data["vm"] = "[" + ",".join(js_array(vm[:, k] / (vm_peak[k] or 1.0), 3) for k in range(sid.nq)) + "]"
        data["vm_peak"] = json.dumps(vm_peak.tolist())
        stress_rows = [("modal stresses", f"{sid.stress.n_nodes} {html.escape(sid.stress.scope)} nodes"),
                       *[(f"{k + 1}", f"{v / PA_PER_MPA:.4g} MPa") for k, v in enumerate(vm_peak)]]
    names = mode_names(sid)
    options = "".join(f"<option value='{k}'>{html.escape(s)}</option>" for k, s in enumerate(names))
    controls = (f"mode <select id='mode'><option value='-1'>undeformed</option>{options}</select> "
                "scale <input id='scale' type='range' min='0' max='5' step='0.1' value='1'> "
                "<button id='play'>animate</button> displayed factor <span id='factor'></span> x "
                "(1 = largest displacement at 10 % of the body size)")
    if stress_rows:
        controls += (" colour <select id='colour'><option value='u'>displacement</option>"
                     "<option value='vm'>von Mises stress</option></select> <span id='vmpeak'></span>")
    side = (table(properties_rows(sid)) + f"<p>surface: {html.escape(surface.source)}</p>"
            + "<h4>modes</h4>" + table([(s.split(':')[0], html.escape(s.split(':', 1)[1])) for s in names])
            + ("<h4>largest von Mises stress per unit q</h4>" + table(stress_rows) if stress_rows else "")
            + "<h4>checks</h4>" + table(checks_rows(sid)))
    figure = mode_figure(surface, nodes, size, unit_names(str(sid.units))["length"])
    return write_page(out_path, sid_path.name, figure, controls, side, _MODE_SCRIPT, js_object(data))


