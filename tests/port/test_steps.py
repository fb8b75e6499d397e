"""The compiled core's integrator kernels (sidprep/solver/core/steps.pyx, se3.pyx, runge_kutta.pyx)
against the numba kernels they replace (sidprep/solver/integrators/base.py, se3.py,
runge_kutta.py): the same results to round-off, on random inputs and on states of the example
scenes (slider_crank, engine, flexible_pendulum, beam_slider_crank)."""

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sidprep.solver.core import records, steps
from sidprep.solver.core import runge_kutta as core_rk
from sidprep.solver.core import se3 as core_se3
from sidprep.solver.integrators import base
from sidprep.solver.integrators import runge_kutta as numba_rk
from sidprep.solver.integrators import se3 as numba_se3
from sidprep.solver.integrators.initial import independent_rows
from sidprep.solver.run import Run
from sidprep.solver.scene import load_scene

ROOT = Path(__file__).resolve().parents[2]
NO_ROWS = np.zeros(0, np.int64)
#: kernel against kernel, the same arithmetic in the same order (and the same LAPACK dgetrf):
#: the largest difference relative to the largest entry of the numba result
KERNEL_RTOL = 1e-12
#: the example scenes and the `sidprep reduce` arguments of the SID files they read (made in a
#: scratch copy of the example's folder, as their READMEs say)
SCENES = {
    "flexible_pendulum": ("examples/flexible_pendulum/scene.toml", []),
    "engine_rigid": ("examples/engine/scene_rigid.toml", []),
    "engine": ("examples/engine/scene.toml", [[str(ROOT / "data/meshes/piston_rod.msh"), "-o", "piston_rod.sid.h5"]]),
    "beam_slider_crank": ("examples/beam_slider_crank/scene.toml", []),
    "slider_crank": ("examples/slider_crank/scene.toml",
                     [["crank.msh", "--cutoff-factor", "10", "-o", "crank.sid.h5"],
                      [str(ROOT / "data/meshes/bar.msh"), "--cutoff-factor", "10", "-o", "conrod.sid.h5"]]),
}


def numba_evaluate(L, R, A, Q, u, t, lam, refs):
    """The numba Evaluation at a state (base.state_equations without the index-1 solve)."""
    return base.state_equations(L, R, A, Q, u, float(t), lam, refs, NO_ROWS, NO_ROWS, False)[0]


def close(x, ref, rtol=KERNEL_RTOL):
    """|x - ref| <= rtol max |ref| entrywise, NaN where ref is NaN."""
    x, ref = np.asarray(x, float), np.asarray(ref, float)
    assert x.shape == ref.shape
    np.testing.assert_array_equal(np.isnan(x), np.isnan(ref))
    scale = max(np.nanmax(np.abs(ref), initial=0.0), 1e-300)
    return np.nanmax(np.abs(x - ref), initial=0.0) <= rtol * scale


class SceneState:
    """A layout of an example scene (numba namedtuple L, core record Lc) and a generic state of
    it: the initial pose moved by a random increment, random velocities, multipliers, references."""

    def __init__(self, path):
        scene = load_scene(path)
        run = Run(scene.system, scene.t_end, scene.settings)
        self.L, self.Lc = run.L, records.layout_record(run.L)
        R, A, Q, _ = run.initial_positions()
        rng = np.random.default_rng(len(R) * 7 + Q.size)
        self.n, self.m_all = int(self.L.uoff[-1]), base.constraint_rows(self.L)
        self.R, self.A, self.Q = base.advance_pose(self.L, R, A, Q, 0.1 * rng.standard_normal(self.n))
        self.u = rng.standard_normal(self.n)
        self.lam = rng.standard_normal(self.m_all)
        self.refs = 0.1 * rng.standard_normal(len(run.refs))
        self.t = 0.0123
        self.rng = rng
        e = numba_evaluate(self.L, self.R, self.A, self.Q, self.u, self.t, self.lam, self.refs)
        self.free = np.arange(self.n)
        self.kept = np.flatnonzero(independent_rows(e.B))
        self.e = e


@pytest.fixture(scope="module", params=list(SCENES))
def scene(request, tmp_path_factory):
    path, reductions = SCENES[request.param]
    path = ROOT / path
    if reductions:
        folder = tmp_path_factory.mktemp(request.param) / path.parent.name
        shutil.copytree(path.parent, folder)
        for args in reductions:
            done = subprocess.run([sys.executable, "-m", "sidprep.cli.main", "reduce", *args, "-q", "--no-sid-fem"],
                                  cwd=folder, capture_output=True, text=True, check=False)
            assert done.returncode == 0, done.stderr
        path = folder / path.name
    return SceneState(path)


