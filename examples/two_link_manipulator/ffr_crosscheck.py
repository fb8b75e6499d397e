#!/usr/bin/env python3
"""Cross-check: the two-link manipulator in absolute nodal coordinates (sidprep/solver/absolute_nodal/)
against the same links as meshed, reduced flexible bodies in the floating-frame solver.

Each link is a steel strip 1 m x 67.246 mm x 9.4718 mm (E = 210 GPa, nu = 0.3, rho = 7850 kg/m^3:
EI = E b h^3 / 12 = 1.000e3 N m^2 about the thin direction, m = 5.000 kg) meshed with tet10
(data/meshes/make_bar.py) and reduced by `sidprep reduce` (Craig-Bampton on the end-face
masters, free-free eigenmodes + frequency-response modes); the two bodies are joined by revolute
joints about y, gravity along -z, so the paper's X-Y plane is the x-z plane here.  Compared: the
chord angles phi_1, phi_2 - phi_1 (from the joint node positions, both formulations) and beam 2's
tip x and y over t in [0, T].

    python examples/two_link_manipulator/ffr_crosscheck.py [--t-end 1.0] [--work DIR]

prints the refinement table of the README.
"""

from __future__ import annotations

import argparse
import math
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))                                   # the repository's solver package
HERE = Path(__file__).resolve().parent
E, NU, RHO = 210e9, 0.3, 7850.0
EI, MASS, LENGTH = 1.0e3, 5.0, 1.0
#: strip section giving EI and the mass with steel: A = m / (rho L), h = sqrt(12 I / A), b = A / h
AREA = MASS / (RHO * LENGTH)
THICK = math.sqrt(12.0 * EI / E / AREA)
WIDTH = AREA / THICK
#: the strip's axial stiffness E A = 1.34e8 N (the paper's 2500 EI = 2.5e6 N would stretch the
#: absolute-nodal links 50 times more than the meshed ones: ~1e-4 m at the tip)
EA_STRIP = E * AREA
PSI2 = math.radians(15.0)
#: refinement levels: absolute-nodal elements per link (RK4 step from its stability limit),
#: (mesh size m, eigenmodes, FFR generalised-alpha step s)
LEVELS = ((4, (0.02, 2, 2e-4)),
          (8, (0.01, 4, 1e-4)),
          (16, (0.01, 8, 5e-5)),
          (32, (0.005, 8, 5e-5)))
#: comparison windows (s): the first swing, and the whole run (the chaotic double pendulum
#: amplifies every difference after the fast whip of link 2 near t = 0.6 s)
WINDOWS = (0.5, 1.0)


def reduced_strip(size: float, modes: int, work: Path) -> Path:
    """Mesh the strip and reduce it (cached in ``work``); the SID file path."""
    mesh = work / f"strip_{size:g}.msh"
    sid = work / f"strip_{size:g}_m{modes}_stiff.sid.h5"
    if not mesh.exists():
        subprocess.run([sys.executable, str(ROOT / "data" / "meshes" / "make_bar.py"), "--box", str(LENGTH),
                        str(WIDTH), str(THICK), "--size", str(size), "--out", str(mesh)], check=True,
                       stdout=subprocess.DEVNULL)
    if not sid.exists():
        subprocess.run([sys.executable, "-m", "sidprep.cli.main", "reduce", str(mesh), "-o", str(sid), "--interface", "fixed_end",
                        "--interface", "free_end", "--modes", str(modes), "--stiffening", "--damping", "0", "--no-sid-fem", "--no-obj",
                        "--no-check-frequencies", "--E", str(E), "--nu", str(NU), "--rho", str(RHO), "-q"],
                       check=True, cwd=ROOT, stdout=subprocess.DEVNULL)
    return sid


def ffr_scene_text(sid: Path, t_end: float, step: float) -> str:
    """The two links as flexible bodies with revolute joints (x-z plane, hinge axes along y)."""
    c, s = math.cos(PSI2), math.sin(PSI2)
    face = np.array([0.0, WIDTH / 2, THICK / 2])        # centre of the end face x = 0 (the master)
    R = np.array([[c, 0, -s], [0, 1, 0], [s, 0, c]])    # rotation about y by -psi2 (x towards +z)
    p2 = np.array([LENGTH, 0.0, 0.0]) - R @ face
    return f"""
[scene]
gravity = [0.0, 0.0, -9.81]
effects = "all"
[solver]
t_end = {t_end}
method = "genalpha"
step = {step}
rho_inf = 1.0
[bodies.link1]
type = "flexible"
sid = "{sid}"
position = [0.0, {-face[1]}, {-face[2]}]
[bodies.link2]
type = "flexible"
sid = "{sid}"
position = [{p2[0]}, {p2[1]}, {p2[2]}]
rotation = [0.0, {-PSI2}, 0.0]
[markers.pivot]
body = "ground"
z_axis = [0.0, 1.0, 0.0]
[markers.root]
body = "link1"
node_index = 0
z_axis = [0.0, 1.0, 0.0]
[markers.elbow1]
body = "link1"
node_index = 1
z_axis = [0.0, 1.0, 0.0]
[markers.elbow2]
body = "link2"
node_index = 0
z_axis = [0.0, 1.0, 0.0]
[markers.tip]
body = "link2"
node_index = 1
[joints.hinge]
type = "revolute"
markers = ["pivot", "root"]
[joints.elbow]
type = "revolute"
markers = ["elbow1", "elbow2"]
"""


