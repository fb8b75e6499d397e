"""The compiled core's base layer (sidprep/solver/core/rotations.pyx, records.pyx, curves.pyx,
body.pyx) against the numba kernels it replaces (sidprep/solver/equations/rotations.py,
assemble.py's workspaces, curves.py, body.py): the same results to round-off, on random inputs
and on the bodies, curves and paths of example scenes (every SID term switched on: inertia
change, second-order inertia, stiffening, Coriolis, centrifugal, preload, damping, gravity)."""

import functools
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from port_probe import ROOT, close, compile_probe
from scipy.interpolate import CubicSpline, PPoly
from scipy.spatial.transform import Rotation

from sidprep.solver.compile.layout import compiled_layout, pack_terms
from sidprep.solver.core import body as core_body
from sidprep.solver.core import curves as core_curves
from sidprep.solver.core import records
from sidprep.solver.core import rotations as core_rotations
from sidprep.solver.equations import assemble as numba_assemble
from sidprep.solver.equations import body as numba_body
from sidprep.solver.equations import curves as numba_curves
from sidprep.solver.equations import rotations as numba_rotations
from sidprep.solver.model.bodies import RigidBody
from sidprep.solver.model.effects import EFFECTS
from sidprep.solver.run import Run
from sidprep.solver.scene import load_scene

#: flexible bodies whose SID files hold every term (helicopter_rotor's blade, beam_buckling's
#: beam) and one without Ct1 and De (flexible_pendulum's bar)
FULL_BODIES = ["helicopter_rotor/scene", "beam_buckling/scene", "flexible_pendulum/scene"]
#: scenes whose layouts carry markers moving along paths (robotic_portal: tabulated motions)
PATH_SCENES = ["robotic_portal/scene", "moving_force/scene", "moving_mass/scene"]
#: scenes whose layouts make the records (load-stiffened markers, drivers, force elements)
RECORD_SCENES = ["helicopter_rotor/scene", "flexible_pendulum/scene", "beam_slider_crank/scene",
                 "robotic_portal/scene", "moving_mass/scene"]
#: random states per body
DRAWS = 4
#: the body.py names of the offsets and flags tables' columns
TERM_NAMES = ["MD0", "I0", "ME", "KE", "MD1", "I1", "CT0", "CT1", "CR0", "CR1", "GR0", "GE", "OE0", "OE1", "KS0",
              "KS1", "DE", "P2", "N_TERMS"]
FLAG_NAMES = ["F_INERTIA", "F_CT1", "F_CR1", "F_CORIOLIS", "F_OE0", "F_OE1", "F_PRELOAD", "F_DAMPING", "F_GRAVITY",
              "F_SECOND", "N_FLAGS"]


@pytest.fixture(scope="module")
def probe(tmp_path_factory):
    """base_layer_probe.pyx, compiled: Python entries to the pointer kernels."""
    return compile_probe(Path(__file__).with_name("base_layer_probe.pyx"), tmp_path_factory.mktemp("probe"))


@functools.cache
def scene_run(name):
    """The Run of an example scene (its layout)."""
    scene = load_scene(ROOT / "examples" / f"{name}.toml")
    return Run(scene.system, scene.t_end, scene.settings)


# ------------------------------------------------------------------------------------ rotations
def rotation_vectors(rng):
    """Rotation vectors of every regime: zero, below SMALL_ANGLE and SE3_SMALL_ANGLE, between, large."""
    unit = rng.standard_normal(3)
    unit /= np.linalg.norm(unit)
    return [np.zeros(3)] + [angle * unit for angle in (3e-7, 5e-5, 2e-4, 0.3, 2.0, 6.0)] + \
        [rng.standard_normal(3) for _ in range(3)]


def test_rotation_constants(probe):
    assert probe.constants() == (numba_rotations.SMALL_ANGLE, numba_rotations.SE3_SMALL_ANGLE)
    assert (core_rotations.SMALL_ANGLE, core_rotations.SE3_SMALL_ANGLE) == probe.constants()