def core_evaluation(Lc, e):
    """A core Evaluation holding the numba Evaluation e's M, f, g, B, B_F, b_t."""
    W = records.evaluation_arrays(Lc)
    for name in ("M", "f", "g", "B", "bt"):
        np.asarray(getattr(W, name))[...] = getattr(e, name)
    if W.kin.stiffened:
        np.asarray(W.BF)[...] = e.BF
    return W


# ---------------------------------------------------------------- linear algebra


@pytest.mark.parametrize("k", [1, 2, 5, 17, 60])
def test_lu_factor_and_solve_match_numba(k):
    """The same LAPACK dgetrf factors and pivots; the same solution, NaN where singular."""
    rng = np.random.default_rng(k)
    a = rng.standard_normal((k, k)) + k * np.eye(k) * rng.uniform(0, 1)
    b = rng.standard_normal(k)
    lu_ref, piv_ref = base.lu_factor(a)
    lu, piv = a.copy(), np.zeros(k, np.intc)
    assert steps.lu_factor(lu, piv) == 0
    np.testing.assert_array_equal(piv, piv_ref)
    assert close(lu, lu_ref)
    x = np.empty(k)
    steps.lu_solve(lu, piv, b, x)
    assert close(x, base.lu_solve(lu_ref, piv_ref, b))
    steps.lu_solve(lu, piv, b, b)  # in place
    np.testing.assert_array_equal(b, x)
    if k > 1:
        a[k - 1] = 0.0  # singular (an exact zero pivot): a NaN solution, as numba's
        lu, piv = a.copy(), np.zeros(k, np.intc)
        assert steps.lu_factor(lu, piv) > 0
        steps.lu_solve(lu, piv, np.ones(k), x)
        assert close(x, base.lu_solve(*base.lu_factor(a), np.ones(k)))
        assert np.isnan(x).any()


@pytest.mark.parametrize("n, nf, m", [(6, 6, 0), (9, 7, 3), (16, 16, 5), (30, 24, 11)])
def test_restrict_and_kkt_solve_match_numba(n, nf, m):
    rng = np.random.default_rng(n + nf + m)
    M = rng.standard_normal((n, n))
    M = M @ M.T + n * np.eye(n)
    f = rng.standard_normal(n)
    B = rng.standard_normal((m + 2, n))
    BF = B + 0.1 * rng.standard_normal(B.shape)
    free = np.sort(rng.choice(n, nf, replace=False)).astype(np.int64)
    kept = np.sort(rng.choice(m + 2, m, replace=False)).astype(np.int64)
    ref = base.restrict(M, f, B, BF, free, kept)
    out = (np.empty((nf, nf)), np.empty(nf), np.empty((m, nf)), np.empty((m, nf)))
    steps.restrict(M, f, B, BF, free, kept, *out)
    for x, r in zip(out, ref):
        np.testing.assert_array_equal(x, r)
    rhs = rng.standard_normal(m)
    x_ref, lam_ref = base.kkt_solve(*ref, rhs)
    z = np.empty(nf + m)
    steps.kkt_solve(*out, rhs, np.empty((nf + m, nf + m)), np.empty(nf + m, np.intc), z)
    assert close(z[:nf], x_ref) and close(z[nf:], lam_ref)


def test_expand_and_multipliers_settled_match_numba():
    rng = np.random.default_rng(3)
    kept = np.array([0, 2, 5], np.int64)
    lam = rng.standard_normal(3)
    out = np.full(7, 9.0)
    steps.expand(lam, kept, out)
    np.testing.assert_array_equal(out, base.expand(lam, kept, np.empty(7)))
    near = lam * (1 + 1e-11)
    cases = [(np.zeros(0), np.zeros(0)), (lam, near), (lam, lam * (1 + 1e-9)), (lam, np.array([np.nan, 1.0, 2.0])),
             (np.array([np.nan, 1.0, 2.0]), lam), (np.zeros(3), np.zeros(3))]
    for a, b in cases:
        assert steps.multipliers_settled(a, b) == base.multipliers_settled(a, b)


# ---------------------------------------------------------------- sample buffers


def test_sample_buffers_match_numba():
    rng = np.random.default_rng(5)
    nb, nq, n, m, nj = 2, 3, 15, 4, 2
    shapes = {"R": (nb, 3), "A": (nb, 3, 3), "Q": (nq,), "u": (n,), "ud": (n,), "lam": (m,), "refs": (nj,), "work": (3,)}
    rows = [{k: rng.standard_normal(s) for k, s in shapes.items()} for _ in range(3)]
    ref = base.sample_buffers(5, rows[0]["R"], rows[0]["Q"], rows[0]["u"], rows[0]["lam"], rows[0]["refs"])
    buf = steps.sample_buffers(5, rows[0]["R"], rows[0]["Q"], rows[0]["u"], rows[0]["lam"], rows[0]["refs"])
    for k, row in enumerate(rows):
        args = [row[f] for f in ("R", "A", "Q", "u", "ud", "lam", "refs", "work")]
        base.store_sample(ref, k, 0.1 * k, *args)
        steps.store_sample(buf, k, 0.1 * k, *args)
    got, want = steps.first_samples(buf, 3), base.first_samples(ref, 3)
    assert got._fields == want._fields
    for x, r in zip(got, want):
        np.testing.assert_array_equal(x, r)


