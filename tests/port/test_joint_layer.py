"""The compiled core's markers, joints and force elements (sidprep/solver/core/constraints.pyx,
forces.pyx) against the numba kernels they replace (sidprep/solver/equations/constraints.py,
forces.py): the same results to round-off, on random inputs and on the markers, joints and force
elements of example scenes (bump stops, joint forces, friction, tables of time and of a joint
coordinate, loads and springs on markers moving along paths, load-stiffened markers)."""

import functools
import importlib.util
from pathlib import Path

import numpy as np
import pytest
from Cython.Build import cythonize
from scipy.spatial.transform import Rotation
from setuptools import Distribution, Extension

from sidprep.solver.core import constraints as core_constraints
from sidprep.solver.core import forces as core_forces
from sidprep.solver.core import records
from sidprep.solver.equations import constraints as numba_constraints
from sidprep.solver.equations import forces as numba_forces
from sidprep.solver.equations.assemble import every_marker
from sidprep.solver.integrators.base import constraint_rows, evaluate
from sidprep.solver.run import Run
from sidprep.solver.scene import load_scene

ROOT = Path(__file__).resolve().parents[2]
#: kernel against kernel, the same arithmetic in the same order: relative to the largest entry
KERNEL_RTOL = 1e-12
#: example scenes with markers, joints and force elements of every kind the kernels know
SCENES = ["helicopter_rotor/scene",        # joint force, spring-damper with a bump stop, load-stiffened blade
          "engine/scene_rigid",            # force from a table of a joint angle, along a direction; a slide
          "beam_slider_crank/scene",       # joint friction on a prismatic joint
          "robotic_portal/scene",          # springs between markers moving along paths (tabulated motions)
          "moving_force/scene",            # a force on a marker moving along a load-stiffened beam
          "beam_buckling/scene",           # a torque from a table of time
          "moving_mass/scene"]             # a rigid body riding a path (on_path joint)
#: random draws of the state per scene
DRAWS = 3


