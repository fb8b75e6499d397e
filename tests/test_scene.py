"""TOML scenes: what a scene builds, and the one-line error for every kind of bad entry.

Physics reference: a rigid physical pendulum built from a scene, small amplitude, against
theta(t) = theta0 cos(omega t), omega^2 = m g d / I_pivot (closed form).
"""

from pathlib import Path

import numpy as np
import pytest

from sidprep.errors import InputError
from sidprep.sid.io.sid_hdf5 import write_sid_hdf5
from sidprep.sid.model import sid_invariants
from sidprep.solver.results import BodySource
from sidprep.solver.run import simulate as simulate_system
from sidprep.solver.scene import load_scene, simulate

#: relative error of the small-angle pendulum (amplitude 0.01 rad: nonlinearity ~ theta0^2 / 16)
PENDULUM_RTOL = 2e-3

TINY_SCENE = """
[scene]
title = "tiny"
gravity = [0, 0, -9.81]

[solver]
t_end = 0.05
step = 1e-3

[output]
rate = 100
signals = ["tip.position.z", "hinge.coordinate", "energy.total", "bar.q.2"]

[bodies.bar]
type = "flexible"
sid = "tiny.sid.h5"
make = "python make_tiny.py"

[markers.pivot]
body = "ground"
z_axis = [0, 1, 0]

[markers.root]
body = "bar"
node = 1
z_axis = [0, 1, 0]

[markers.tip]
body = "bar"
node_index = 1

[joints.hinge]
type = "revolute"
markers = ["pivot", "root"]
"""


def tiny_sid():
    """A 5-point-mass bar along x (1 kg, 1 m) with two bending shapes, nodes 1 (root) and 5 (tip)."""
    n = 5
    X = np.zeros((n, 3))
    X[:, 0] = np.linspace(0.0, 1.0, n)
    Phi = np.zeros((3 * n, 2))
    Phi[2::3, 0] = Phi[1::3, 1] = X[:, 0] ** 2
    nodes = [(1, X[0], Phi[0:3]), (5, X[-1], Phi[-3:])]
    return sid_invariants(X, np.diag(np.full(n, 0.2)), Phi, nodes, frequencies_hz=[10.0, 15.0])


@pytest.fixture
def scene_dir(tmp_path):
    write_sid_hdf5(tiny_sid(), tmp_path / "tiny.sid.h5")
    (tmp_path / "scene.toml").write_text(TINY_SCENE)
    return tmp_path


def write(folder, text, name="scene.toml"):
    path = folder / name
    path.write_text(text)
    return path


def test_scene_builds_the_system(scene_dir):
    scene = load_scene(scene_dir / "scene.toml", t_end=0.02)
    assert scene.title == "tiny" and scene.t_end == 0.02 and scene.settings.output_dt == 0.01
    (bar,) = scene.system.bodies
    assert bar.name == "bar" and bar.nq == 2 and scene.sources["bar"].kind == "flexible"
    (hinge,) = scene.system.joints
    assert hinge.kind == "revolute" and hinge.name == "hinge"
    root = hinge.marker2
    assert np.allclose(root.rotation[:, 2], [0, 1, 0]) and np.allclose(root.rotation.T @ root.rotation, np.eye(3))
    result = simulate(scene)
    assert result.t[-1] == pytest.approx(0.02) and set(result.joints) == {"hinge"}
    assert np.allclose(result.markers["root"], 0.0, atol=1e-9)            # the hinge point stays put


def test_rigid_pendulum_from_scene_matches_small_angle_solution(tmp_path):
    m, length, theta0 = 2.0, 0.8, 0.01
    i_cm = m * length**2 / 12
    omega = np.sqrt(m * 9.81 * length / 2 / (i_cm + m * length**2 / 4))
    period = 2 * np.pi / omega
    path = write(tmp_path, f"""
[solver]
t_end = {period}
step = 5e-4
rho_inf = 1.0
[output]
rate = 200
[bodies.rod]
type = "rigid"
mass = {m}
com = [0, 0, {-length / 2}]
inertia = [{i_cm}, {i_cm}, 0.0]
rotation = [0, {theta0}, 0]
[markers.pivot]
body = "ground"
z_axis = [0, 1, 0]
[markers.top]
body = "rod"
z_axis = [0, 1, 0]
[joints.hinge]
type = "revolute"
markers = ["pivot", "top"]
""")
    result = simulate(load_scene(path))
    angle = result.joints["hinge"].coordinate
    expected = theta0 * np.cos(omega * result.t)
    assert np.max(np.abs(angle - expected)) <= PENDULUM_RTOL * theta0