def test_rotation_maps_random(probe):
    """exp_so3, se3_jacobian, se3_jacobian_solve in each regime of their series; the matrix ones
    also written over their input."""
    rng = np.random.default_rng(1)
    for theta in rotation_vectors(rng):
        v = rng.standard_normal(3)
        assert close(probe.rotation_kernel("exp_so3", theta), numba_rotations.exp_so3(theta))
        assert close(probe.rotation_kernel("se3_jacobian", theta), numba_rotations.se3_jacobian(theta))
        want = numba_rotations.se3_jacobian_solve(theta, v)
        assert close(probe.rotation_kernel("se3_jacobian_solve", theta, v), want)
        assert close(probe.rotation_kernel("se3_jacobian_solve", theta, v, alias=1), want)
        assert close(core_rotations.rotation_matrix(theta), numba_rotations.exp_so3(theta))
        assert close(core_rotations.se3_jacobian_matrix(theta), numba_rotations.se3_jacobian(theta))
        assert close(core_rotations.solve_se3_jacobian(theta, v), want)


def test_vector_kernels_random(probe):
    """dot3, cross3, matvec3, tmatvec3, matmul3, skew3, align, quaternions; out = an input too."""
    rng = np.random.default_rng(2)
    for _ in range(10):
        a, b, A, B = rng.standard_normal(3), rng.standard_normal(3), rng.standard_normal((3, 3)), \
            rng.standard_normal((3, 3))
        assert close(probe.dot3(a, b), numba_rotations.dot(a, b))
        for alias in (-1, 0, 1):
            assert close(probe.rotation_kernel("cross3", a, b, alias=alias), numba_rotations.cross(a, b))
            assert close(probe.rotation_kernel("matmul3", A, B, alias=alias), numba_rotations.matmul(A, B))
        for alias in (-1, 1):
            assert close(probe.rotation_kernel("matvec3", A, a, alias=alias), numba_rotations.matvec(A, a))
            assert close(probe.rotation_kernel("tmatvec3", A, a, alias=alias), numba_rotations.tmatvec(A, a))
        assert close(probe.rotation_kernel("skew3", a), numba_rotations.skew(a))
        assert close(core_rotations.skew_matrix(a), numba_rotations.skew(a))
        ua, ub = a / np.linalg.norm(a), b / np.linalg.norm(b)
        assert close(probe.rotation_kernel("align", ua, ub), numba_rotations.align(ua, ub))
        e, w = rng.standard_normal(4), rng.standard_normal(3)
        assert close(probe.rotation_kernel("quaternion_to_matrix", e), numba_rotations.quaternion_to_matrix(e))
        assert close(probe.rotation_kernel("quaternion_rate", e, w), numba_rotations.quaternion_rate(e, w))


def test_strided_products_random(probe):
    """dot, matvec, tmatvec, matmul on strided views (every other entry, padded columns) of any size."""
    rng = np.random.default_rng(3)
    for p, r, k in [(3, 1, 1), (3, 7, 4), (5, 16, 3), (1, 2, 9)]:
        a = rng.standard_normal((p, 2 * r + 3))[:, :2 * r:2]
        b = rng.standard_normal((r + 2, k + 5))[1:r + 1, 2:k + 2]
        x, y = rng.standard_normal(2 * r)[::2], rng.standard_normal(3 * p)[::3]
        z = rng.standard_normal(r)
        assert close(probe.dot(x, z), numba_rotations.dot(x, z))
        out = np.full(2 * p, np.nan)
        probe.matvec(a, x, out[::2])
        assert close(out[::2], numba_rotations.matvec(a, x)) and np.isnan(out[1::2]).all()
        out = np.full(r, np.nan)
        probe.tmatvec(a, y, out)
        assert close(out, numba_rotations.tmatvec(a, y))
        out = np.full((p, k + 2), np.nan)
        probe.matmul(a, b, out[:, 1:k + 1])
        assert close(out[:, 1:k + 1], numba_rotations.matmul(np.ascontiguousarray(a), np.ascontiguousarray(b)))
        assert np.isnan(out[:, 0]).all() and np.isnan(out[:, k + 1]).all()