@pytest.fixture(scope="module")
def probe(tmp_path_factory):
    """joint_layer_probe.pyx, compiled: Python entries to the pointer kernels."""
    build = tmp_path_factory.mktemp("probe")
    source = Path(__file__).with_name("joint_layer_probe.pyx")
    extension = cythonize([Extension("joint_layer_probe", [str(source)])], include_path=[str(ROOT)],
                          build_dir=str(build), quiet=True,
                          compiler_directives={"language_level": 3, "boundscheck": True})
    command = Distribution({"ext_modules": extension}).get_command_obj("build_ext")
    command.build_lib = command.build_temp = str(build)
    command.ensure_finalized()
    command.run()
    spec = importlib.util.spec_from_file_location("joint_layer_probe", command.get_ext_fullpath("joint_layer_probe"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def close(x, ref, rtol=KERNEL_RTOL):
    """Whether x equals ref to rtol of ref's largest entry (equal where ref is zero)."""
    x, ref = np.asarray(x, float), np.asarray(ref, float)
    return x.shape == ref.shape and np.max(np.abs(x - ref), initial=0.0) <= rtol * np.max(np.abs(ref), initial=0.0)


def rotation(rng):
    return Rotation.random(random_state=rng).as_matrix()


def random_marker(rng, nq):
    """(r, A, q, position, rotation, phi, psi) of a marker on a body with nq modes."""
    return (rng.standard_normal(3), rotation(rng), rng.standard_normal(nq), rng.standard_normal(3), rotation(rng),
            rng.standard_normal((3, nq)), rng.standard_normal((3, nq)))


def padded(a, width, rng):
    """a (3, k) in the first k columns of a (3, width) array of noise (the kernels read only those)."""
    out = rng.standard_normal((a.shape[0], width))
    out[:, :a.shape[1]] = a
    return out


@pytest.mark.parametrize("nq", [0, 1, 4, 9])
def test_marker_kinematics_random(probe, nq):
    """marker_pose and marker_jacobians (shapes rows lds apart, Jacobian rows ld apart) and the
    Python marker_kinematics give numba's p, A_m, JT, JR, d."""
    rng = np.random.default_rng(nq)
    for _ in range(5):
        r, A, q, pos, rot, phi, psi = random_marker(rng, nq)
        ref = numba_constraints.marker_kinematics(r, A, q, pos, rot, phi, psi)
        for got, want in zip(core_constraints.marker_kinematics(r, A, q, pos, rot, phi, psi), ref):
            assert close(got, want)
        p, m, d = probe.marker_pose(r, A, q, pos, rot, padded(phi, nq + 3, rng), padded(psi, nq + 3, rng))
        assert close(p, ref[0]) and close(m, ref[1]) and close(d, ref[4])
        jt, jr = rng.standard_normal((3, nq + 11)), rng.standard_normal((3, nq + 11))
        tail = jt[:, 6 + nq:].copy()
        probe.marker_jacobians(A, d, padded(phi, nq + 2, rng), padded(psi, nq + 2, rng), nq, jt, jr)
        assert close(jt[:, :6 + nq], ref[2]) and close(jr[:, :6 + nq], ref[3])
        np.testing.assert_array_equal(jt[:, 6 + nq:], tail)


@pytest.mark.parametrize("nq", [1, 3, 8])
def test_stiffened_jacobian_random(probe, nq):
    """jac + A (K0 q) in the modal columns, into a padded out or in place."""
    rng = np.random.default_rng(10 + nq)
    jac, A, q, k0 = rng.standard_normal((3, 6 + nq)), rotation(rng), rng.standard_normal(nq), \
        rng.standard_normal((3, nq, nq))
    ref = numba_constraints.stiffened_jacobian(jac, A, q, k0)
    wide = padded(jac, 6 + nq + 2, rng)
    out = rng.standard_normal(wide.shape)
    probe.stiffened_jacobian(wide, A, q, k0, out)
    assert close(out[:, :6 + nq], ref)
    probe.stiffened_jacobian(wide, A, q, k0, wide)
    assert close(wide[:, :6 + nq], ref)


def numba_joint_rows(rows, p1, a1, p2, a2):
    g, c = np.zeros(len(rows) + 2), np.zeros((len(rows) + 2, 4, 3))
    numba_constraints.joint_rows(rows, p1, a1, p2, a2, g, c, 2)
    return g[2:], c[2:]


def core_joint_rows(probe, rows, p1, a1, p2, a2):
    g, c = np.full(len(rows), np.nan), np.full((len(rows), 4, 3), np.nan)
    probe.joint_rows(rows, p1, a1, p2, a2, g, c)
    return g, c


def test_joint_rows_random(probe):
    """Position rows along every axis of marker 1 and perpendicularity rows of every pair of axes."""
    rng = np.random.default_rng(20)
    rows = np.array([[0, k, -1] for k in range(3)] + [[1, k, kb] for k in range(3) for kb in range(3)], np.int64)
    for _ in range(5):
        p1, a1, p2, a2 = rng.standard_normal(3), rotation(rng), rng.standard_normal(3), rotation(rng)
        g, c = core_joint_rows(probe, rows, p1, a1, p2, a2)
        ref_g, ref_c = numba_joint_rows(rows, p1, a1, p2, a2)
        assert close(g, ref_g) and close(c, ref_c)


def test_joint_coordinate_random(probe):
    """Angles about z1 unwrapped against references several turns away, and slides."""
    rng = np.random.default_rng(30)
    for kind in (core_constraints.ANGLE, core_constraints.SLIDE):
        for _ in range(20):
            p1, a1, p2, a2 = rng.standard_normal(3), rotation(rng), rng.standard_normal(3), rotation(rng)
            ref = rng.uniform(-30.0, 30.0)
            value, c = probe.joint_coordinate(kind, p1, a1, p2, a2, ref)
            want, want_c = numba_constraints.joint_coordinate(kind, p1, a1, p2, a2, ref)
            assert close(value, want) and close(c, want_c)


@pytest.mark.parametrize("raw, ref", [(0.0, 0.0), (np.pi, 0.0), (-np.pi, 0.0), (3.0, -3.0), (-3.0, 3.0),
                                      (0.1, 20.0), (0.1, -20.0), (1e-17, 2 * np.pi), (-1e-17, -2 * np.pi),
                                      (7.5, 7.5 - np.pi)])
def test_unwrap_is_pythons_modulo(probe, raw, ref):
    """unwrap's modulo takes the divisor's sign (Python's %, numba's), also at the half-turn."""
    assert probe.unwrap(raw, ref) == numba_constraints.unwrap(raw, ref)


def test_spring_laws_random(probe):
    """Tension, its parts and the bump stop's potential, with the stop open and engaged."""
    rng = np.random.default_rng(40)
    for has_stop in (0.0, 1.0):
        for _ in range(20):
            par = np.zeros(core_forces.FE_PAR_COLUMNS)
            par[:3] = rng.uniform(0.0, 1e4), rng.uniform(0.0, 1e2), rng.uniform(0.1, 1.0)
            par[3:8] = has_stop, rng.uniform(-0.01, 0.01), rng.uniform(1e4, 1e8), rng.uniform(1.0, 2.5), \
                rng.uniform(0.0, 1e3)
            x, rate = rng.uniform(-0.05, 0.05), rng.standard_normal()
            assert close(probe.spring_tension(par, x, rate), numba_forces.spring_tension(par, x, rate))
            assert close(probe.bump_potential(par, x), numba_forces.bump_potential(par, x))


def test_add_joint_load_random(probe):
    rng = np.random.default_rng(50)
    loads, crow, value = rng.standard_normal((4, 6)), rng.standard_normal((4, 3)), rng.standard_normal()
    ref = loads.copy()
    numba_forces.add_joint_load(ref, np.array([3, 1]), crow, value)
    probe.add_joint_load(loads, 3, 1, crow, value)
    assert close(loads, ref)


def test_constants_are_numbas_and_the_layouts():
    """The kinds are the numba modules'; the tables' widths those of the layouts build_layout makes."""
    for name in ("NO_COORDINATE", "ANGLE", "SLIDE"):
        assert getattr(core_constraints, name) == getattr(numba_constraints, name)
    for name in ("FE_FORCE", "FE_TORQUE", "FE_SPRING", "FE_JOINT_FORCE", "FE_FRICTION", "FE_MOVING_MASS"):
        assert getattr(core_forces, name) == getattr(numba_forces, name)
    L = scene_run(SCENES[0]).L
    assert (L.fe_int.shape[1], L.fe_par.shape[1]) == (core_forces.FE_INT_COLUMNS, core_forces.FE_PAR_COLUMNS)


@functools.cache
def scene_run(name):
    """The Run of an example scene (its layout and initial pose)."""
    scene = load_scene(ROOT / "examples" / f"{name}.toml")
    return Run(scene.system, scene.t_end, scene.settings)


def scene_states(name):
    """(L, numba Evaluation, t, lam) at DRAWS random states about the scene's initial pose: every
    marker of the layout active, spring lengths set (as the run's start sets them)."""
    run = scene_run(name)
    L = every_marker(run.L)
    L = L._replace(fe_par=L.fe_par.copy())
    R, A, Q, u = run.initial_positions()
    rng = np.random.default_rng(len(name))
    springs = (L.fe_int[:, 0] == numba_forces.FE_SPRING) & np.isnan(L.fe_par[:, 2])
    L.fe_par[springs, 2] = rng.uniform(0.1, 1.0, springs.sum())
    for _ in range(DRAWS):
        Ri = R + 0.01 * rng.standard_normal(R.shape)
        Ai = np.array([a @ Rotation.from_rotvec(0.05 * rng.standard_normal(3)).as_matrix() for a in A]).reshape(A.shape)
        Qi, ui = Q + 1e-3 * rng.standard_normal(Q.shape), rng.standard_normal(u.shape)
        t, lam = rng.uniform(0.0, scene_run(name).t_end), 1e3 * rng.standard_normal(constraint_rows(L))
        refs = rng.uniform(-10.0, 10.0, L.joint_mk.shape[0])
        yield L, evaluate(L, Ri, Ai, Qi, ui, t, lam, refs), (Ri, Ai, Qi), t, lam


@pytest.mark.parametrize("name", SCENES)
def test_scene_markers_and_joints(probe, name):
    """Every body marker of the scene (not on a path), its load-stiffened Jacobians, every joint's
    rows and coordinate, at random states, from the numba evaluation's marker kinematics."""
    for L, e, (R, A, Q), _, _ in scene_states(name):
        kin = e.kin
        for k in np.flatnonzero((L.mk_body >= 0) & (L.mk_path[:, 0] < 0)):
            b = L.mk_body[k]
            nq = L.qoff[b + 1] - L.qoff[b]
            q, o = Q[L.qoff[b]:L.qoff[b + 1]], L.mk_shape[k]
            phi, psi = L.shapes[o:o + 3 * nq].reshape(3, nq), L.shapes[o + 3 * nq:o + 6 * nq].reshape(3, nq)
            p, m, d = np.empty(3), np.empty((3, 3)), np.empty(3)
            numba_constraints.marker_pose(R[b], A[b], q, L.mk_pos[k], L.mk_rot[k], phi, psi, p, m, d)
            wide_phi, wide_psi = np.hstack([phi, np.zeros((3, 1))]), np.hstack([psi, np.zeros((3, 1))])
            got = probe.marker_pose(R[b], A[b], q, L.mk_pos[k], L.mk_rot[k], wide_phi, wide_psi)
            assert close(got[0], p) and close(got[1], m) and close(got[2], d)
            assert close(got[0], kin.P[k]) and close(got[1], kin.AM[k])
            jt, jr = np.zeros(kin.JT[k].shape), np.zeros(kin.JR[k].shape)
            probe.marker_jacobians(A[b], d, wide_phi, wide_psi, nq, jt, jr)
            assert close(jt, kin.JT[k]) and close(jr, kin.JR[k])
            for o0, jac, force in [(L.mk_k0[k, 0], jt, kin.JTF[k]), (L.mk_k0[k, 1], jr, kin.JRF[k])]:
                if o0 >= 0:
                    out = np.zeros_like(jac)
                    probe.stiffened_jacobian(jac, A[b], q, L.shapes[o0:o0 + 3 * nq * nq].reshape(3, nq, nq), out)
                    assert close(out[:, :6 + nq], force[:, :6 + nq])
        for j, (k1, k2) in enumerate(L.joint_mk):
            rows = L.jrows[L.joint_off[j]:L.joint_off[j + 1]]
            args = kin.P[k1], kin.AM[k1], kin.P[k2], kin.AM[k2]
            if len(rows):
                g, c = core_joint_rows(probe, rows, *args)
                ref_g, ref_c = numba_joint_rows(rows, *args)
                assert close(g, ref_g) and close(c, ref_c)
                assert close(g, e.g[L.joint_off[j]:L.joint_off[j + 1]])
            for kind in (core_constraints.ANGLE, core_constraints.SLIDE):
                value, c = probe.joint_coordinate(kind, *args, 0.3 * j)
                want, want_c = numba_constraints.joint_coordinate(kind, *args, 0.3 * j)
                assert close(value, want) and close(c, want_c)


def core_kinematics(Lc, kin):
    """The core MarkerKinematics of layout record Lc holding the numba kinematics kin."""
    out = records.marker_kinematics(Lc)
    for field in ("P", "AM", "VEL", "OMG", "VC", "WC", "JT", "JR"):
        np.asarray(getattr(out, field))[...] = getattr(kin, field)
    return out


def force_element_variants(L, kin):
    """L, then L with every load in its marker's frame and a moving mass (no load of its own
    here), with every bump stop engaged and with every one open (clearance 1 mm below or above
    the deflection: both branches of each law)."""
    yield L
    par = np.vstack([L.fe_par, np.zeros((1, L.fe_par.shape[1]))])
    par[-1, 0] = 1.0
    fe_int = np.vstack([L.fe_int, np.full((1, L.fe_int.shape[1]), -1)])
    fe_int[-1, :2] = numba_forces.FE_MOVING_MASS, 0
    loads = np.isin(fe_int[:, 0], [numba_forces.FE_FORCE, numba_forces.FE_TORQUE])
    par[loads, 7] = 1.0 - par[loads, 7]
    stops = np.flatnonzero((fe_int[:, 0] == numba_forces.FE_SPRING) & (par[:, 3] > 0.0))
    for gap in (-1e-3, 1e-3):
        par = par.copy()
        for i in stops:
            length = np.linalg.norm(kin.P[fe_int[i, 2]] - kin.P[fe_int[i, 1]])
            par[i, 4] = -(length - par[i, 2]) + gap
        yield L._replace(fe_int=fe_int, fe_par=par)


@pytest.mark.parametrize("name", SCENES)
def test_scene_force_elements(name):
    """force_elements' loads and flows, stop_states and has_stops at random states of the scene
    (random multipliers for friction, random times and joint coordinates for the tables)."""
    for L0, e, _, t, lam in scene_states(name):
        for L in force_element_variants(L0, e.kin):
            Lc = records.layout_record(L)
            kin = core_kinematics(Lc, e.kin)
            nmk = L.mk_body.shape[0]
            loads, flows = np.zeros((nmk, 6)), np.zeros(4)
            numba_forces.force_elements(L, t, e.kin, e.coords, e.crows, e.convective, lam, loads, flows)
            got_loads, got_flows = np.zeros((nmk, 6)), np.zeros(4)
            core_forces.force_elements(Lc, t, kin, e.coords, e.crows, e.convective, lam, got_loads, got_flows)
            assert close(got_loads, loads) and close(got_flows, flows)
            nfe = L.fe_int.shape[0]
            pen, rate = np.zeros(nfe), np.zeros(nfe)
            numba_forces.stop_states(L, e.kin, pen, rate)
            got_pen, got_rate = np.zeros(nfe), np.zeros(nfe)
            core_forces.stop_states(Lc, kin, got_pen, got_rate)
            finite = np.isfinite(pen)
            np.testing.assert_array_equal(np.isfinite(got_pen), finite)
            assert close(got_pen[finite], pen[finite]) and close(got_rate, rate)
            assert core_forces.has_stops(Lc) == numba_forces.has_stops(L)


@pytest.mark.parametrize("name", SCENES)
def test_scene_curves(probe, name):
    """Every curve of the scene's layout (tables, tabulated motions, paths) at random abscissae
    within and beyond its breakpoints, and the motion curves' arrays (placeholders for index -1)."""
    L = scene_run(name).L
    Lc = records.layout_record(L)
    rng = np.random.default_rng(60)
    for index in range(L.curve_meta.shape[0]):
        x = numba_forces.curve_arrays(L.curve_x, L.curve_c, L.curve_meta, index)[0]
        span = x[-1] - x[0]
        for at in rng.uniform(x[0] - 0.2 * span, x[-1] + 0.2 * span, 5):
            want = numba_forces.curve(L.curve_x, L.curve_c, L.curve_meta, L.curve_period, index, at)
            assert close(probe.curve(Lc, index, at), want)
    for index in [-1, *range(L.curve_meta.shape[0])]:
        x, c = numba_forces.motion_curve(L.curve_x, L.curve_c, L.curve_meta, index)
        got_x, got_c = probe.motion_curve(Lc, index)
        np.testing.assert_array_equal(got_x, x)
        np.testing.assert_array_equal(got_c, c.ravel())


def test_scenes_cover_every_force_element_and_joint_coordinate():
    """The scenes above hold every force element kind but the moving mass (force_element_variants
    adds one), both joint coordinates, bump stops, tables, path markers and load stiffening."""
    layouts = [scene_run(name).L for name in SCENES]
    kinds = set(np.concatenate([L.fe_int[:, 0] for L in layouts]).tolist())
    assert kinds >= {numba_forces.FE_FORCE, numba_forces.FE_TORQUE, numba_forces.FE_SPRING,
                     numba_forces.FE_JOINT_FORCE, numba_forces.FE_FRICTION}
    assert {1, 2} <= set(np.concatenate([L.joint_kind for L in layouts]).tolist())
    assert any(((L.fe_int[:, 0] == numba_forces.FE_SPRING) & (L.fe_par[:, 3] > 0)).any() for L in layouts)
    assert any(((L.fe_int[:, 4] >= 0)).any() for L in layouts)
    assert any((L.mk_path[:, 0] >= 0).any() for L in layouts) and any((L.mk_k0 >= 0).any() for L in layouts)