BAD_ENTRIES = [
    # (edit of the tiny scene, words the one-line message must contain)
    (lambda s: s.replace('sid = "tiny.sid.h5"', 'sid = "gone.sid.h5"'), ["[bodies.bar] sid", "not found", "python make_tiny.py"]),
    (lambda s: s.replace("t_end = 0.05", "t_end = -1"), ["[solver] t_end", "> 0"]),
    (lambda s: s.replace("t_end = 0.05", 't_end = "long"'), ["[solver] t_end", "number"]),
    (lambda s: s.replace("step = 1e-3", "stepp = 1e-3"), ["[solver] stepp", "unknown key", "did you mean `step`"]),
    (lambda s: s.replace('type = "revolute"', 'type = "hinge"'), ["[joints.hinge] type", "spherical", "revolute"]),
    (lambda s: s.replace('markers = ["pivot", "root"]', 'markers = ["pivot", "nowhere"]'), ["[joints.hinge] markers", "nowhere"]),
    (lambda s: s.replace('markers = ["pivot", "root"]', 'markers = ["root", "tip"]'), ["both markers are on body"]),
    (lambda s: s.replace("node = 1\n", "node = 3\n"), ["[markers.root] node", "no node 3", "1, 5"]),
    (lambda s: s.replace("node_index = 1", "node_index = 7"), ["[markers.tip] node_index", "0..1"]),
    (lambda s: s.replace('body = "bar"\nnode = 1', 'body = "arm"\nnode = 1'), ["[markers.root] body", "'arm'", "bar"]),
    (lambda s: s.replace("z_axis = [0, 1, 0]\n\n[markers.root]", "z_axis = [0, 0, 0]\n\n[markers.root]"), ["z_axis", "zero vector"]),
    (lambda s: s.replace("gravity = [0, 0, -9.81]", "gravity = [0, -9.81]"), ["[scene] gravity", "shape 3"]),
    (lambda s: s.replace('title = "tiny"', 'title = "tiny"\neffects = ["gravity", "magic"]'), ["[scene] effects", "'magic'", "coriolis"]),
    (lambda s: s.replace('"bar.q.2"', '"bar.q.3"'), ["[output] signals", "bar.q.3"]),
    (lambda s: s.replace("[markers.tip]", "[markers.bar]"), ["[markers.bar]", "also used in [bodies.bar]"]),
    (lambda s: s.replace("[solver]", "[solvr]"), ["unknown top-level", "did you mean [solver]"]),
    (lambda s: s.replace('title = "tiny"', 'title = "tiny"\nplanar = "yes"'), ["[scene] planar", "true or false"]),
    (lambda s: s + "\n[bodies.box]\ntype = \"rigid\"\nmass = 1.0\n", ["[bodies.box] inertia", "missing"]),
    (lambda s: s + "\n[bodies.box]\ntype = \"rigid\"\nmass = 1.0\ninertia = [1, 1]\n", ["[bodies.box] inertia", "kg m^2"]),
    (lambda s: s + "\n[bodies.box]\ntype = \"rigid\"\nmass = 1\ninertia = [1,1,1]\nrotation = [[1,0,0],[0,1,0],[0,0,2]]\n",
     ["[bodies.box] rotation", "not a rotation matrix"]),
    (lambda s: s + "\n[forces.push]\ntype = \"point_force\"\nmarker = \"tip\"\nvalue = [1, 2]\n", ["[forces.push] value", "3 numbers"]),
    (lambda s: s + "\n[drivers.motor]\njoint = \"hinge\"\nmotion = \"warp\"\n", ["[drivers.motor] motion", "constant_speed"]),
    (lambda s: s + "\n[forces.spring]\ntype = \"spring_damper\"\nmarkers = [\"pivot\"]\n", ["[forces.spring] markers", "exactly 2"]),
    (lambda s: s.replace("[output]", "[output\n"), ["TOML syntax error"]),
]