# ---------------------------------------------------------------- scene states


def test_has_friction_matches_numba(scene):
    assert steps.has_friction(scene.Lc) == base.has_friction(scene.L)


@pytest.mark.parametrize("size", [0.3, 1e-5, 1e-9])
@pytest.mark.parametrize("body_frame", [False, True])
def test_advance_pose_matches_numba(scene, size, body_frame):
    """Large and small increments (the Taylor branches of exp_so3 and se3_jacobian); in place too."""
    s = scene
    dx = size * s.rng.standard_normal(s.n)
    ref = base.advance_pose(s.L, s.R, s.A, s.Q, dx, body_frame)
    out = (np.empty_like(s.R), np.empty_like(s.A), np.empty_like(s.Q))
    steps.advance_pose(s.Lc, s.R, s.A, s.Q, dx, body_frame, *out)
    for x, r in zip(out, ref):
        assert close(x, r)
    R, A, Q = s.R.copy(), s.A.copy(), s.Q.copy()
    steps.advance_pose(s.Lc, R, A, Q, dx, body_frame, R, A, Q)
    for x, r in zip((R, A, Q), out):
        np.testing.assert_array_equal(x, r)


@pytest.mark.parametrize("baumgarte", [0.0, 7.0])
def test_index1_solve_matches_numba(scene, baumgarte):
    s = scene
    gam = s.rng.standard_normal(s.kept.size)
    ud_ref, lam_ref = base.index1_solve(s.e, gam, s.u, s.free, s.kept, baumgarte)
    W = core_evaluation(s.Lc, s.e)
    ud, lam = np.full(s.n, 9.0), np.empty(s.kept.size)
    steps.index1_solve(W, steps.index1_workspace(s.Lc, s.free.size, s.kept.size), gam, s.u, s.free, s.kept, baumgarte,
                       ud, lam)
    assert close(ud, ud_ref) and close(lam, lam_ref)


def test_velocity_transformations_match_numba(scene):
    """S u, S^T u, c, S ud + c, S^T (ud - c), X S, S^T X (se3.py)."""
    s = scene
    ud = s.rng.standard_normal(s.n)
    out = np.empty(s.n)
    for inverse in (False, True):
        core_se3.rotate_translations(s.Lc, s.A, s.u, inverse, out)
        assert close(out, numba_se3.rotate_translations(s.L, s.A, s.u, inverse))
    pairs = [(core_se3.inertial_velocities, numba_se3.inertial_velocities, (s.u,)),
             (core_se3.body_velocities, numba_se3.body_velocities, (s.u,)),
             (core_se3.convective, numba_se3.convective, (s.u,)),
             (core_se3.inertial_accelerations, numba_se3.inertial_accelerations, (s.u, ud)),
             (core_se3.body_accelerations, numba_se3.body_accelerations, (s.u, ud))]
    for core, numba, args in pairs:
        core(s.Lc, s.A, *args, out)
        assert close(out, numba(s.L, s.A, *args)), core.__name__
    X = s.rng.standard_normal((5, s.n))
    Xc, Xn = X.copy(), X.copy()
    core_se3.right_multiply(Xc, s.Lc, s.A)
    numba_se3.right_multiply(Xn, s.L, s.A)
    assert close(Xc, Xn)
    Xc, Xn = X.T.copy(), X.T.copy()
    core_se3.left_multiply(Xc, s.Lc, s.A)
    numba_se3.left_multiply(Xn, s.L, s.A)
    assert close(Xc, Xn)


def test_to_body_frame_matches_numba(scene):
    s = scene
    W = core_evaluation(s.Lc, s.e)
    e = s.e._replace(M=s.e.M.copy(), f=s.e.f.copy(), B=s.e.B.copy())
    e = e._replace(BF=e.B if np.shares_memory(s.e.BF, s.e.B) else s.e.BF.copy())
    numba_se3.to_body_frame(s.L, s.A, s.u, e)
    c = np.empty(s.n)
    core_se3.to_body_frame(s.Lc, s.A, s.u, W, c)
    for name in ("M", "f", "B", "BF"):
        assert close(getattr(W, name), getattr(e, name)), name
    assert close(c, numba_se3.convective(s.L, s.A, s.u))