def ffr_signals(sid: Path, t_end: float, step: float, t: np.ndarray, work: Path) -> dict:
    """phi1, phi2 - phi1 (rad), tip x, y (m) of the FFR run at the times ``t``."""
    from sidprep.solver.scene import load_scene, simulate

    path = work / "ffr_scene.toml"
    path.write_text(ffr_scene_text(sid, t_end, step))
    r = simulate(load_scene(path))
    m = {k: np.column_stack([np.interp(t, r.t, r.markers[k][:, i]) for i in (0, 2)])
         for k in ("root", "elbow1", "tip")}
    return _chain_signals(m["root"], m["elbow1"], m["tip"])


def _chain_signals(pin, elbow, tip) -> dict:
    d1, d2 = elbow - pin, tip - elbow
    phi1 = np.unwrap(np.arctan2(d1[:, 1], d1[:, 0]))
    phi2 = np.unwrap(np.arctan2(d2[:, 1], d2[:, 0]))
    return {"phi1": phi1, "phi2 - phi1": phi2 - phi1, "tip x": tip[:, 0], "tip y": tip[:, 1]}


def anc_signals(elements: int, t_end: float, rate: float, EI: float = EI):
    """Times and the same signals of the absolute-nodal model with ``elements`` per link (EA of
    the strip), RK4 at 90 % of its stability limit."""
    from sidprep.solver.absolute_nodal.assembly import assemble
    from sidprep.solver.absolute_nodal.model import AbsoluteNodalModel, Beam, Support
    from sidprep.solver.absolute_nodal.run import RK4_STABILITY, highest_frequency, simulate_absolute_nodal
    from sidprep.solver.integrators.settings import SolverSettings

    beams = (Beam("link1", LENGTH, MASS, EI, EA_STRIP, elements, ("pin", "elbow"), 0.0),
             Beam("link2", LENGTH, MASS, EI, EA_STRIP, elements, ("elbow", "tip"), PSI2))
    model = AbsoluteNodalModel(beams, (Support("pin", "pin"),), gravity=(0.0, -9.81))
    n_out = round(t_end * rate)
    steps = n_out * math.ceil(t_end * highest_frequency(assemble(model)) / (0.9 * RK4_STABILITY) / n_out)
    r = simulate_absolute_nodal(model, t_end, SolverSettings(method="rk4", h=t_end / steps, output_dt=1 / rate))
    return r.t, _chain_signals(*(r.markers[p][:, :2] for p in ("pin", "elbow", "tip")))


def compare(level: int, t_end: float, work: Path) -> dict:
    """{window: {signal: max |ANC - FFR| over [0, window]}} at refinement ``level`` (0-based)."""
    ne, (size, modes, h_ffr) = LEVELS[level]
    t, anc = anc_signals(ne, t_end, rate=200.0)
    ffr = ffr_signals(reduced_strip(size, modes, work), t_end, h_ffr, t, work)
    return {w: {k: float(np.max(np.abs(anc[k] - ffr[k])[t <= w + 1e-9])) for k in anc} for w in WINDOWS if w <= t_end}


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--t-end", type=float, default=1.0)
    p.add_argument("--work", type=Path, default=None, help="folder for meshes and SID files (default: temporary)")
    p.add_argument("--levels", type=int, default=len(LEVELS))
    args = p.parse_args(argv)
    print(f"strip {WIDTH * 1e3:.3f} x {THICK * 1e3:.4f} mm: EI = {E * WIDTH * THICK**3 / 12:.4g} N m^2, "
          f"m = {RHO * AREA * LENGTH:.4g} kg")
    with tempfile.TemporaryDirectory() as tmp:
        work = args.work or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        print("| ANC elements/link | FFR mesh size, eigenmodes, step | window [s] | max diff phi1 [rad] | "
              "phi2-phi1 [rad] | tip x [m] | tip y [m] |")
        print("|---|---|---|---|---|---|---|")
        for level in range(args.levels):
            ne, (size, modes, hf) = LEVELS[level]
            for w, d in compare(level, args.t_end, work).items():
                print(f"| {ne} | {size * 1e3:g} mm, {modes}, {hf:g} s | 0 - {w:g} | {d['phi1']:.2e} | "
                      f"{d['phi2 - phi1']:.2e} | {d['tip x']:.2e} | {d['tip y']:.2e} |", flush=True)


if __name__ == "__main__":
    main()