@pytest.mark.parametrize("edit, words", BAD_ENTRIES)
def test_bad_entry_gives_one_line_input_error(scene_dir, edit, words):
    path = write(scene_dir, edit(TINY_SCENE))
    with pytest.raises(InputError) as err:
        load_scene(path)
    message = str(err.value)
    assert "\n" not in message and message.startswith(str(path))
    for w in words:
        assert w in message, message


def test_forces_drivers_and_rigid_obj_are_built(scene_dir):
    (scene_dir / "box.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    extra = """
[bodies.box]
type = "rigid"
mass = 1.0
inertia = [0.1, 0.1, 0.1, 0.0, 0.0, 0.0]
obj = "box.obj"
position = [0, 0, -1]

[markers.box_top]
body = "box"

[markers.hook]
body = "ground"
position = [0, 0, -0.5]

[forces.spring]
type = "spring_damper"
markers = ["hook", "box_top"]
stiffness = 100.0
damping = 1.0
bump_stop = { clearance = 0.1, stiffness = 1e4 }

[forces.push]
type = "point_force"
marker = "tip"
table = { x = [0.0, 1.0], y = [[0, 0, 0], [0, 0, 10]] }

[forces.spring_hinge]
type = "joint_force"
joint = "hinge"
stiffness = 5.0

[drivers.none_here]
joint = "hinge"
motion = "smooth_start"
speed = 1.0
ramp_time = 0.5
"""
    scene = load_scene(write(scene_dir, TINY_SCENE + extra))
    s = scene.system
    assert [type(f).__name__ for f in s.forces] == ["SpringDamper", "PointForce", "JointForce"]
    assert len(s.drivers) == 1 and scene.sources["box"] == BodySource("rigid", str(scene_dir / "box.obj"))
    assert s.forces[0].length is None                         # default: the marker distance at the start
    r = simulate_system(s, 2e-3, h=1e-3)
    assert s.forces[0].length is None                         # the run resolved it, the model is unchanged
    assert abs(r.energy["spring"][0]) < 1e-12                 # unstretched at the start
    joint_force = s.forces[2]
    assert (joint_force.stiffness, joint_force.damping, joint_force.constant) == (5.0, 0.0, 0.0)
    assert np.allclose(s.forces[1].value(0.5), [0, 0, 5])     # table interpolated over time


def test_the_complete_example_of_the_documentation_builds(tmp_path):
    root = Path(__file__).resolve().parents[1]
    doc = (root / "docs/scenes.md").read_text()
    text = doc.split("```toml\n", 1)[1].split("```", 1)[0]
    sid = (root / "examples/flexible_pendulum/bar.sid.h5").as_posix()
    (tmp_path / "block.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    scene = load_scene(write(tmp_path, text.replace('sid = "bar.sid.h5"', f'sid = "{sid}"')))
    s = scene.system
    assert [b.name for b in s.bodies] == ["bar", "block"] and [j.kind for j in s.joints] == ["revolute"]
    assert [type(f).__name__ for f in s.forces] == ["SpringDamper", "PointForce", "JointFriction"]
    assert scene.output.signals[0] == "hinge.coordinate" and scene.settings.h == 1e-3
    assert s.planar is None                                    # "auto"


def test_the_python_mirror_of_the_documentation_runs(tmp_path, monkeypatch):
    root = Path(__file__).resolve().parents[1]
    code = (root / "docs/scenes.md").read_text().split("```python\n", 1)[1].split("```", 1)[0]
    code = code.replace("examples/", f"{root.as_posix()}/examples/").replace("simulate(system, 1.0,", "simulate(system, 0.02,")
    monkeypatch.chdir(tmp_path)
    namespace = {}
    exec(compile(code, "docs/scenes.md", "exec"), namespace)
    toml = load_scene(root / "examples/flexible_pendulum/scene.toml", t_end=0.02)
    assert np.allclose(namespace["result"].joints["hinge"].coordinate, simulate(toml).joints["hinge"].coordinate,
                       rtol=0, atol=1e-12)                    # script and scene are the same model
    assert (tmp_path / "pendulum.png").is_file()
