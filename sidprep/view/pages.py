"""Self-contained HTML pages (plotly, JavaScript inlined) for mode shapes and simulated mechanisms.

``write_mode_page`` draws a SID body: its surface (the stored FE surface modes, or an OBJ / the
convex hull of its nodes deformed by ``sidprep.interpolation`` for SID files with few nodes), its
interface nodes and body frame, each mode animated on demand with an adjustable scale, and a side
table (mass, CM, inertia, frequencies, checks).  The page opens offline by double-click.
Append ``#mode=N`` (1-based) to the address to show mode N at its peak (used for screenshots).
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
from sidprep.sid.io.atomic import atomic_path
from sidprep.sid.io.obj import read_obj
from sidprep.sid.model import inertia_matrix
from sidprep.sid.stress import stress_on_points, von_mises
from sidprep.sid.surface import (Surface, interpolated_surface, node_points, rigid_surface, stored_surface,
    surface_motion, surface_von_mises)
from sidprep.solver.results import read_results


#: the pages show stresses in MPa
PA_PER_MPA = 1e6
#: the largest mode displacement is drawn as this fraction of the body's bounding-box diagonal
DISPLAY_FRACTION = 0.1
#: digits kept in the page's coordinates (relative to the body size): 1e-5 of the diagonal
PAGE_DIGITS = 5
PLOT_ID = "sidprep-plot"
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


def _rounded(a: np.ndarray, size: float) -> list:
    step = size * 10.0 ** -PAGE_DIGITS
    return (np.round(np.asarray(a, float) / step) * step).ravel().tolist()


def _table(rows: list[tuple[str, str]]) -> str:
    return "<table>" + "".join(f"<tr><th>{html.escape(k)}</th><td>{v}</td></tr>" for k, v in rows) + "</table>"


def _properties_rows(sid) -> list[tuple[str, str]]:

    cm = sid.mdCM.M0[:, 0] / sid.mass if sid.mass else np.zeros(3)
    inertia = inertia_matrix(np.asarray(sid.J.M0, float).ravel())
    fmt = lambda v: " ".join(f"{x:.4g}" for x in v)  # noqa: E731
    return [("units", html.escape(str(sid.units))), ("mass", f"{sid.mass:.6g}"),
            ("CM", fmt(cm)), ("inertia at O", "<br>".join(fmt(r) for r in inertia)),
            ("nodes", str(len(sid.nodes))), ("modes", str(sid.nq))]


def _checks_rows(sid) -> list[tuple[str, str]]:

    rows = []
    for name, c in sid_checks(sid).items():
        flag = "info" if c["severity"] == "info" else "ok" if c["passed"] else "FAIL"
        value = c["value"]
        shown = f"{value:.2e}" if isinstance(value, (int, float)) else html.escape(str(value))
        rows.append((name, f"<span class='{flag}'>{flag}</span> {shown}"))
    return rows


def _mode_names(sid) -> list[str]:
    kinds = list(getattr(sid, "mode_kinds", ()) or ()) + [""] * sid.nq
    freqs = np.asarray(getattr(sid, "frequencies_hz", None) if getattr(sid, "frequencies_hz", None) is not None
                       else np.full(sid.nq, np.nan), float)
    return [f"{k + 1}: {freqs[k]:.4g} Hz {kinds[k]}".strip() for k in range(sid.nq)]


def _figure(surface: Surface, nodes: np.ndarray, size: float):
    import plotly.graph_objects as go  # deferred: 0.25 s import, pages only

    p, t = surface.points, surface.triangles
    traces = [go.Mesh3d(x=p[:, 0], y=p[:, 1], z=p[:, 2], i=t[:, 0], j=t[:, 1], k=t[:, 2],
                        intensity=np.zeros(len(p)), colorscale="Viridis", cmin=0, cmax=1, flatshading=False,
                        colorbar=dict(title="|u| / max"), name="surface", showscale=True),
              go.Scatter3d(x=nodes[:, 0], y=nodes[:, 1], z=nodes[:, 2], mode="markers",
                           marker=dict(size=4, color="red"), name="nodes")]
    axis = 0.25 * size
    for a, colour in enumerate(("red", "green", "blue")):
        end = np.zeros(3)
        end[a] = axis
        traces.append(go.Scatter3d(x=[0, end[0]], y=[0, end[1]], z=[0, end[2]], mode="lines+text",
                                   text=["", "xyz"[a]], line=dict(color=colour, width=6), name=f"K {'xyz'[a]}"))
    fig = go.Figure(traces)
    fig.update_layout(scene=dict(aspectmode="data"), margin=dict(l=0, r=0, t=0, b=0), showlegend=False)
    return fig


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
#{plot_id} {{ flex: 1; }}
</style></head><body>
<div id="main"><div id="controls">{controls}</div>{plot}</div>
<div id="side"><h3>{title}</h3>{side}</div>
<script>{script}</script>
</body></html>
"""


