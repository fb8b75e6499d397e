"""The compiled core's generalised-alpha loop (sidprep/solver/core/genalpha.pyx, driven by
integrators/genalpha.py's GeneralizedAlpha) against the numba ga_loop it replaces: whole runs of
example scenes give the same samples, outputs, step counts and events.

The kernels of genalpha.pyx are C functions of the loop (ga_state, newton_residual, dense_state,
state_flows, iteration_matrix, local_error, approach_bound, contact_factor, contact_accepted,
deflection_check): every one of them runs in these runs (the contact scene the contact kernels,
the error-controlled run local_error, the output rates dense_state), so a whole run that matches
step for step checks each of them."""

import shutil
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from sidprep.solver.core.outputs import PostConstants as CorePostConstants
from sidprep.solver.core.records import Layout
from sidprep.solver.integrators import genalpha as numba_genalpha
from sidprep.solver.integrators.base import (LARGE_DEFORMATION, MAX_STEPS, NEWTON_FAILED, Problem,
                                             Samples, Stepper, new_status)
from sidprep.solver.integrators.initial import body_sizes
from sidprep.solver.integrators.outputs import PostConstants, PostSetup, SampledOutputs
from sidprep.solver.integrators.se3 import body_frame_free
from sidprep.solver.integrators.settings import SolverSettings
from sidprep.solver.postprocess import post_setup
from sidprep.solver.run import Run
from sidprep.solver.scene import load_scene

from test_impacts import ball_on_a_stop

#: a whole run against the numba loop, per field relative to its largest entry (the constraint
#: error cerr relative to the system length): measured 0 (bit-equal) on every case but the
#: error-controlled one, where one rounding differs at its fourth step (a last bit of the state)
#: and grows to 1.5e-11 (Q) over its 37 steps
RUN_RTOL = 1e-9
#: output samples per call of the loop in the resumed case (the loop stops and is called again)
SMALL_CHUNK = 7

ROOT = Path(__file__).resolve().parents[2]
#: examples whose flexible bodies are reduced by the test (``reduced_examples``): the files copied
#: and the reductions, (mesh, SID file, options) each, as the scenes' make lines without stress or output files
REDUCED = {
    "engine": (("scene.toml", "gas_force.py", "crank.obj", "piston.obj"),
               (("data/meshes/piston_rod.msh", "piston_rod.sid.h5", ()),)),
    "slider_crank": (("scene.toml", "crank.msh"),
                     (("examples/slider_crank/crank.msh", "crank.sid.h5", ("--cutoff-factor", "10")),
                      ("data/meshes/bar.msh", "conrod.sid.h5", ("--cutoff-factor", "10")))),
}
#: (scene or system, t_end s, overrides): each example scene with method genalpha for a short
#: stretch (seconds of CPU), one error-controlled run, and the Hertz stop of tests/test_impacts.py
#: through its first impact (the contact kernels)
CASES = {
    "flexible_pendulum": ("examples/flexible_pendulum/scene.toml", 0.2, {}),
    "flexible_pendulum_rtol": ("examples/flexible_pendulum/scene.toml", 0.2, {"rtol": 1e-5}),
    "flexible_pendulum_dense": ("examples/flexible_pendulum/scene.toml", 0.2, {"output_dt": 7e-4}),
    "slider_crank": ("slider_crank", 0.05, {}),
    "engine": ("engine", 0.01, {}),
    "engine_rigid": ("examples/engine/scene_rigid.toml", 0.02, {}),
    "beam_slider_crank": ("examples/beam_slider_crank/scene.toml", 0.5, {}),
    "beam_buckling": ("examples/beam_buckling/scene.toml", 0.5, {}),
    "moving_mass": ("examples/moving_mass/scene.toml", 0.5, {}),
    "hertz_stop": (None, 0.16, {"method": "genalpha", "h": 1e-3, "output_dt": 1e-4}),
    "resumed": ("examples/flexible_pendulum/scene.toml", 0.2, {"output_dt": 7e-4}),
}


def numba_layout(L):
    """The numba kernels' Layout namedtuple of L (a core Layout record or that namedtuple)."""
    return L.arrays if isinstance(L, Layout) else L


def numba_post(post):
    """The numba PostSetup of ``post`` (of core records or of numba namedtuples)."""
    c = post.c
    if isinstance(c, CorePostConstants):
        c = PostConstants(*(np.asarray(getattr(c, f)) for f in PostConstants._fields[:-1]), int(c.stiffening))
    return PostSetup(numba_layout(post.L), numba_layout(post.L0), c)


