"""The compiled core's explicit integrators, sample outputs and out-of-plane reactions
(sidprep/solver/core/explicit.pyx, outputs.pyx, planar.pyx) against the numba kernels they replace
(sidprep/solver/integrators/explicit.py, outputs.py, planar.py): the same results to round-off."""

import numpy as np
import pytest

from sidprep.solver.core import explicit as core_explicit
from sidprep.solver.core import outputs as core_outputs
from sidprep.solver.core import planar as core_planar
from sidprep.solver.core.records import layout_record
from sidprep.solver.equations import assemble as numba_assemble
from sidprep.solver.integrators import explicit as numba_explicit
from sidprep.solver.integrators import outputs as numba_outputs
from sidprep.solver.integrators import planar as numba_planar
from sidprep.solver.integrators.base import SampleBuffers
from sidprep.solver.integrators.outputs import PostSetup, SampledOutputs
from sidprep.solver.postprocess import post_setup

import test_assemble
from test_assemble import ROOT, random_state, scene_run

#: the example folders whose SID files `sidprep reduce` makes (test_assemble's fixture)
reduced = test_assemble.reduced

#: kernel against kernel, the same arithmetic in the same order: relative to the largest entry
KERNEL_RTOL = 1e-12


def rank_deficient(rng, no, nd, rank, dependent_on):
    """(no, nd) of the given rank: rows >= rank are combinations of the rows dependent_on."""
    u, _ = np.linalg.qr(rng.standard_normal((nd, rank)))
    head = rng.uniform(0.4, 2.0, (rank, 1)) * u.T
    tail = rng.standard_normal((no - rank, len(dependent_on))) @ head[dependent_on] / len(dependent_on)
    return np.ascontiguousarray(np.vstack([head, tail]))


def core_independent_equations(a):
    rows = np.zeros(min(a.shape), np.int64)
    return rows[:core_planar.independent_equations(np.ascontiguousarray(a), rows)]


def core_minimum_norm_solution(a, load, rows):
    no, nd = a.shape
    x = np.zeros(nd)
    core_planar.minimum_norm_solution(np.ascontiguousarray(a), load, rows, np.zeros((no, no)), np.zeros(no), x)
    return x


def close(x, ref, rtol=KERNEL_RTOL):
    return np.max(np.abs(x - ref), initial=0.0) <= rtol * max(np.max(np.abs(ref), initial=0.0), 1e-300)


@pytest.mark.parametrize("no, nd, rank", [(9, 9, 9), (9, 12, 9), (9, 12, 6), (12, 9, 9), (12, 9, 5), (3, 2, 1)])
def test_out_of_plane_solution_matches_numba(no, nd, rank):
    """independent_equations picks the same rows; minimum_norm_solution gives the same reactions
    on later matrices of the pattern, and where the rank fell or grew (its lstsq fallback)."""
    rng = np.random.default_rng(no * 100 + nd * 10 + rank)
    deps = list(range(min(rank, 3)))
    first = rank_deficient(rng, no, nd, rank, deps)
    rows = core_independent_equations(first)
    np.testing.assert_array_equal(rows, numba_planar.independent_equations(first))
    others = [rank_deficient(rng, no, nd, rank, deps) for _ in range(3)]
    if rank > 1:
        others.append(rank_deficient(rng, no, nd, rank - 1, deps[:1]))
    if rank < min(no, nd):
        others.append(rank_deficient(rng, no, nd, rank + 1, deps[:1]))
    for a in others:
        load = a @ rng.standard_normal(nd)
        ref = numba_planar.minimum_norm_solution(a, load, rows)
        assert close(core_minimum_norm_solution(a, load, rows), ref)
        x = np.zeros(nd)
        core_planar.lstsq(a, load, x)
        assert close(x, numba_planar.lstsq(a, load))
        assert core_planar.solves(a, ref, load) == numba_planar.solves(a, ref, load)


#: a whole run against the numba kernels: the same arithmetic in the same order except LAPACK's
#: and libm's builds, so the runs stay equal to round-off accumulated over the steps; per field,
#: relative to its largest entry
RUN_RTOL = 1e-9
#: samples per random-state comparison of sample_outputs
SAMPLES = 4
#: the scenes of the sample-output comparison (random states): friction and node markers
#: (slider_crank), a planar run's out-of-plane reactions (engine/scene_rigid), the stiffening work
#: (moving_mass, helicopter_rotor, beam_buckling; load-stiffened markers in the latter two)
OUTPUT_SCENES = ["flexible_pendulum/scene", "slider_crank/scene", "engine/scene", "engine/scene_rigid",
                 "moving_mass/scene", "spinning_body/scene", "helicopter_rotor/scene", "beam_buckling/scene"]


def started_run(name, reduced):
    """The Run of examples/<name>.toml after its consistent start (planar reduction included),
    with its start State."""
    run = scene_run(ROOT / "examples" / f"{name}.toml", reduced)
    return run, run.consistent_start()


