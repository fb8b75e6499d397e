"""The mechanism page of a simulation (``sidprep animate``): every body's surface moving as
x = r_O + A (c + S q) (sid-spec 5.2), coloured by |u| (m) or by the von Mises stress (MPa), the
ground (the inertial frame and a plane across gravity), the joints and markers, a time slider with
real-time play, and true or exaggerated deformation.

The page carries each body's surface, shapes S and deviatoric stress modes once, and per shown
sample only r_O, A and q: its script forms the positions and the von Mises stress
sigma_v = |W S_sigma q| (sidprep.sid.stress.DEVIATOR_ROWS) of the frame it shows, so its size grows
with the surface, not with surface x samples.  The stress colour scale ends at the envelope of
``sidprep stress`` (the largest von Mises stress over every sample of the run at the SID's stress
nodes), the displacement scale at the largest |u| of the shown samples.

Append ``#t=N`` (sample N of those shown), ``&exaggerated`` and ``&stress`` to the address to open
the page there.
"""

from __future__ import annotations

import html
import json
from pathlib import Path

import numpy as np

from sidprep.errors import InputError
from sidprep.sid.io import read_sid
from sidprep.sid.io.obj import read_obj
from sidprep.sid.stress import DEVIATOR_ROWS
from sidprep.sid.surface import Surface, rigid_surface, surface_motion
from sidprep.solver.results import read_results
from sidprep.tables import parse_toml
from sidprep.solver.stress import body_stress_modes, von_mises_envelope
from sidprep.view.modes import DISPLAY_FRACTION, body_surface
from sidprep.view.page import (PA_PER_MPA, axis_titles, colorbar, frame_axes, js_array, js_object, table,
                               write_page)

#: at most this many time samples go into a page (every k-th output sample)
MAX_PAGE_FRAMES = 300
#: the ground plane lies this fraction of the mechanism's size below its lowest point
GROUND_CLEARANCE = 0.05
#: gravity's direction when the scene has none (the scene file's default is -z as well)
DEFAULT_DOWN = (0.0, 0.0, -1.0)
#: the ground frame's axes are drawn this fraction of the mechanism's size long
GROUND_AXES = 0.15


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
        if not info.source:
            continue
        path = resolve_source(info.source, results_path, scene_path)
        if info.kind == "flexible":
            surfaces[name] = body_surface(read_sid(path), str(path))
        else:
            points, triangles = read_obj(path)
            surfaces[name] = rigid_surface(points, triangles, path.name)
    if not surfaces:
        raise InputError(f"{results_path}: no body has a surface to animate; give rigid bodies an `obj` "
                         "or flexible bodies a SID file")
    return rf, surfaces


def shown_samples(nt: int, limit: int) -> np.ndarray:
    """Every k-th of nt samples, at most ``limit`` of them (the first always)."""
    return np.arange(0, nt, max(1, int(np.ceil(nt / limit))))


def exaggeration(result, surfaces: dict, samples: np.ndarray) -> float:
    """Scale that draws the largest elastic displacement of the shown ``samples`` at
    DISPLAY_FRACTION of the mechanism size (1 when nothing deforms)."""
    peak, extent = 0.0, []
    for name, s in surfaces.items():
        b = result.bodies[name]
        x, u = surface_motion(s, b.position[samples], b.rotation[samples], b.q[samples])
        peak = max(peak, float(np.linalg.norm(u, axis=2).max()))
        extent.append(x.reshape(-1, 3))
    size = float(np.linalg.norm(np.ptp(np.vstack(extent), axis=0)))
    return DISPLAY_FRACTION * size / peak if peak > 0 else 1.0


def stress_envelope_mpa(rf, results_path: Path, names) -> float:
    """The largest von Mises stress (MPa) over every sample of the run at the stress nodes of the
    bodies ``names`` with modal stresses: ``sidprep stress``'s envelope; 0 when none has them."""
    peak = 0.0
    for name in names:
        try:
            _, _, stress = body_stress_modes(results_path, rf, name)
        except InputError:       # a body without modal stresses is coloured by displacement only
            continue
        peak = max(peak, float(von_mises_envelope(stress, rf.result.bodies[name].q)[0].max()) / PA_PER_MPA)
    return peak