def test_python_rotations():
    """as_rotation and matrix_to_quaternion, moved into the core as they were."""
    rng = np.random.default_rng(4)
    for theta in rotation_vectors(rng):
        assert close(core_rotations.as_rotation(theta), numba_rotations.as_rotation(theta))
        rot = numba_rotations.exp_so3(theta)
        assert close(core_rotations.matrix_to_quaternion(rot), numba_rotations.matrix_to_quaternion(rot))
    for rot in Rotation.random(20, random_state=5).as_matrix():
        assert close(core_rotations.matrix_to_quaternion(rot), numba_rotations.matrix_to_quaternion(rot))
        assert close(core_rotations.as_rotation(rot), rot)
    assert close(core_rotations.as_rotation(None), np.eye(3))
    with pytest.raises(ValueError, match="rotation vector"):
        core_rotations.as_rotation(np.zeros(4))


# ------------------------------------------------------------------------------------- records
@pytest.mark.parametrize("name", RECORD_SCENES)
def test_records_as_the_numba_workspaces(name):
    """layout_record views the layout's own arrays; evaluation_arrays has the shapes of numba's
    and shares B_F, JTF, JRF with B, JT, JR exactly when no marker is load-stiffened."""
    run = scene_run(name)
    arrays = run.L
    L = records.layout_record(arrays)
    assert records.layout_record(L) is L and L.arrays is arrays
    odd = arrays._replace(qoff=arrays.qoff.astype(np.int32), mk_pos=np.asfortranarray(arrays.mk_pos))
    converted = records.layout_record(odd)
    assert converted.arrays.qoff.dtype == np.int64 and converted.arrays.mk_pos.flags.c_contiguous
    assert np.array_equal(np.asarray(converted.qoff), arrays.qoff) and np.array_equal(converted.mk_pos, arrays.mk_pos)
    built = compiled_layout(run.system, run.terms, run.stiffened)
    for field, a in built.arrays._asdict().items():
        assert np.array_equal(a, getattr(arrays, field), equal_nan=True) and np.array_equal(getattr(built, field), a, equal_nan=True)
    for field, a in arrays._asdict().items():
        assert getattr(L.arrays, field) is a
        assert np.shares_memory(np.asarray(getattr(L, field)), a) or a.size == 0
    W, ref = records.evaluation_arrays(L), numba_assemble.evaluation_arrays(arrays)
    for field in ref._fields:
        if field != "kin":
            assert np.asarray(getattr(W, field)).shape == getattr(ref, field).shape, field
            assert not np.asarray(getattr(W, field)).any()
    for field in ref.kin._fields:
        assert np.asarray(getattr(W.kin, field)).shape == getattr(ref.kin, field).shape, field
    stiffened = bool(numba_assemble.load_stiffened(arrays.mk_k0))
    assert W.kin.stiffened == stiffened
    for mine, theirs in [(W.B, W.BF), (W.kin.JT, W.kin.JTF), (W.kin.JR, W.kin.JRF)]:
        assert np.shares_memory(np.asarray(mine), np.asarray(theirs)) != stiffened
    w_max = W.kin.JT.shape[2]
    assert np.asarray(W.kin.work).shape == (w_max + records.WORK_EXTRA_ROWS, w_max)
    every = L.with_every_marker()
    assert (np.asarray(every.mk_active) == 1).all() and np.array_equal(every.arrays.mk_active,
                                                                      numba_assemble.every_marker(arrays).mk_active)
    assert every.arrays.fe_par is arrays.fe_par


# -------------------------------------------------------------------------------------- curves
def random_curves(rng):
    """(x, c) piecewise polynomials of degree 0 to 3, one to nine pieces."""
    out = []
    for degree in range(4):
        for pieces in (1, 2, 9):
            x = np.cumsum(rng.uniform(0.1, 1.0, pieces + 1)) - 0.5
            out.append((x, rng.standard_normal((degree + 1, pieces))))
    y = np.sin(np.pi * np.linspace(0.0, 2.0, 7))
    y[-1] = y[0]
    spline = CubicSpline(np.linspace(0.0, 2.0, 7), y, bc_type="periodic")
    return out + [(spline.x, spline.c)]


