"""sidprep converge: the error each rung's Richardson estimate claims, checked against an
independent reference run 16x finer than the recommended setting, on four kinds of scene."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from sidprep.solver.converge import ConvergeOptions, converge
from sidprep.solver.results import signal
from sidprep.solver.scene import load_scene, simulate

from sidprep.errors import InputError

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
#: the reference run's step is this many times finer than the recommended one
REFERENCE_REFINEMENT = 16
#: the estimated error of the recommended setting is within this factor of the measured one
HONESTY_FACTOR = 3.0

#: a stiff body: a steel beam 0.3 m x 50 mm x 50 mm (free-free bending modes 3-16 kHz) swinging as
#: a pendulum (about 1 Hz)
STIFF_SCENE = """
[scene]
title = "stiff beam pendulum"
gravity = [0.0, 0.0, -9.81]

[solver]
t_end = 0.1
step = 1e-3

[output]
rate = 500
signals = ["hinge.coordinate", "tip.position.z", "energy.total"]

[bodies.rod]
type = "beam"
length = 0.3
section = "rectangle:0.05,0.05"
material = "steel"
bc = "free-free"
modes = "xz:1-3"
damping = 0.0

[markers.pivot]
body = "ground"
z_axis = [0.0, 1.0, 0.0]

[markers.root]
body = "rod"
node = 1
z_axis = [0.0, 1.0, 0.0]

[markers.tip]
body = "rod"
node = 2

[joints.hinge]
type = "revolute"
markers = ["pivot", "root"]
"""


@pytest.fixture(scope="module")
def stiff_scene(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("stiff") / "scene.toml"
    path.write_text(STIFF_SCENE)
    return path


#: scene, signals, window end (s), h0 (s), tolerance, also run the other effects choice
CASES = {
    "flexible pendulum": ("flexible_pendulum/scene.toml", ("hinge.coordinate", "tip.position.z"), 0.05, 5e-5, 1e-4,
                          False),
    "closed loop, flexible links": ("beam_slider_crank/scene.toml", ("slider_joint.coordinate", "conrod.q.1"), 0.2,
                                    2e-3, 1e-4, True),
    "spinning flexible body": ("spinning_body/scene.toml", ("bar.omega.x", "bar.omega.y"), 0.2, 1e-3, 1e-5, False),
    "stiff body": (None, ("hinge.coordinate", "tip.position.z"), 0.1, 5e-4, 1e-4, False),
}


def measured_error(path, setting, t_end: float, signals) -> float:
    """max over signals of max |x - x_ref| / range(x_ref), x_ref: the same method and rho_inf at
    a step REFERENCE_REFINEMENT times finer (the scene's output samples)."""
    scene = load_scene(path)
    kw = {"method": setting.method, "rho_inf": setting.rho_inf, "output_dt": scene.settings.output_dt, "t_end": t_end}
    run = simulate(scene, h=setting.h, **kw)
    ref = simulate(scene, h=setting.h / REFERENCE_REFINEMENT, **kw)
    return max(np.max(np.abs(signal(run, n)[0] - signal(ref, n)[0])) / np.ptp(signal(ref, n)[0]) for n in signals)


@pytest.mark.parametrize("case", CASES)
def test_the_recommended_setting_meets_the_tolerance_and_its_estimate_is_honest(case, stiff_scene):
    scene, signals, t_end, step, tol, effects = CASES[case]
    path = stiff_scene if scene is None else EXAMPLES / scene
    report = converge(path, ConvergeOptions(signals=signals, tol=tol, window=(0.0, t_end), methods=("genalpha",),
                                            step=step, effects=effects))
    rec = report.recommendation()
    measured = measured_error(path, rec.setting, t_end, signals)
    assert measured <= tol
    assert measured / HONESTY_FACTOR <= rec.estimated_error <= HONESTY_FACTOR * measured
    assert rec.cpu_s == min(r.cpu_s for r in report.runs if r.estimated_error <= tol and r.setting.effects == "auto")
    if effects:
        assert report.effects_change is not None and 0 <= report.effects_change < tol


def test_cli_json_plot_and_pool(tmp_path):
    """The command on a local pool of 2 processes: JSON with runs and recommended, the plot, and
    each process's warm-up booked apart from the runs' own CPU-s."""
    plot = tmp_path / "pareto.png"
    r = subprocess.run([sys.executable, "-m", "sidprep.cli.main", "converge",
                        str(EXAMPLES / "beam_slider_crank/scene.toml"), "--window", "0", "0.1", "--method", "genalpha",
                        "--signal", "slider_joint.coordinate", "--levels", "3", "--no-effects", "--workers", "2",
                        "--json", "-o", str(plot), "-q"], capture_output=True, text=True, check=False)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert len(out["runs"]) == 6 and plot.stat().st_size > 0
    rec = out["recommended"]
    assert {"method", "step", "rho_inf", "rtol", "cpu_s", "estimated_error"} <= set(rec)
    assert rec["estimated_error"] <= 1e-3 and "step = " in rec["toml"]
    runs = sorted(run["cpu_s"] for run in out["runs"])
    assert out["warm_up_cpu_s"] > 0 and runs[0] > 0 and np.isfinite(runs[-1])


def bad(argv) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "sidprep.cli.main", "converge", *argv, "-q", "--workers", "1"],
                          capture_output=True, text=True, check=False)