def deviatoric_modes_mpa(surface: Surface) -> np.ndarray | None:
    """W S_sigma at the surface points (ns, 5, nq), MPa per unit q: |W S_sigma q| is the von Mises
    stress (sidprep.sid.stress.DEVIATOR_ROWS); None without modal stresses."""
    if surface.stress is None:
        return None
    return np.einsum("rc,sck->srk", DEVIATOR_ROWS, surface.stress) / PA_PER_MPA


def gravity_direction(scene_text: str) -> np.ndarray:
    """The unit vector of the scene's ``[scene] gravity`` (DEFAULT_DOWN when absent or zero)."""
    try:
        g = np.asarray(parse_toml(scene_text, "scene").get("scene", {}).get("gravity", DEFAULT_DOWN), float)
    except (InputError, ValueError, TypeError, AttributeError):   # a results file's scene is only provenance
        g = np.asarray(DEFAULT_DOWN)
    norm = float(np.linalg.norm(g)) if g.shape == (3,) else 0.0
    return g / norm if norm > 0 and np.isfinite(norm) else np.asarray(DEFAULT_DOWN)


def ground_plane(cloud: np.ndarray, down: np.ndarray, size: float) -> tuple[np.ndarray, np.ndarray]:
    """Corners (4, 3) m and triangles (2, 3) of the ground: a plane across ``down`` a clearance
    below the lowest point of ``cloud`` (n, 3), covering its shadow."""
    e1 = np.cross(down, [1.0, 0.0, 0.0] if abs(down[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(down, e1)
    depth = float((cloud @ down).max()) + GROUND_CLEARANCE * size
    a, b = cloud @ e1, cloud @ e2
    pad = GROUND_CLEARANCE * size
    corners = [(a.min() - pad) * e1 + (b.min() - pad) * e2, (a.max() + pad) * e1 + (b.min() - pad) * e2,
               (a.max() + pad) * e1 + (b.max() + pad) * e2, (a.min() - pad) * e1 + (b.max() + pad) * e2]
    return np.array(corners) + depth * down, np.array([[0, 1, 2], [0, 2, 3]])


def joint_markers(result) -> set[str]:
    """Names of the markers that joints connect (drawn as hinges)."""
    return {m for j in result.joints.values() for m in getattr(j, "markers", ())}


_MECHANISM_SCRIPT = """
const slider = document.getElementById('time'), mode = document.getElementById('deform');
const colour = document.getElementById('colour');
let playing = false, wall0 = 0, t0 = 0, last = 0, stress = colour.value === 'stress';
function show(i) {
  const s = mode.value === 'exaggerated' ? D.exaggeration : 1.0;
  const xs = [], ys = [], zs = [], cs = [];
  for (const B of D.bodies) {
    const n = B.c.length / 3, nq = B.nq, r = B.r.slice(3 * i, 3 * i + 3), A = B.A.slice(9 * i, 9 * i + 9);
    const q = B.q.slice(nq * i, nq * i + nq);
    const x = new Array(n), y = new Array(n), z = new Array(n), c = new Array(n);
    for (let p = 0; p < n; p++) {
      let u0 = 0, u1 = 0, u2 = 0;
      const o = 3 * p * nq;
      for (let k = 0; k < nq; k++) { u0 += B.S[o + k] * q[k]; u1 += B.S[o + nq + k] * q[k]; u2 += B.S[o + 2 * nq + k] * q[k]; }
      const l0 = B.c[3*p] + s * u0, l1 = B.c[3*p+1] + s * u1, l2 = B.c[3*p+2] + s * u2;
      x[p] = r[0] + A[0]*l0 + A[1]*l1 + A[2]*l2;
      y[p] = r[1] + A[3]*l0 + A[4]*l1 + A[5]*l2;
      z[p] = r[2] + A[6]*l0 + A[7]*l1 + A[8]*l2;
      if (stress) {
        let vm = 0;
        if (B.V) for (let row = 0; row < 5; row++) {
          const v = 5 * p * nq + row * nq;
          let d = 0;
          for (let k = 0; k < nq; k++) d += B.V[v + k] * q[k];
          vm += d * d;
        }
        c[p] = Math.sqrt(vm);
      } else c[p] = Math.hypot(u0, u1, u2);
    }
    xs.push(x); ys.push(y); zs.push(z); cs.push(c);
  }
  const M = D.markers, m = M.names.length;
  const mx = new Array(m), my = new Array(m), mz = new Array(m);
  for (let k = 0; k < m; k++) { const o = 3 * (i * m + k); mx[k] = M.P[o]; my[k] = M.P[o+1]; mz[k] = M.P[o+2]; }
  Plotly.restyle(gd, {x: xs, y: ys, z: zs, intensity: cs}, D.bodies.map((_, b) => b));
  if (m) Plotly.restyle(gd, {x: [mx], y: [my], z: [mz]}, [D.bodies.length]);
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
const h = /t=(\\d+)/.exec(location.hash);
if (h) slider.value = Math.min(+h[1], D.t.length - 1);
if (/exaggerated/.test(location.hash)) mode.value = 'exaggerated';
if (/stress/.test(location.hash) && !colour.disabled) { colour.value = 'stress'; stress = true; }
legend();
show(+slider.value);
requestAnimationFrame(tick);
"""


def body_data(surface: Surface, b, samples: np.ndarray) -> str:
    """The page's data of one body: points c, shapes S, deviatoric stress modes V (if any) once,
    r_O, A and q at the shown samples."""
    nq = surface.shapes.shape[2]
    members = {"nq": str(nq), "c": js_array(surface.points), "S": js_array(surface.shapes),
               "r": js_array(b.position[samples]), "A": js_array(b.rotation[samples]),
               "q": js_array(b.q[samples][:, :nq])}
    deviatoric = deviatoric_modes_mpa(surface)
    if deviatoric is not None:
        members["V"] = js_array(deviatoric)
    return js_object(members)


def write_mechanism_page(results_path, out_path, colour: str = "displacement") -> Path:
    """Self-contained HTML page of a simulated mechanism (module doc); ``colour`` the initial
    colouring ("displacement" or "stress"), a switch on the page."""
    import plotly.graph_objects as go  # deferred: 0.25 s import, pages only

    results_path = Path(results_path)
    rf, surfaces = mechanism_surfaces(results_path)
    result = rf.result
    keep = shown_samples(len(result.t), MAX_PAGE_FRAMES)
    scale = exaggeration(result, surfaces, keep)
    has_stress = any(s.stress is not None for s in surfaces.values())
    if colour == "stress" and not has_stress:
        raise InputError(f"{results_path}: no body's SID has modal stresses to colour by; reduce with "
                         "`sidprep reduce MESH --stress` and re-run the simulation, or colour by displacement")
    vm_max = stress_envelope_mpa(rf, results_path, [n for n, s in surfaces.items() if s.stress is not None])
    traces, clouds, umax, bodies = [], [], 0.0, []
    for name, s in surfaces.items():
        b = result.bodies[name]
        x, u = surface_motion(s, b.position[keep], b.rotation[keep], b.q[keep], scale)
        clouds.append(x.reshape(-1, 3))
        umag = np.linalg.norm(u, axis=2)
        umax = max(umax, float(umag.max()))
        bodies.append(body_data(s, b, keep))
        t = s.triangles
        traces.append(go.Mesh3d(x=x[0, :, 0], y=x[0, :, 1], z=x[0, :, 2], i=t[:, 0], j=t[:, 1], k=t[:, 2],
                                intensity=umag[0], name=name, coloraxis="coloraxis", hoverinfo="name"))
    names = sorted(result.markers)
    hinges = joint_markers(result)
    positions = np.stack([result.markers[n][keep] for n in names], axis=1) if names else np.zeros((len(keep), 0, 3))
    traces.append(go.Scatter3d(x=positions[0, :, 0], y=positions[0, :, 1], z=positions[0, :, 2], mode="markers",
                               hovertext=names, hoverinfo="text",
                               marker=dict(size=[7 if n in hinges else 3 for n in names],
                                           symbol=["diamond" if n in hinges else "circle" for n in names],
                                           color=["black" if n in hinges else "grey" for n in names]),
                               name="markers"))
    cloud = np.vstack(clouds + [positions.reshape(-1, 3), np.zeros((1, 3))])
    size = float(np.linalg.norm(np.ptp(cloud, axis=0))) or 1.0
    corners, triangles = ground_plane(cloud, gravity_direction(rf.scene.get("text", "")), size)
    traces.append(go.Mesh3d(x=corners[:, 0], y=corners[:, 1], z=corners[:, 2], i=triangles[:, 0],
                            j=triangles[:, 1], k=triangles[:, 2], color="lightgrey", opacity=0.35, name="ground",
                            hoverinfo="name"))
    traces += frame_axes(GROUND_AXES * size, "ground")
    cloud = np.vstack([cloud, corners])
    lo, hi = cloud.min(axis=0), cloud.max(axis=0)
    pad = 0.05 * float(np.max(hi - lo) or 1.0)
    ranges = [[float(a - pad), float(b + pad)] for a, b in zip(lo, hi)]
    spans = np.array([r[1] - r[0] for r in ranges])
    titles = axis_titles("m")
    fig = go.Figure(traces)
    fig.update_layout(scene=dict(**{f"{a}axis": dict(range=ranges[k], **titles[f"{a}axis"]) for k, a in enumerate("xyz")},
                                 aspectmode="manual", aspectratio=dict(zip("xyz", (spans / spans.max()).tolist()))),
                      coloraxis=dict(colorscale="Viridis", cmin=0, cmax=umax or 1.0, colorbar=colorbar("|u| (m)")),
                      margin=dict(l=0, r=0, t=0, b=0), showlegend=False)
    data = js_object({"t": json.dumps(result.t[keep].tolist()), "exaggeration": json.dumps(scale),
                      "u_max": json.dumps(umax or 1.0), "vm_max": json.dumps(vm_max or 1.0),
                      "bodies": "[" + ",".join(bodies) + "]",
                      "markers": js_object({"names": json.dumps(names), "P": js_array(positions)})})
    controls = (f"<button id='play'>play</button> t = <span id='clock'></span> s "
                f"<input id='time' type='range' min='0' max='{len(keep) - 1}' step='1' value='0' style='width:40%'> "
                "<select id='deform'><option value='real'>real deformation</option>"
                f"<option value='exaggerated'>exaggerated x {scale:.3g}</option></select> colour "
                f"<select id='colour'{'' if has_stress else ' disabled'}><option value='displacement'>displacement |u|</option>"
                f"<option value='stress'{' selected' if colour == 'stress' else ''}>von Mises stress</option></select>")
    rows = [("results", html.escape(results_path.name)), ("scene", html.escape(rf.scene.get("path", ""))),
            ("time", f"{result.t[0]:.4g} .. {result.t[-1]:.4g} s, {len(result.t)} samples ({len(keep)} shown)"),
            ("max |u|", f"{umax:.3g} m (shown samples)")]
    if has_stress:
        rows.append(("max von Mises", f"{vm_max:.4g} MPa (all {len(result.t)} samples, as sidprep stress)"))
    rows += [(name, html.escape(s.source)) for name, s in surfaces.items()]
    return write_page(out_path, results_path.name, fig, controls, table(rows), _MECHANISM_SCRIPT, data)