def numba_post(post):
    """The numba kernels' PostSetup of the core's (postprocess.post_setup): namedtuples of arrays."""
    c = post.c
    c = numba_outputs.PostConstants(*(np.asarray(getattr(c, f)) for f in numba_outputs.PostConstants._fields[:-1]),
                                    int(c.stiffening))
    return PostSetup(post.L.arrays, post.L0.arrays, c)


def random_samples(run, state, rng, count):
    """SampleBuffers of ``count`` random states (test_assemble.random_state), random accelerations
    and kept multipliers."""
    rows = [random_state(run, rng) for _ in range(count)]
    stack = [np.array([r[i] for r in rows]) for i in range(7)]
    R, A, Q, u, t, _, refs = stack
    return SampleBuffers(t, R, A, Q, u, rng.normal(0.0, 1.0, u.shape), rng.normal(0.0, 10.0, (count, state.lam.size)),
                         refs, np.zeros((count, 3)))


def relative_difference(x, ref) -> float:
    """max |x - ref| / max |ref| (NaN where both are NaN counts as equal)."""
    x, ref = np.asarray(x, float), np.asarray(ref, float)
    assert x.shape == ref.shape
    both = np.isnan(x) & np.isnan(ref)
    assert np.array_equal(np.isnan(x), np.isnan(ref))
    diff = np.where(both, 0.0, np.abs(x - ref))
    return float(np.max(diff, initial=0.0) / max(np.max(np.where(both, 0.0, np.abs(ref)), initial=0.0), 1e-300))


@pytest.mark.parametrize("name", OUTPUT_SCENES)
def test_sample_outputs_match_numba(name, reduced):
    """Every SampledOutputs field of the compiled sample_outputs at random states."""
    run, state = started_run(name, reduced)
    post = post_setup(run)
    s = random_samples(run, state, np.random.default_rng(5), SAMPLES)
    L, L0, c = numba_post(post)
    ref = numba_outputs.sample_outputs(L, L0, s, c)
    out = core_outputs.sample_outputs(post.L, post.L0, s, post.c)
    for field in SampledOutputs._fields:
        assert relative_difference(getattr(out, field), getattr(ref, field)) <= KERNEL_RTOL, field


#: whole runs {case: (scene, t_end s, h s)}: h within RK4's stability limit (the first step of
#: the adaptive methods); each a few hundred steps
RUNS = {
    "flexible_pendulum": ("flexible_pendulum/scene", 0.005, 1e-5),
    "slider_crank": ("slider_crank/scene", 0.001, 4e-6),
    "engine": ("engine/scene", 0.002, 1e-5),
    "moving_mass": ("moving_mass/scene", 0.1, 1e-4),
    "spinning_body": ("spinning_body/scene", 0.05, 1e-4),
}
#: output samples per call of the RK4 loop in these runs (small: the loop resumes several times)
RUN_CHUNK = 64
#: the adaptive methods' tolerances in these runs (relative, absolute)
ADAPTIVE_RTOL, ADAPTIVE_ATOL = 1e-6, 1e-9


class Kernels:
    """One side of a run's comparison: its explicit kernels on the run's problem (a run's
    RhsParams, numba's tuple or the core's record, each with its own angle references)."""

    def __init__(self, run, state, core):
        self.core, self.L = core, run.L
        self.refs = run.refs.copy()
        post = post_setup(run)
        baumgarte = float(run.settings.baumgarte)
        if core:
            self.params = core_explicit.rhs_params(layout_record(run.L), run.free, run.kept, self.refs, baumgarte,
                                                   state.lam)
            self.post = post
        else:
            self.params = (run.L, run.free, run.kept, self.refs, baumgarte, state.lam.copy(),
                           numba_assemble.evaluation_arrays(run.L))
            self.post = numba_post(post)

    def rhs(self, t, y):
        if not self.core:
            return numba_explicit.index1_rhs(t, y, self.params)
        ydot = np.empty_like(y)
        core_explicit.index1_rhs(t, np.ascontiguousarray(y), self.params, ydot)
        return ydot

    def sample(self, t, y):
        """(R, A, Q, u, ud, lam, work) at an accepted state; the angle references follow it."""
        if not self.core:
            return numba_explicit.sample(self.L, t, y, self.params, self.refs)
        p = self.params
        core_explicit.sample(t, np.ascontiguousarray(y), p)
        return tuple(np.array(a) for a in (p.R, p.A, p.Q, p.u, p.ud, p.lam)) + (y[-3:].copy(),)

    def rk4_loop(self, *args):
        loop = core_explicit.rk4_loop if self.core else numba_explicit.rk4_loop
        return loop(*args[:6], self.params, *args[6:], self.post)

    def outputs(self, s):
        outputs = core_outputs.sample_outputs if self.core else numba_outputs.sample_outputs
        return outputs(self.post.L, self.post.L0, s, self.post.c)


