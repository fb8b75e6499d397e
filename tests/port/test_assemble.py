"""The compiled system equations (sidprep.solver.core.assemble and its path kernels, core.paths)
against the numba kernels of sidprep.solver.equations.assemble: every Evaluation field, the marker
kinematics, the energies, the drives' constraint power and the moving masses, at random states of
the layouts of every floating-frame example scene and of a system with what no scene has (a mass
sliding on a path, friction on it, a tabulated path motion): the run's layout and the one with
every marker active."""

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sidprep.solver import SolverSettings
from sidprep.solver.absolute_nodal.scene import is_absolute_nodal_scene
from sidprep.solver.core import assemble as core
from sidprep.solver.core.records import evaluation_arrays, layout_record, load_stiffened, marker_kinematics
from sidprep.solver.equations import assemble as numba_kernels
from sidprep.solver.equations.rotations import exp_so3
from sidprep.solver.run import Run
from sidprep.solver.scene import load_scene
from sidprep.tables import read_toml_text

ROOT = Path(__file__).resolve().parents[2]
#: difference allowed to the numba kernels, relative to each array's largest entry: the same
#: arithmetic in the same order, so round-off of a few operations
RTOL = 1e-12
#: random states per layout
STATES = 3
#: the scenes whose flexible bodies the README's reduction makes ({scene folder: reduce commands})
REDUCED = {
    "engine": [[str(ROOT / "data/meshes/piston_rod.msh"), "-o", "piston_rod.sid.h5"]],
    "slider_crank": [["crank.msh", "--cutoff-factor", "10", "-o", "crank.sid.h5"],
                     [str(ROOT / "data/meshes/bar.msh"), "--cutoff-factor", "10", "-o", "conrod.sid.h5"]],
}
#: every scene of the examples that is not an absolute-nodal model
SCENES = [p for p in sorted((ROOT / "examples").glob("*/scene*.toml"))
          if not is_absolute_nodal_scene(read_toml_text(p, "scene file")[0])]


@pytest.fixture(scope="module")
def reduced(tmp_path_factory):
    """The folders of REDUCED copied, their SID files made by `sidprep reduce` ({name: folder})."""
    folders = {}
    for name, commands in REDUCED.items():
        folder = tmp_path_factory.mktemp(name)
        for f in (ROOT / "examples" / name).iterdir():
            if f.is_file():
                shutil.copy(f, folder / f.name)
        for args in commands:
            done = subprocess.run([sys.executable, "-m", "sidprep.cli.main", "reduce", *args, "-q", "--no-sid-fem",
                                   "--no-obj"], cwd=folder, capture_output=True, text=True)
            assert done.returncode == 0, done.stderr
        folders[name] = folder
    return folders


def sliding_on_a_beam():
    """A System no example has: a pinned-pinned steel beam carrying a rigid mass that slides with
    friction on its deformed axis (OnPath: the projection of the mass onto the path) and a
    moving mass driven along the axis by a table."""
    from sidprep.reduction.beam import beam_options_from_table, beam_sid
    from sidprep.solver import (Fixed, FlexibleBody, JointFriction, MovingMass, OnPath, RigidBody, System,
                                TabulatedMotion)

    sid = beam_sid(beam_options_from_table({"length": 15.0, "section": "rectangle:0.1,0.1", "E": 2.1e11, "nu": 0.3,
                                            "rho": 7850.0, "bc": "pinned-pinned", "modes": "xz:1-4",
                                            "frames": [0.5], "damping": 0.01}, "test"))
    s = System(gravity=(0.0, 0.0, -9.81))
    beam = s.add(FlexibleBody(sid, name="beam"))
    s.add(Fixed(s.ground.marker(), beam.marker(), name="supports"))
    along_x = np.array([0.0, np.pi / 2, 0.0])
    rail = beam.path_marker("axis", rotation=along_x, name="rail")
    mass = s.add(RigidBody(100.0, inertia=[1e-2, 1e-2, 1e-2], name="mass", position=(2.0, 0.0, 0.0)))
    slide = s.add(OnPath(rail, mass.marker(rotation=along_x), name="slide"))
    s.add(JointFriction(slide, 0.2, preload=10.0, name="friction"))
    cart = beam.path_marker("axis", TabulatedMotion([0.0, 1.0, 2.0, 3.0], [1.0, 4.0, 9.0, 16.0]), name="cart")
    s.add(MovingMass(cart, 50.0, name="cart_mass"))
    return s, 3.0, SolverSettings()


#: the scenes, and systems built here for what no scene has
CASES = SCENES + [sliding_on_a_beam]


def case_id(case) -> str:
    return f"{case.parent.name}/{case.stem}" if isinstance(case, Path) else case.__name__