def test_curve_value_random(probe):
    """Values, slopes and curvatures inside, beyond both ends and wrapped by a period (Python's
    floored modulo, also for arguments before the first breakpoint)."""
    rng = np.random.default_rng(6)
    for x, c in random_curves(rng):
        ats = np.concatenate([rng.uniform(x[0] - 3.0, x[-1] + 3.0, 12), x, [x[0] - 2 * (x[-1] - x[0])]])
        for period in (0.0, x[-1] - x[0], 0.37):
            for at in ats:
                for derivative in range(3):
                    want = numba_curves.curve_value(x, c, period, at, derivative)
                    assert close(probe.curve_value(x, c, period, at, derivative), want), (period, at, derivative)
        assert close(PPoly(c, x)(x[0] + 0.3), probe.curve_value(x, c, 0.0, x[0] + 0.3, 0))


def test_motion_state_random(probe):
    """Constant speed, smooth start (before, during and after the ramp) and a tabulated spline."""
    rng = np.random.default_rng(7)
    x, c = random_curves(rng)[-1]
    for t in np.concatenate([[-1.0, 0.0, 0.25, 0.5, 0.75], rng.uniform(-0.5, 3.0, 10)]):
        for kind in (core_curves.CONSTANT_SPEED, core_curves.SMOOTH_START, core_curves.TABULATED):
            params = np.array([rng.standard_normal(), rng.standard_normal(), 0.5])
            want = numba_curves.motion_state(kind, params, x, c, t)
            assert close(probe.motion_state(kind, params, x, c, t), want), (kind, t)


@pytest.mark.parametrize("name", PATH_SCENES)
def test_path_shapes_scenes(probe, name):
    """Point, Phi, Psi, on, and their s-derivatives along every path marker of a scene's layout,
    on the path, at its ends and beyond them."""
    arrays = scene_run(name).L
    L = records.layout_record(arrays)
    rng = np.random.default_rng(8)
    paths = np.flatnonzero(arrays.mk_path[:, 0] >= 0)
    assert paths.size
    for k in paths:
        first, b = arrays.mk_path[k, 0], arrays.mk_body[k]
        nq = int(arrays.qoff[b + 1] - arrays.qoff[b])
        meta = arrays.curve_meta[first]
        x = arrays.curve_x[meta[0]:meta[0] + meta[1]]
        for s in np.concatenate([x[[0, -1]], rng.uniform(x[0] - 0.2, x[-1] + 0.2, 8)]):
            got = probe.path_shapes(L, first, nq, s)
            want = numba_curves.path_shapes(arrays.curve_x, arrays.curve_c, arrays.curve_meta, first, nq, s)
            assert got[3] == want[3]
            for i in (0, 1, 2, 4, 5):
                assert close(got[i], want[i]), (k, s, i)


def test_curve_constants():
    for name in ("CONSTANT_SPEED", "SMOOTH_START", "TABULATED"):
        assert getattr(core_curves, name) == getattr(numba_curves, name)


# ---------------------------------------------------------------------------------------- body
def random_terms(rng, nq, drop=()):
    """A BodyTerms-like record of random arrays (nq modes), every term present but those in ``drop``."""
    arrays = {"md0": (3,), "I0": (3, 3), "Me": (nq, nq), "Ke": (nq, nq), "md1": (nq, 3), "I1": (nq, 3, 3),
              "P": (3, 3, nq, nq), "Ct0": (nq, 3), "Ct1": (nq, nq, 3), "Cr0": (nq, 3), "Cr1": (nq, nq, 3),
              "Gr0": (nq, 3, 3), "Ge": (3, nq, nq), "Oe0": (nq, 6), "Oe1": (nq, nq, 6), "ks0": (nq,), "ks1": (nq, nq),
              "De": (nq, nq)}
    terms = {name: None if name in drop else rng.standard_normal(shape) for name, shape in arrays.items()}
    return SimpleNamespace(nq=nq, mass=rng.uniform(0.5, 5.0), gravity="gravity" not in drop, **terms)


def scene_terms():
    """(label, BodyTerms) of the FULL_BODIES with every effect their SID files hold, and of every
    body of those scenes' own runs (their chosen effects)."""
    out = []
    for name in FULL_BODIES:
        run = scene_run(name)
        for body, terms in zip(run.system.bodies, run.terms):
            out.append((f"{name}:{body.name}", terms))
            if not isinstance(body, RigidBody):
                out.append((f"{name}:{body.name}:all", body.terms(set(EFFECTS), gravity=True)))
    return out