def start_rows(state, refs, rows):
    """SampleBuffers of ``rows`` (0 or 1) copies of the start."""
    s = state
    return SampleBuffers(np.full(rows, s.t), np.repeat(s.R[None], rows, 0), np.repeat(s.A[None], rows, 0),
                         np.repeat(s.Q[None], rows, 0), np.repeat(s.u[None], rows, 0), np.repeat(s.ud[None], rows, 0),
                         np.repeat(s.lam[None], rows, 0), np.repeat(refs[None], rows, 0), np.zeros((rows, 3)))


def rk4_run(run, state, kernels, h, out_dt):
    """(SampleBuffers, SampledOutputs, steps) of RK4 from the start to run.t_end, the loop called
    again whenever RUN_CHUNK samples are full (as explicit.RungeKutta4 drives it)."""
    y = numba_explicit.pack(run.L, state.R, state.A, state.Q, state.u, np.zeros(3))
    steps = np.array([0, 10 ** 9], np.int64)
    t, next_index, chunks, outs = 0.0, 1, [], []
    while t < run.t_end - 1e-12 * max(1.0, run.t_end) and np.all(np.isfinite(y)):
        first = start_rows(state, kernels.refs, 0 if chunks else 1)
        t, y, next_index, buf, out = kernels.rk4_loop(t, y, run.t_end, h, out_dt, next_index, RUN_CHUNK, steps, first)
        chunks.append(buf)
        outs.append(out)
    samples = SampleBuffers(*(np.concatenate([getattr(c, f) for c in chunks]) for f in SampleBuffers._fields))
    outputs = SampledOutputs(*(np.concatenate([getattr(o, f) for o in outs]) for f in SampledOutputs._fields))
    return samples, outputs, int(steps[0])


def adaptive_run(run, state, kernels, method, h):
    """(SampleBuffers, SampledOutputs, steps) of scipy's RK45 / DOP853 on the kernels' rhs, a
    sample after every step (as adaptive.ScipyRungeKutta steps a scene without stops or tables)."""
    from scipy.integrate import DOP853, RK45

    y = numba_explicit.pack(run.L, state.R, state.A, state.Q, state.u, np.zeros(3))
    solver = {"rk45": RK45, "dop853": DOP853}[method](kernels.rhs, 0.0, y, run.t_end, rtol=ADAPTIVE_RTOL,
                                                      atol=ADAPTIVE_ATOL, first_step=h)
    rows = [(0.0, (state.R, state.A, state.Q, state.u, state.ud, state.lam, np.zeros(3)), kernels.refs.copy())]
    while solver.status == "running":
        solver.step()
        rows.append((solver.t, kernels.sample(solver.t, solver.y), kernels.refs.copy()))
    stack = [np.array([r[1][k] for r in rows]) for k in range(7)]
    samples = SampleBuffers(np.array([r[0] for r in rows]), *stack[:6], np.array([r[2] for r in rows]), stack[6])
    return samples, kernels.outputs(samples), len(rows) - 1


def assert_same_runs(run, ref):
    """Two (SampleBuffers, SampledOutputs, steps): the same steps, every sample's state, work and
    outputs to RUN_RTOL."""
    (s, out, steps), (s_ref, out_ref, steps_ref) = run, ref
    assert steps == steps_ref
    for field in SampleBuffers._fields:
        assert relative_difference(getattr(s, field), getattr(s_ref, field)) <= RUN_RTOL, field
    for field in SampledOutputs._fields:
        assert relative_difference(getattr(out, field), getattr(out_ref, field)) <= RUN_RTOL, field


@pytest.mark.parametrize("method", ["rk4", "rk45", "dop853"])
@pytest.mark.parametrize("case", list(RUNS))
def test_whole_runs_match_numba(case, method, reduced):
    """Every sample's state, work and outputs to RUN_RTOL, the same number of steps: RK4 through
    its compiled loop (samples at out_dt = 2 h, resumed every RUN_CHUNK samples), RK45 and DOP853
    through scipy on the compiled right-hand side and samples."""
    name, t_end, h = RUNS[case]
    results = []
    for core in (True, False):
        run, state = started_run(name, reduced)
        run.t_end = t_end
        kernels = Kernels(run, state, core)
        if method == "rk4":
            results.append(rk4_run(run, state, kernels, h, 2.0 * h))
        else:
            results.append(adaptive_run(run, state, kernels, method, h))
    assert_same_runs(*results)
    assert results[0][0].t[-1] == pytest.approx(t_end) and np.all(np.isfinite(results[0][0].u))


def test_rk4_beyond_its_stability_limit_stops_like_numba(reduced):
    """slider_crank's crank modes at h = 1e-5 s are beyond RK4's limit: both loops stop at the same
    last finite state after the same steps, with the same samples."""
    results = []
    for core in (True, False):
        run, state = started_run("slider_crank/scene", reduced)
        run.t_end = 0.002
        results.append(rk4_run(run, state, Kernels(run, state, core), 1e-5, 2e-5))
    assert_same_runs(*results)
    assert results[0][0].t[-1] < 0.002