def scene_run(case, reduced) -> Run:
    """The Run of a scene (REDUCED scenes from their copies) or of a system built here, its layout
    as a simulation builds it (the free lengths of springs given none: the marker distances at the
    initial pose)."""
    if isinstance(case, Path):
        folder = reduced.get(case.parent.name)
        scene = load_scene(folder / case.name if folder else case)
        run = Run(scene.system, scene.t_end, scene.settings)
    else:
        run = Run(*case())
    run.resolve_spring_lengths(*run.initial_positions()[:3])
    return run


def random_state(run: Run, rng):
    """(R, A, Q, u, t, lam, refs): the initial pose moved and turned at random, random modal
    coordinates, velocities, time, multipliers and angle references."""
    R, A, Q, u = run.initial_positions()
    L = run.L
    R = R + rng.normal(0.0, 0.05, R.shape)
    A = np.array([a @ exp_so3(rng.normal(0.0, 0.3, 3)) for a in A]).reshape(-1, 3, 3)
    Q = rng.normal(0.0, 1e-3, Q.shape)
    u = rng.normal(0.0, 1.0, u.shape)
    t = rng.uniform(0.0, run.t_end)
    m = int(L.joint_off[-1] + L.drv_joint.shape[0])
    return R, A, Q, u, t, rng.normal(0.0, 10.0, m), rng.normal(0.0, 1.0, L.joint_mk.shape[0])


def assert_equal_arrays(ours, theirs, what):
    """ours equals theirs to RTOL of theirs' largest entry (1 for arrays of zeros)."""
    theirs = np.asarray(theirs)
    assert np.isfinite(theirs).all(), what
    scale = max(np.abs(theirs).max(initial=0.0), 1.0 if not theirs.any() else 0.0)
    np.testing.assert_allclose(np.asarray(ours), theirs, rtol=0.0, atol=RTOL * scale, err_msg=what)


def layouts(run: Run):
    """The run's layout and the one with every marker active, each (numba namedtuple, core record)."""
    for L in (run.L, numba_kernels.every_marker(run.L)):
        yield L, layout_record(L)


@pytest.mark.parametrize("path", CASES, ids=case_id)
def test_evaluation_equals_numba(path, reduced):
    """Every field of evaluate_into's Evaluation and kinematics, then energies, the drives' power
    and the moving masses at the same state."""
    run = scene_run(path, reduced)
    rng = np.random.default_rng(7)
    for L, Lc in layouts(run):
        W, Wc = numba_kernels.evaluation_arrays(L), evaluation_arrays(Lc)
        for _ in range(STATES):
            R, A, Q, u, t, lam, refs = random_state(run, rng)
            numba_kernels.evaluate_into(L, W, R, A, Q, u, t, lam, refs)
            core.evaluate_into(Lc, Wc, R, A, Q, u, t, lam, refs)
            for name in numba_kernels.Evaluation._fields:
                if name != "kin":
                    assert_equal_arrays(getattr(Wc, name), getattr(W, name), f"{path}: Evaluation.{name}")
            for name in numba_kernels.MarkerKinematics._fields:
                assert_equal_arrays(getattr(Wc.kin, name), getattr(W.kin, name), f"{path}: kin.{name}")
            theirs = numba_kernels.energies(L, R, A, Q, u, W.M)
            assert_equal_arrays(core.energies(Lc, R, A, Q, u, Wc.M), theirs, f"{path}: energies")
            theirs = numba_kernels.constraint_power(L, W.B, W.bt, u, lam)
            assert_equal_arrays(core.constraint_power(Lc, Wc.B, Wc.bt, u, lam), theirs, f"{path}: constraint_power")
            ud = rng.normal(0.0, 1.0, u.shape)
            theirs = numba_kernels.moving_masses(L, W.kin, R, A, Q, u, ud, t)
            assert_equal_arrays(core.moving_masses(Lc, Wc.kin, R, A, Q, u, ud, t), theirs, f"{path}: moving_masses")
            assert core.has_moving_masses(Lc) == numba_kernels.has_moving_masses(L)
            assert load_stiffened(Lc.mk_k0) == numba_kernels.load_stiffened(L.mk_k0)


@pytest.mark.parametrize("path", CASES, ids=case_id)
def test_markers_equal_numba(path, reduced):
    """markers_into on its own (a workspace of its own, every marker active) at random states."""
    run = scene_run(path, reduced)
    rng = np.random.default_rng(11)
    L = numba_kernels.every_marker(run.L)
    Lc = layout_record(L)
    kin, kinc = numba_kernels.marker_arrays(L), marker_kinematics(Lc)
    for _ in range(STATES):
        R, A, Q, u, t, _, _ = random_state(run, rng)
        numba_kernels.markers_into(L, kin, R, A, Q, u, t)
        core.markers_into(Lc, kinc, R, A, Q, u, t)
        for name in numba_kernels.MarkerKinematics._fields:
            assert_equal_arrays(getattr(kinc, name), getattr(kin, name), f"{path}: markers_into {name}")