def write_page(path, title: str, figure, controls: str, side: str, script: str) -> Path:
    """Write one self-contained HTML page (plotly.js inlined) atomically; returns the path."""
    plot = figure.to_html(full_html=False, include_plotlyjs=True, div_id=PLOT_ID,
                          default_width="calc(100vw - 380px)", default_height="calc(100vh - 40px)", config={"responsive": True})
    text = _PAGE.format(title=html.escape(title), plot_id=PLOT_ID, controls=controls, plot=plot, side=side,
                        script=script)
    path = Path(path)
    with atomic_path(path) as tmp:
        Path(tmp).write_text(text, encoding="utf-8")
    return path


_MODE_SCRIPT = """
const D = %s;
const gd = document.getElementById('%s');
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
    data = {"x": _rounded(surface.points[:, 0], size), "y": _rounded(surface.points[:, 1], size),
            "z": _rounded(surface.points[:, 2], size),
            "shapes": [_rounded(surface.shapes[:, :, k] * amp[k], size) for k in range(sid.nq)],
            "amp": [1.0] * sid.nq}
    stress_rows = []
    if sid.stress is not None:
        modes = surface.stress if surface.stress is not None else stress_on_points(sid.stress, surface.points)
        vm = von_mises(modes.transpose(0, 2, 1))                                 # (ns, nq) Pa/[q]
        vm_peak = vm.max(axis=0)
        data["vm"] = [np.round(vm[:, k] / (vm_peak[k] or 1.0), 3).tolist() for k in range(sid.nq)]
        data["vm_peak"] = vm_peak.tolist()
        stress_rows = [("modal stresses", f"{sid.stress.n_nodes} {html.escape(sid.stress.scope)} nodes"),
                       *[(f"{k + 1}", f"{v / PA_PER_MPA:.4g} MPa") for k, v in enumerate(vm_peak)]]
    names = _mode_names(sid)
    options = "".join(f"<option value='{k}'>{html.escape(s)}</option>" for k, s in enumerate(names))
    controls = (f"mode <select id='mode'><option value='-1'>undeformed</option>{options}</select> "
                "scale <input id='scale' type='range' min='0' max='5' step='0.1' value='1'> "
                "<button id='play'>animate</button> displayed factor <span id='factor'></span> x "
                "(1 = largest displacement at 10 % of the body size)")
    if stress_rows:
        controls += (" colour <select id='colour'><option value='u'>displacement</option>"
                     "<option value='vm'>von Mises stress</option></select> <span id='vmpeak'></span>")
    side = (_table(_properties_rows(sid)) + f"<p>surface: {html.escape(surface.source)}</p>"
            + "<h4>modes</h4>" + _table([(s.split(':')[0], html.escape(s.split(':', 1)[1])) for s in names])
            + ("<h4>largest von Mises stress per unit q</h4>" + _table(stress_rows) if stress_rows else "")
            + "<h4>checks</h4>" + _table(_checks_rows(sid)))
    script = _MODE_SCRIPT % (json.dumps(data), PLOT_ID)
    return write_page(out_path, f"{sid_path.name}", _figure(surface, nodes, size), controls, side, script)


# ---------------------------------------------------------------------------------------------
# the simulated mechanism (sidprep animate)

#: at most this many time samples go into a page or a movie (every k-th output sample)
MAX_PAGE_FRAMES = 300
MAX_MOVIE_FRAMES = 60


def resolve_source(source: str, results_path: Path, scene_path: str) -> Path:
    """Find a body's SID/OBJ file named in a results file: as stored, beside the scene file, or
    beside the results file."""
    candidates = [Path(source)]
    if scene_path:
        candidates.append(Path(scene_path).parent / Path(source).name)
        candidates.append(Path(scene_path).parent / source)
    candidates.append(results_path.parent / Path(source).name)
    found = next((c for c in candidates if c.is_file()), None)
    if found is None:
        raise InputError(f"{results_path}: the body file {source!r} it names is not found (tried "
                         f"{', '.join(map(str, candidates))}); run `sidprep animate` from the simulation's folder")
    return found


def mechanism_surfaces(results_path) -> tuple[object, dict]:
    """The results (``solver.results.ResultsFile``) and {body name: Surface} of its bodies
    with a shape: flexible bodies from their SID (interpolated when it has few nodes), rigid
    bodies from their OBJ (no modes)."""

    results_path = Path(results_path)
    rf = read_results(results_path)
    scene_path = rf.scene.get("path", "")
    surfaces = {}
    for name, info in rf.bodies.items():
        if not info.get("source"):
            continue
        path = resolve_source(info["source"], results_path, scene_path)
        if info.get("kind") == "flexible":
            surfaces[name] = body_surface(read_sid(path), str(path))
        else:
            points, triangles = read_obj(path)
            surfaces[name] = rigid_surface(points, triangles, path.name)
    if not surfaces:
        raise InputError(f"{results_path}: no body has a surface to animate; give rigid bodies an `obj` "
                         "or flexible bodies a SID file")
    return rf, surfaces


def _samples(nt: int, limit: int) -> np.ndarray:
    return np.arange(0, nt, max(1, int(np.ceil(nt / limit))))


def exaggeration(result, surfaces: dict) -> float:
    """Scale that draws the largest elastic displacement of the run at DISPLAY_FRACTION of the
    mechanism size (1 when nothing deforms)."""
    peak, extent = 0.0, []
    for name, s in surfaces.items():
        b = result.bodies[name]
        x, u = surface_motion(s, b.position, b.rotation, b.q)
        umag = np.linalg.norm(u, axis=2)
        peak = max(peak, float(umag.max()))
        extent.append(x.reshape(-1, 3))
    size = float(np.linalg.norm(np.ptp(np.vstack(extent), axis=0)))
    return DISPLAY_FRACTION * size / peak if peak > 0 else 1.0


_MECHANISM_SCRIPT = """
const D = %s;
const gd = document.getElementById('%s');
const slider = document.getElementById('time'), mode = document.getElementById('deform');
const colour = document.getElementById('colour');
let playing = false, wall0 = 0, t0 = 0, last = 0, stress = colour.value === 'stress';
function show(i) {
  const s = mode.value === 'exaggerated' ? D.exaggeration : 1.0;
  const xs = [], ys = [], zs = [], cs = [];
  for (const B of D.bodies) {
    const n = B.c.length / 3, r = B.r[i], A = B.A[i], q = B.q[i];
    const x = new Array(n), y = new Array(n), z = new Array(n), c = new Array(n);
    for (let p = 0; p < n; p++) {
      let u0 = 0, u1 = 0, u2 = 0;
      for (let k = 0; k < q.length; k++) {
        const o = (3 * p) * q.length;
        u0 += B.S[o + k] * q[k]; u1 += B.S[o + q.length + k] * q[k]; u2 += B.S[o + 2 * q.length + k] * q[k];
      }
      const l0 = B.c[3*p] + s * u0, l1 = B.c[3*p+1] + s * u1, l2 = B.c[3*p+2] + s * u2;
      x[p] = r[0] + A[0]*l0 + A[1]*l1 + A[2]*l2;
      y[p] = r[1] + A[3]*l0 + A[4]*l1 + A[5]*l2;
      z[p] = r[2] + A[6]*l0 + A[7]*l1 + A[8]*l2;
      c[p] = Math.hypot(u0, u1, u2);
    }
    xs.push(x); ys.push(y); zs.push(z); cs.push(stress ? (B.vm ? B.vm[i] : new Array(n).fill(0)) : c);
  }
  Plotly.restyle(gd, {x: xs, y: ys, z: zs, intensity: cs}, D.bodies.map((_, b) => b));
  document.getElementById('clock').textContent = D.t[i].toFixed(4);
}
function legend() {
  Plotly.relayout(gd, {'coloraxis.cmax': stress ? D.vm_max : D.u_max,
                       'coloraxis.colorbar.title.text': stress ? 'von Mises (MPa)' : '|u| (m)'});
}
function tick(now) {
  if (playing && now - last > 40) {
    last = now;
    const t = t0 + (now - wall0) / 1000;
    let i = D.t.findIndex(v => v >= t);
    if (i < 0) { i = D.t.length - 1; playing = false; document.getElementById('play').textContent = 'play'; }
    slider.value = i; show(i);
  }
  requestAnimationFrame(tick);
}
document.getElementById('play').onclick = function () {
  playing = !playing; this.textContent = playing ? 'pause' : 'play';
  if (+slider.value >= D.t.length - 1) slider.value = 0;
  wall0 = performance.now(); t0 = D.t[+slider.value];
};
slider.oninput = () => show(+slider.value); mode.onchange = () => show(+slider.value);
colour.onchange = () => { stress = colour.value === 'stress'; legend(); show(+slider.value); };
const m = /t=(\\d+)/.exec(location.hash);
if (m) slider.value = Math.min(+m[1], D.t.length - 1);
if (/exaggerated/.test(location.hash)) mode.value = 'exaggerated';
if (/stress/.test(location.hash) && !colour.disabled) { colour.value = 'stress'; stress = true; }
legend();
show(+slider.value);
requestAnimationFrame(tick);
"""


def write_mechanism_page(results_path, out_path, colour: str = "displacement") -> Path:
    """Self-contained HTML page of a simulated mechanism: surfaces coloured by |u| (m) or by the
    von Mises stress (MPa, bodies whose SID has modal stresses; ``colour`` the initial choice, a
    switch on the page), a time slider with real-time play, true or exaggerated deformation.
    Append ``#t=N&exaggerated&stress`` to the address to open at sample N, exaggerated, coloured by stress."""
    import plotly.graph_objects as go  # deferred: 0.25 s import, pages only

    rf, surfaces = mechanism_surfaces(results_path)
    result = rf.result
    keep = _samples(len(result.t), MAX_PAGE_FRAMES)
    scale = exaggeration(result, surfaces)
    bodies, traces, allx, umax, vm_max = [], [], [], 0.0, 0.0
    for name, s in surfaces.items():
        b = result.bodies[name]
        x, u = surface_motion(s, b.position[keep], b.rotation[keep], b.q[keep], scale)
        umag = np.linalg.norm(u, axis=2)
        allx.append(x.reshape(-1, 3))
        umax = max(umax, float(umag.max()))
        nq = s.shapes.shape[2]
        bodies.append({"c": s.points.ravel().tolist(), "S": s.shapes.reshape(-1).tolist() if nq else [],
                       "r": b.position[keep].tolist(), "A": b.rotation[keep].reshape(len(keep), 9).tolist(),
                       "q": b.q[keep][:, :nq].tolist() if nq else [[] for _ in keep]})
        vm = surface_von_mises(s, b.q[keep])
        if vm is not None:
            vm = vm / PA_PER_MPA
            bodies[-1]["vm"] = np.round(vm, 2).tolist()
            vm_max = max(vm_max, float(vm.max()))
        t = s.triangles
        traces.append(go.Mesh3d(x=x[0, :, 0], y=x[0, :, 1], z=x[0, :, 2], i=t[:, 0], j=t[:, 1], k=t[:, 2],
                                intensity=umag[0], colorscale="Viridis", cmin=0, cmax=1, name=name,
                                coloraxis="coloraxis"))
    cloud = np.vstack(allx)
    lo, hi = cloud.min(axis=0), cloud.max(axis=0)
    pad = 0.05 * float(np.max(hi - lo) or 1.0)
    ranges = [[float(a - pad), float(b + pad)] for a, b in zip(lo, hi)]
    spans = np.array([r[1] - r[0] for r in ranges])
    fig = go.Figure(traces)
    fig.update_layout(scene=dict(xaxis=dict(range=ranges[0]), yaxis=dict(range=ranges[1]),
                                 zaxis=dict(range=ranges[2]), aspectmode="manual",
                                 aspectratio=dict(zip("xyz", (spans / spans.max()).tolist()))),
                      coloraxis=dict(colorscale="Viridis", cmin=0, cmax=umax or 1.0,
                                     colorbar=dict(title="|u| (m)")),
                      margin=dict(l=0, r=0, t=0, b=0), showlegend=False)
    data = {"t": result.t[keep].tolist(), "exaggeration": scale, "bodies": bodies, "u_max": umax or 1.0,
            "vm_max": vm_max or 1.0}
    has_stress = any("vm" in b for b in bodies)
    if colour == "stress" and not has_stress:
        raise InputError(f"{results_path}: no body's SID has modal stresses to colour by; reduce with "
                         "`sidprep reduce MESH --stress` and re-run the simulation, or colour by displacement")
    controls = (f"<button id='play'>play</button> t = <span id='clock'></span> s "
                f"<input id='time' type='range' min='0' max='{len(keep) - 1}' step='1' value='0' style='width:40%'> "
                "<select id='deform'><option value='real'>real deformation</option>"
                f"<option value='exaggerated'>exaggerated x {scale:.3g}</option></select> colour "
                f"<select id='colour'{'' if has_stress else ' disabled'}><option value='displacement'>displacement |u|</option>"
                f"<option value='stress'{' selected' if colour == 'stress' else ''}>von Mises stress</option></select>")
    rows = [("results", html.escape(Path(results_path).name)), ("scene", html.escape(rf.scene.get("path", ""))),
            ("time", f"{result.t[0]:.4g} .. {result.t[-1]:.4g} s, {len(result.t)} samples ({len(keep)} shown)"),
            ("max |u|", f"{umax:.3g} m")]
    if has_stress:
        rows.append(("max von Mises", f"{vm_max:.4g} MPa (shown samples)"))
    rows += [(name, html.escape(s.source)) for name, s in surfaces.items()]
    script = _MECHANISM_SCRIPT % (json.dumps(data), PLOT_ID)
    return write_page(out_path, Path(results_path).name, fig, controls, _table(rows), script)