class NumbaGeneralizedAlpha(Stepper):
    """The reference: the generalised-alpha stepper on the numba ga_loop."""

    name = "genalpha"

    def __init__(self, problem, state, settings):
        super().__init__(problem, state, settings)
        am, af, gamma, beta = numba_genalpha.genalpha_parameters(settings.rho_inf)
        prm = np.array([am, af, gamma, beta, beta * (1 - af) / (1 - am)])
        L = numba_layout(problem.L)
        self.L, self.post = L, numba_post(problem.post)
        self.constants = numba_genalpha.GaConstants(
            prm, body_frame_free(problem.free, L.uoff), problem.kept, problem.weights, float(problem.length),
            settings.deformation_limit * problem.sizes, float(settings.newton_tol), float(settings.tolerance or 0.0),
            float(settings.atol), float(settings.h), float(settings.output_dt or 0.0))
        self.a = np.full(state.u.size, np.nan)
        self.h = settings.h
        self.next_index = 1
        self.workspace = numba_genalpha.ga_workspace(L, self.constants)
        self.status_record = new_status(settings.max_steps)
        self.outputs = []

    def advance(self, t_stop):
        p, s = self.problem, self.state
        x = numba_genalpha.GaState(s.R, s.A, s.Q, s.u, s.ud, self.a, s.lam)
        x, s.t, self.h, self.next_index, buf, out = numba_genalpha.ga_loop(
            self.L, self.constants, self.workspace, x, s.t, t_stop, self.h, self.next_index, p.refs,
            self.status_record, numba_genalpha.CHUNK, self.post)
        self.outputs.append(out)
        s.R, s.A, s.Q, s.u, s.ud, self.a, s.lam = x
        record = self.status_record[0]
        code = int(record["code"])
        if code in (MAX_STEPS, LARGE_DEFORMATION, NEWTON_FAILED):
            self.status, self.message = "failed", f"code {code}"
        elif s.t >= p.t_end - 1e-12 * max(1.0, p.t_end):
            self.status = "finished"
        for key in ("steps", "rejected", "newton_iterations", "jacobians", "h_min", "h_max"):
            self.stats[key] = float(record[key]) if key.startswith("h_") else int(record[key])
        return Samples(*buf)


def reduce_example(name: str, folder: Path) -> Path:
    """The scene of the REDUCED example ``name`` in ``folder``, its bodies reduced there."""
    files, reductions = REDUCED[name]
    for file in files:
        shutil.copy(ROOT / "examples" / name / file, folder / file)
    for mesh, sid, options in reductions:
        subprocess.run([sys.executable, "-m", "sidprep.cli.main", "reduce", str(ROOT / mesh), *options, "-o", sid,
                        "-q", "--no-sid-fem", "--no-obj"], cwd=folder, check=True)
    return folder / "scene.toml"


@pytest.fixture(scope="module")
def reduced_examples(tmp_path_factory) -> dict:
    """{REDUCED example: its scene file in a temporary folder}, reduced on first use."""
    class Scenes(dict):
        def __missing__(self, name):
            self[name] = reduce_example(name, tmp_path_factory.mktemp(name))
            return self[name]
    return Scenes()


def case_run(case, scenes: dict) -> Run:
    """The Run of a CASES entry (scenes: reduced_examples)."""
    source, t_end, overrides = CASES[case]
    if source is None:
        system, settings = ball_on_a_stop(), SolverSettings(**overrides)
    else:
        scene = load_scene(scenes[source] if source in REDUCED else ROOT / source)
        system, settings = scene.system, replace(scene.settings, **overrides)
    return Run(system, t_end, settings)


def drive(run: Run, stepper_class):
    """(Samples, SampledOutputs, stats, status, system length m, calls of the loop) of ``run``
    integrated by stepper_class, as Run.execute drives it."""
    state = run.consistent_start()
    problem = Problem(run.L, run.free, run.kept, run.weights, run.length, run.refs, run.t_end,
                      body_sizes(run.system, run.terms), post_setup(run))
    stepper = stepper_class(problem, state.copy(), run.settings)
    chunks = []
    while stepper.status == "running":
        chunks.append(stepper.advance(run.t_end))
    samples = Samples(*(np.concatenate([getattr(c, f) for c in chunks]) for f in Samples.__dataclass_fields__))
    outputs = SampledOutputs(*(np.concatenate([getattr(o, f) for o in stepper.outputs])
                               for f in SampledOutputs._fields))
    return samples, outputs, stepper.stats, stepper.status, run.length, len(chunks)


def relative_difference(x, ref) -> float:
    """max |x - ref| / max |ref| (NaN where both are NaN counts as equal)."""
    x, ref = np.asarray(x, float), np.asarray(ref, float)
    assert x.shape == ref.shape
    both = np.isnan(x) & np.isnan(ref)
    assert np.array_equal(np.isnan(x), np.isnan(ref))
    diff = np.where(both, 0.0, np.abs(x - ref))
    return float(np.max(diff, initial=0.0) / max(np.max(np.where(both, 0.0, np.abs(ref)), initial=0.0), 1e-300))


@pytest.mark.parametrize("case", list(CASES))
def test_whole_runs_match_the_numba_loop(case, reduced_examples, monkeypatch):
    """Every sample's state, work and outputs to RUN_RTOL; the same steps, rejections, Newton
    iterations and Jacobians (the events: step cuts, contact crossings) and the same status
    (the resumed case: both loops called every SMALL_CHUNK samples)."""
    if case == "resumed":
        monkeypatch.setattr(numba_genalpha, "CHUNK", SMALL_CHUNK)
    core = drive(case_run(case, reduced_examples), numba_genalpha.GeneralizedAlpha)
    ref = drive(case_run(case, reduced_examples), NumbaGeneralizedAlpha)
    assert core[3] == ref[3] and core[5] == ref[5] and (core[5] > 1) == (case == "resumed")
    for key in ("steps", "rejected", "newton_iterations", "jacobians"):
        assert core[2][key] == ref[2][key], key
    for key in ("h_min", "h_max"):
        assert core[2][key] == pytest.approx(ref[2][key], rel=RUN_RTOL)
    for field in Samples.__dataclass_fields__:
        assert relative_difference(getattr(core[0], field), getattr(ref[0], field)) <= RUN_RTOL, field
    for field in SampledOutputs._fields:
        if field == "cerr":
            assert np.max(np.abs(core[1].cerr - ref[1].cerr)) <= RUN_RTOL * ref[4]
        else:
            assert relative_difference(getattr(core[1], field), getattr(ref[1], field)) <= RUN_RTOL, field