@pytest.mark.parametrize("size", [0.4, 1e-7])
def test_body_increment_matches_numba(scene, size):
    """The SE(3) logarithm of a moved pose, above and below SMALL_ANGLE."""
    s = scene
    R1, A1, Q1 = base.advance_pose(s.L, s.R, s.A, s.Q, size * s.rng.standard_normal(s.n), True)
    dx = np.empty(s.n)
    core_se3.body_increment(s.Lc, s.R, s.A, R1, A1, s.Q, Q1, dx)
    assert close(dx, numba_se3.body_increment(s.L, s.R, s.A, R1, A1, s.Q, Q1))


def test_constraint_convection_matches_numba(scene):
    """gamma by the central difference of two evaluations (GAMMA_STEP)."""
    s = scene
    ref = base.constraint_convection(s.L, base.evaluation_arrays(s.L), s.R, s.A, s.Q, s.u, s.t, s.refs, s.kept)
    gam = np.empty(s.kept.size)
    W, ws = records.evaluation_arrays(s.Lc), steps.index1_workspace(s.Lc, s.free.size, s.kept.size)
    steps.constraint_convection(s.Lc, W, ws, s.R, s.A, s.Q, s.u, s.t, s.refs, s.kept, gam)
    assert close(gam, ref)


@pytest.mark.parametrize("baumgarte", [0.0, 5.0])
def test_index1_accelerations_match_numba(scene, baumgarte):
    """Accelerations and multipliers (iterated on lambda where friction reads them), and the
    evaluation left in the workspace."""
    s = scene
    guess = s.lam[s.kept].copy()
    W_ref = base.evaluation_arrays(s.L)
    ud_ref, lam_ref = base.index1_accelerations(s.L, W_ref, s.R, s.A, s.Q, s.u, s.t, s.refs, s.free, s.kept,
                                                baumgarte, guess)
    W, ws = records.evaluation_arrays(s.Lc), steps.index1_workspace(s.Lc, s.free.size, s.kept.size)
    ud, lam = np.empty(s.n), np.empty(s.kept.size)
    steps.index1_accelerations(s.Lc, W, ws, s.R, s.A, s.Q, s.u, s.t, s.refs, s.free, s.kept, baumgarte, guess,
                               ud, lam)
    assert close(ud, ud_ref) and close(lam, lam_ref)
    for name in ("M", "f", "g", "B"):
        assert close(getattr(W, name), getattr(W_ref, name)), name


@pytest.mark.parametrize("solve", [False, True])
def test_state_equations_match_numba(scene, solve):
    s = scene
    ref = base.state_equations(s.L, s.R, s.A, s.Q, s.u, s.t, s.lam, s.refs, s.free, s.kept, solve)
    got = steps.state_equations(s.Lc, s.R, s.A, s.Q, s.u, s.t, s.lam, s.refs, s.free, s.kept, solve)
    for name in ("M", "f", "g", "B", "BF", "bt", "coords", "loads", "flows"):
        assert close(getattr(got[0], name), getattr(ref[0], name)), name
    assert close(got[1], ref[1]) and close(got[2], ref[2])


# ---------------------------------------------------------------- Runge-Kutta


def test_rk4_stage_combine_hermite_match_numba():
    rng = np.random.default_rng(11)
    y, k1, k2, k3, k4 = rng.standard_normal((5, 13))
    out = np.empty(13)
    core_rk.rk4_stage(y, 0.37, k1, out)
    np.testing.assert_array_equal(out, numba_rk.rk4_stage(y, 0.37, k1))
    core_rk.rk4_combine(y, 0.37, k1, k2, k3, k4, out)
    np.testing.assert_array_equal(out, numba_rk.rk4_combine(y, 0.37, k1, k2, k3, k4))
    for theta in (0.0, 0.3, 1.0):
        assert core_rk.hermite(theta) == numba_rk.hermite(theta)


def oscillator(t, y, params):
    """A damped, forced oscillator: a plain Python right-hand side."""
    w, zeta = params
    return np.array([y[1], -w * w * y[0] - 2 * zeta * w * y[1] + np.sin(t)])


def test_rk4_fixed_matches_numba():
    """The same steps and samples as numba's rk4_fixed with the compiled twin of the rhs."""
    import numba  # the reference's right-hand side must be a numba function

    rhs = numba.njit(oscillator)
    y0, params = np.array([1.0, 0.0]), (3.0, 0.05)
    t, Y = core_rk.rk4_fixed(oscillator, 0.2, y0, 0.01, 37, 4, params)
    t_ref, Y_ref = numba_rk.rk4_fixed(rhs, 0.2, y0, 0.01, 37, 4, params)
    np.testing.assert_array_equal(t, t_ref)
    assert close(Y, Y_ref)
    assert close(core_rk.rk4_step(oscillator, 0.2, y0, 0.01, params), numba_rk.rk4_step(rhs, 0.2, y0, 0.01, params))
    with pytest.raises(ValueError, match="every"):
        core_rk.rk4_fixed(oscillator, 0.0, y0, 0.01, 3, 0, params)