def state(rng, nq, scale):
    """(q, qd, w, gk, r, A, g) of a random state, modal coordinates of size ``scale``."""
    return (scale * rng.standard_normal(nq), scale * rng.standard_normal(nq), rng.standard_normal(3),
            9.81 * rng.standard_normal(3), rng.standard_normal(3), Rotation.random(random_state=rng).as_matrix(),
            np.array([0.0, 0.0, -9.81]))


def check_body(probe, terms, rng, scale):
    """Every body kernel of the packed ``terms`` at DRAWS random states against numba's."""
    F, off, flags = pack_terms(terms)
    mass, nq = float(terms.mass), terms.nq
    for _ in range(DRAWS):
        q, qd, w, gk, r, A, g = state(rng, nq, scale)
        want_m, want_h = numba_body.body_equations(F, off, flags, mass, q, qd, w, gk)
        m, h = np.full((6 + nq + 1, 6 + nq + 2), np.nan), np.full(6 + nq + 1, np.nan)
        probe.body_equations(F, off, flags, mass, q, qd, w, gk, m, h)
        assert close(m[:6 + nq, :6 + nq], want_m) and close(h[:6 + nq], want_h)
        got_m, got_h = core_body.body_matrices(F, off, flags, mass, q, qd, w, gk)
        assert close(got_m, want_m) and close(got_h, want_h)
        assert np.isnan(m[:, 6 + nq:]).all() and np.isnan(m[6 + nq:]).all() and np.isnan(h[6 + nq:]).all()
        for got, want in zip(probe.inertia_terms(F, off, flags, q, 5), numba_body.inertia_terms(F, off, flags, nq, q)):
            assert close(got, want)
        assert close(probe.gravity_md(F, off, q), numba_body.gravity_md(F, off, nq, q))
        out = np.zeros(6 + nq)
        probe.add_gravity_force(F, off, flags, mass, q, gk, out)
        assert close(out, numba_body.gravity_force(F, off, flags, mass, q, gk))
        got = probe.body_potentials(F, off, flags, mass, r, A, q, g)
        want = numba_body.body_potentials(F, off, flags, mass, r, A, q, g)
        assert close(got[0], want[0]) and close(got[1], want[1])


@pytest.mark.parametrize("nq", [0, 1, 4, 9])
def test_body_kernels_random(probe, nq):
    """All terms on, then each switched off alone, with unit-sized random arrays and states."""
    rng = np.random.default_rng(20 + nq)
    optional = ["md1", "P", "Ct1", "Cr1", "Gr0", "Oe0", "Oe1", "ks0", "De", "gravity"]
    for drop in [()] + [(name,) + (("I1",) if name == "md1" else ("Ge",) if name == "Gr0" else ("ks1",)
                                   if name == "ks0" else ()) for name in optional]:
        check_body(probe, random_terms(rng, nq, drop), rng, 1.0)


def test_first_order_and_pairs_random(probe):
    """add_first_order into rows ld apart, pair_contraction of two different vectors."""
    rng = np.random.default_rng(30)
    nq = 5
    x1f, q, x = rng.standard_normal((nq, 3 * nq)), rng.standard_normal(nq), rng.standard_normal((nq, 3))
    want = x.copy()
    numba_body.add_first_order(want, x1f, q)
    padded = np.full((nq, 7), np.nan)
    padded[:, :3] = x
    probe.add_first_order(padded, x1f, q)
    assert close(padded[:, :3], want) and np.isnan(padded[:, 3:]).all()
    p, y = rng.standard_normal((9, nq * nq)), rng.standard_normal(nq)
    assert close(probe.pair_contraction(p, q, y), numba_body.pair_contraction(p, q, y))


@pytest.mark.parametrize("label, terms", scene_terms(), ids=lambda v: v if isinstance(v, str) else "")
def test_body_kernels_scenes(probe, label, terms):
    """The bodies of example scenes, with their own effects and with all of them, at states of
    modal amplitudes 1e-3 and 1."""
    rng = np.random.default_rng(40)
    for scale in (1e-3, 1.0):
        check_body(probe, terms, rng, scale)


def test_body_constants():
    """The offsets and flags columns are body.py's (compile/layout.py packs by them)."""
    for name in TERM_NAMES + FLAG_NAMES:
        assert getattr(core_body, name) == getattr(numba_body, name), name