def test_a_signal_that_does_not_exist():
    r = bad([str(EXAMPLES / "beam_slider_crank/scene.toml"), "--signal", "slider_joint.nonsense"])
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "slider_joint.nonsense" in r.stderr


def test_a_tolerance_no_setting_meets():
    with pytest.raises(InputError, match="no setting meets --tol 1e-12.*closest: genalpha"):
        converge(EXAMPLES / "beam_slider_crank/scene.toml",
                 ConvergeOptions(signals=("slider_joint.coordinate",), tol=1e-12, window=(0.0, 0.05),
                                 methods=("genalpha",), levels=3, effects=False)).recommendation()


def test_a_scene_that_fails_at_every_setting(tmp_path):
    text = (EXAMPLES / "flexible_pendulum/scene.toml").read_text().replace("rho_inf = 0.9", "rho_inf = 0.9\n"
                                                                          "deformation_limit = 1e-12")
    scene = tmp_path / "scene.toml"
    scene.write_text(text.replace('sid = "bar.sid.h5"', f'sid = "{EXAMPLES / "flexible_pendulum/bar.sid.h5"}"'))
    with pytest.raises(InputError, match="tried 6 settings, 6 failed; e.g. genalpha"):
        converge(scene, ConvergeOptions(signals=("hinge.coordinate",), window=(0.0, 0.02), methods=("genalpha",),
                                        levels=3, effects=False))


#: the FEMBS promise: static deflection at the interfaces within 1 % of the full FE model's
STATIC_TOL = 0.01
#: the ladder's cost column against a separate reduction, CPU time measured side by side
COST_TOL = 0.3


def test_fe_ladder_recommends_a_mode_count_meeting_the_static_tolerance_at_the_cost_of_a_reduce():
    """Piston rod: the recommended rung, reduced again on its own, meets 1 % static deflection
    against the full FE solve of the checks, and cost what the ladder's column says."""
    import time

    from sidprep.jobs.fe_ladder import fe_ladder
    from sidprep.jobs.options import ReduceOptions
    from sidprep.jobs.reduce import reduce

    mesh = ROOT / "data/meshes/piston_rod.msh"
    report = fe_ladder(mesh, modes=(4, 8), static_tol=STATIC_TOL)
    rec = report.recommendation()
    assert (rec.modes, rec.frm) == (8, True) and rec.nq == 20      # 4 + FRMs: 5.8 %; no FRMs: 100 %
    cpu0 = time.process_time()
    alone = reduce(mesh, ReduceOptions(modes=rec.modes, frm=rec.frm))
    cpu = time.process_time() - cpu0
    assert alone.checks["static_deflection_max_rel_error"] <= STATIC_TOL
    assert abs(rec.cpu_s / cpu - 1) <= COST_TOL


def test_fe_ladder_on_the_command_line_names_the_closest_when_none_meets(tmp_path):
    r = bad([str(ROOT / "data/meshes/piston_rod.msh"), "--modes-ladder", "2", "--static-tol", "1e-4"])
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "closest: 2 modes + FRMs" in r.stderr