def write_mechanism_movie(results_path, out_path, exaggerated: bool = True, colour: str = "displacement") -> Path:
    """An .mp4 (needs ffmpeg) or .gif movie of the mechanism with matplotlib, at most
    MAX_MOVIE_FRAMES frames, surfaces coloured by |u| (m) or by the von Mises stress (``colour =
    "stress"``, MPa), with a colour bar."""
    import matplotlib  # deferred: 1.2 s import, plots only

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # deferred: 1.2 s import, plots only
    from matplotlib import animation
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # deferred: with matplotlib

    out_path = Path(out_path)
    suffix = out_path.suffix.lower()
    if suffix == ".mp4" and not animation.FFMpegWriter.isAvailable():
        raise InputError(f"{out_path}: writing .mp4 needs ffmpeg (apt-get install ffmpeg); write a .gif instead")
    rf, surfaces = mechanism_surfaces(results_path)
    result = rf.result
    keep = _samples(len(result.t), MAX_MOVIE_FRAMES)
    scale = exaggeration(result, surfaces) if exaggerated else 1.0
    motion = {}
    for n, s in surfaces.items():
        x, u = surface_motion(s, result.bodies[n].position[keep], result.bodies[n].rotation[keep],
                              result.bodies[n].q[keep], scale)
        motion[n] = (x, np.linalg.norm(u, axis=2))
    cloud = np.vstack([x.reshape(-1, 3) for x, _ in motion.values()])
    if colour == "stress":
        values = {n: surface_von_mises(s, result.bodies[n].q[keep]) for n, s in surfaces.items()}
        values = {n: None if v is None else v / PA_PER_MPA for n, v in values.items()}
        if all(v is None for v in values.values()):
            raise InputError(f"{results_path}: no body's SID has modal stresses to colour by; reduce with "
                             "`sidprep reduce MESH --stress` and re-run the simulation, or colour by displacement")
        values = {n: np.zeros(motion[n][1].shape) if v is None else v for n, v in values.items()}
        label = "von Mises (MPa)"
    else:
        values, label = {n: u for n, (_, u) in motion.items()}, "|u| (m)"
    umax = max(float(v.max()) for v in values.values()) or 1.0
    fig = plt.figure(figsize=(6.6, 5), dpi=80)
    ax = fig.add_subplot(projection="3d")
    cmap = plt.get_cmap("viridis")
    fig.colorbar(plt.cm.ScalarMappable(matplotlib.colors.Normalize(0, umax), cmap), ax=ax, shrink=0.6, label=label)

    def draw(f):
        ax.cla()
        for name, s in surfaces.items():
            x, _ = motion[name]
            colours = cmap(values[name][f][s.triangles].mean(axis=1) / umax)
            ax.add_collection3d(Poly3DCollection(x[f][s.triangles], facecolors=colours, linewidths=0))
        for set_lim, a in ((ax.set_xlim, 0), (ax.set_ylim, 1), (ax.set_zlim, 2)):
            set_lim(cloud[:, a].min(), cloud[:, a].max())
        ax.set_box_aspect(np.ptp(cloud, axis=0) + 1e-12)
        ax.set_title(f"t = {result.t[keep][f]:.3f} s, deformation x {scale:.3g}")

    movie = animation.FuncAnimation(fig, draw, frames=len(keep))
    dt = float(np.median(np.diff(result.t[keep]))) if len(keep) > 1 else 0.1
    fps = max(1, min(30, round(1.0 / dt)))
    writer = animation.PillowWriter(fps=fps) if suffix == ".gif" else animation.FFMpegWriter(fps=fps)
    with atomic_path(out_path) as tmp:
        movie.save(str(tmp) + suffix, writer=writer)
        Path(str(tmp) + suffix).replace(tmp)
    plt.close(fig)
    return out_path
