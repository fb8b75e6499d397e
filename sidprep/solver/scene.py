"""Scene files (TOML) -> a ``sidprep.solver.System`` plus solver and output settings.

The format is documented with a complete example in ``docs/scenes.md``.  Tables::

    [scene]            name, title, gravity (m/s^2), effects ("auto" | "all" | [names]), planar
    [solver]           t_end, method, step, rho_inf, rtol, atol, static_start, newton_tol, deformation_limit,
                       energy_tol
    [output]           rate (samples/s), signals, plot, csv, animate
    [bodies.<name>]    type = "flexible" (sid, make, q0, qd0, effects) | "rigid" (mass, com,
                       inertia, obj); position, rotation, velocity, omega
    [markers.<name>]   body, position | node | node_index | path + motion keys, rotation | z_axis
    [joints.<name>]    type = spherical | revolute | cylindrical | prismatic | planar | fixed; markers
    [drivers.<name>]   joint, motion = constant_speed | smooth_start | table
    [forces.<name>]    type = point_force | point_torque | spring_damper | joint_force | joint_friction

Every problem raises one ``InputError`` line: ``<scene file>: [<table>] <key>: <problem>; <fix>``.
Paths (sid, obj) are relative to the scene file.  Units are SI.
"""

from __future__ import annotations

import difflib
import hashlib
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from sidprep.errors import InputError, SimulationFailed
from sidprep.sid.io import read_sid
from sidprep.solver.absolute_nodal.model import AbsoluteNodalModel
from sidprep.solver.absolute_nodal.scene import is_absolute_nodal_scene, load_absolute_nodal_scene
from sidprep.solver.core.rotations import as_rotation
from sidprep.solver.integrators.settings import SolverSettings
from sidprep.solver.model.bodies import FlexibleBody, RigidBody
from sidprep.solver.model.effects import EFFECTS
from sidprep.solver.model.forces import (JointForce, JointFriction, MovingMass, PointForce, PointTorque,
    SpringDamper, Table, bump_stop)
from sidprep.solver.model.joints import ConstantSpeed, Driver, JOINT_TYPES, SmoothStart, TabulatedMotion
from sidprep.solver.model.system import System
from sidprep.solver.results import BodyHistory, BodySource, JointHistory, Result, signal
from sidprep.solver.run import check_settings, simulate as simulate_system
from sidprep.solver.scene_tables import OutputSettings, read_output_settings, read_solver_settings
from sidprep.tables import TomlTable, read_toml_text, subtables


#: names a user may not give to bodies / markers / joints (they name other things in signals)
RESERVED_NAMES = ("ground", "energy")
#: |z_axis| and orthonormality of rotation matrices are checked to this tolerance
ROTATION_TOL = 1e-6


@dataclass(frozen=True)
class Scene:
    """A parsed scene.

    path : the scene file; text, sha256 : its content (provenance); name : what its outputs are
    called ([scene] name, else the folder of a ``scene.toml``, else the file's stem); title : [scene] title;
    system : the built System (an AbsoluteNodalModel for a scene of absolute-nodal beams);
    t_end : s; settings : the SolverSettings of [solver] and [output] rate (the solver's own
    defaults for every key not given); output : OutputSettings; sources : {body name: BodySource}
    (results provenance).
    """

    path: Path
    text: str
    sha256: str
    title: str
    system: object
    t_end: float
    settings: SolverSettings
    output: OutputSettings
    sources: dict = field(default_factory=dict)
    name: str = ""

    def provenance(self) -> dict:
        return {"path": str(self.path), "sha256": self.sha256, "text": self.text}


# ---------------------------------------------------------------------------------------------
# typed access to one TOML table


# ---------------------------------------------------------------------------------------------
# the tables


def _effects(t: TomlTable, key: str, default):
    v = t.raw(key, default)
    if v is None or v in ("auto", "all"):
        return v
    names = [v] if isinstance(v, str) else v
    if not isinstance(names, list) or not all(isinstance(x, str) for x in names):
        t.fail(key, f"must be \"auto\", \"all\" or a list of effect names, got {v!r}", 'write e.g. effects = ["gravity"]')
    bad = [x for x in names if x not in EFFECTS]
    if bad:
        t.fail(key, f"unknown effect {bad[0]!r}", f"use \"auto\", \"all\" or names from: {', '.join(EFFECTS)}")
    return names


def _missing_sid(t: TomlTable, path: Path) -> None:
    make = t.string("make", None)
    fix = f"make it with `{make}` (run in {t.file.parent})" if make else \
        "make it with `sidprep reduce MESH -o <file>` or fix the path (relative to the scene file)"
    t.fail("sid", f"SID file {path} not found", fix)


def _flexible_body(name: str, t: TomlTable, pose: dict):
    path = t.path("sid")
    if not path.is_file():
        _missing_sid(t, path)
    t.string("make", None)
    try:
        sid = read_sid(path, physical="error")
    except InputError as exc:         # names the file, the problem and the fix already
        raise InputError(f"{t.file}: [{t.where}] sid: {exc}") from None
    q0 = t.array("q0", None, shape=(sid.nq,))
    qd0 = t.array("qd0", None, shape=(sid.nq,))
    body = FlexibleBody(sid, name=name, q0=q0, qd0=qd0, effects=_effects(t, "effects", None), source=str(path),
                        **pose)
    return body, BodySource("flexible", str(path.resolve()))  # absolute: found from any folder later


def _beam_body(name: str, t: TomlTable, pose: dict):
    """An analytical Euler-Bernoulli Beam declared inline (sidprep.reduction.beam: its SID in memory)."""
    # deferred: 14 CPU-ms of imports (the FE side's analytical beam) that scenes without inline beams skip
    from sidprep.reduction.beam import BEAM_TABLE_KEYS, beam_options_from_table, beam_sid

    beam = {key: t.raw(key) for key in BEAM_TABLE_KEYS if t.has(key)}
    sid = beam_sid(beam_options_from_table(beam, f"{t.file}: [{t.where}]"))
    q0 = t.array("q0", None, shape=(sid.nq,))
    qd0 = t.array("qd0", None, shape=(sid.nq,))
    body = FlexibleBody(sid, name=name, q0=q0, qd0=qd0, effects=_effects(t, "effects", None), **pose)
    return body, BodySource("beam")


def _rigid_body(name: str, t: TomlTable, pose: dict):
    mass = t.number("mass", positive=True)
    inertia = t.array("inertia")
    if inertia.shape not in ((3,), (6,), (3, 3)):
        t.fail("inertia", f"shape {inertia.shape} is not 3 (principal), 6 ([Ixx, Iyy, Izz, Ixy, Ixz, Iyz]) or 3x3",
               "give the inertia about the centre of mass in kg m^2")
    obj = t.path("obj", None)
    if obj is not None and not obj.is_file():
        t.fail("obj", f"OBJ file {obj} not found", "fix the path (relative to the scene file) or remove `obj`")
    body = RigidBody(mass, t.vector("com", [0.0, 0.0, 0.0]), inertia, name=name, obj=obj, **pose)
    return body, BodySource("rigid", "" if obj is None else str(obj))


#: body tables by their `type`: a SID file, an inline analytical beam, a rigid body
BODY_TYPES = {"flexible": _flexible_body, "beam": _beam_body, "rigid": _rigid_body}


def _bodies(file: Path, root: dict, system) -> dict:
    sources = {}
    for name, t in subtables(file, root, "bodies"):
        kind = t.string("type", choices=tuple(BODY_TYPES))
        pose = {"position": t.vector("position", None), "rotation": _rotation(t),
                "velocity": t.vector("velocity", None), "omega": t.vector("omega", None)}
        body, sources[name] = BODY_TYPES[kind](name, t, pose)
        t.finish()
        system.add(body)
    if not sources:
        raise InputError(f"{file}: no bodies; add at least one [bodies.<name>] table with type = \"flexible\", \"beam\" or \"rigid\"")
    return sources


def _rotation(t: TomlTable, key: str = "rotation") -> np.ndarray | None:
    """A rotation matrix from a 3x3 matrix (orthonormal, det +1) or a rotation vector (rad)."""
    if not t.has(key):
        return None
    a = t.array(key)
    if a.shape not in ((3,), (3, 3)):
        t.fail(key, f"must be a rotation vector (3 numbers, rad) or a 3x3 matrix, got shape {a.shape}",
               f"write e.g. `{key} = [0.0, 0.0, 1.5708]`")
    if a.shape == (3, 3) and (np.max(np.abs(a @ a.T - np.eye(3))) > ROTATION_TOL or np.linalg.det(a) < 0):
        t.fail(key, "is not a rotation matrix (not orthonormal with det +1)",
               "give the body->inertial rotation matrix rows, or a rotation vector")
    return as_rotation(a)


def _z_axis_rotation(t: TomlTable) -> np.ndarray:
    """A rotation whose third column is the unit vector ``z_axis`` (the joint axis) and whose x
    axis is the first body axis (x, else y) not near z, made normal to z: z = [0, 0, 1] keeps
    the body axes, so a joint angle is measured from the body's x axis."""
    z = t.vector("z_axis")
    norm = np.linalg.norm(z)
    if norm < ROTATION_TOL:
        t.fail("z_axis", "is the zero vector", "give the joint axis direction, e.g. [0, 1, 0]")
    z = z / norm
    helper = np.eye(3)[0] if abs(z[0]) < 0.9 else np.eye(3)[1]
    x = helper - (helper @ z) * z
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


def _markers(file: Path, root: dict, system) -> dict:
    bodies = {b.name: b for b in system.bodies}
    markers = {}
    for name, t in subtables(file, root, "markers"):
        body_name = t.string("body")
        if body_name != "ground" and body_name not in bodies:
            t.fail("body", f"no body {body_name!r}", f"use \"ground\" or one of: {', '.join(bodies)}")
        body = system.ground if body_name == "ground" else bodies[body_name]
        if t.has("rotation") and t.has("z_axis"):
            t.fail("z_axis", "given together with `rotation`", "give only one of them")
        rotation = _z_axis_rotation(t) if t.has("z_axis") else _rotation(t)
        on_node = t.has("node") or t.has("node_index")
        if t.has("path"):
            if not isinstance(body, FlexibleBody):
                t.fail("path", f"body {body_name!r} is not flexible", "put moving markers on a flexible body or Beam")
            if on_node or t.has("position"):
                t.fail("path", "given together with a node or position", "a path marker's position is s(t) on the path")
            try:
                m = body.path_marker(t.string("path"), _motion(t) if t.has("motion") else None, rotation=rotation,
                                     name=name)
            except ValueError as exc:
                t.fail("path", str(exc).split("; ")[0], str(exc).split("; ")[-1])
        elif on_node:
            if not isinstance(body, FlexibleBody):
                t.fail("node", f"body {body_name!r} is not flexible", "use `position` on rigid bodies and ground")
            if t.has("position"):
                t.fail("position", "given together with a node", "give either `node`/`node_index` or `position`")
            m = _node_marker(t, body, name)
            if rotation is not None:
                m.rotation = rotation           # marker -> K at q = 0 instead of the node's AP0
        else:
            m = body.marker(t.vector("position", [0.0, 0.0, 0.0]), rotation, name=name)
        t.finish()
        markers[name] = m
    return markers


def _node_marker(t: TomlTable, body, name: str):
    if t.has("node") and t.has("node_index"):
        t.fail("node_index", "given together with `node`", "give the FE node number `node` or the 0-based `node_index`")
    if t.has("node"):
        node_id = t.integer("node")
        ids = [n.node_id for n in body.sid.nodes]
        if node_id not in ids:
            t.fail("node", f"the SID of body {body.name!r} has no node {node_id}",
                   f"use one of its node numbers: {', '.join(map(str, ids[:12]))}{' ...' if len(ids) > 12 else ''}")
        return body.node_marker(node_id=node_id, name=name)
    index = t.integer("node_index")
    if not 0 <= index < len(body.sid.nodes):
        t.fail("node_index", f"must be in 0..{len(body.sid.nodes) - 1}", "count the SID nodes from 0")
    return body.node_marker(index, name=name)


def _lookup(t: TomlTable, key: str, table: dict, what: str):
    name = t.string(key)
    if name not in table:
        t.fail(key, f"no {what} {name!r}", f"define [{what}s.{name}] or use one of: {', '.join(table) or '(none)'}")
    return table[name]


def _marker_pair(t: TomlTable, markers: dict):
    pair = t.strings("markers")
    if len(pair) != 2:
        t.fail("markers", f"needs exactly 2 marker names, got {len(pair)}", 'write markers = ["on_body_1", "on_body_2"]')
    for m in pair:
        if m not in markers:
            t.fail("markers", f"no marker {m!r}", f"define [markers.{m}] or use one of: {', '.join(markers) or '(none)'}")
    return markers[pair[0]], markers[pair[1]]


def _joints(file: Path, root: dict, system, markers: dict) -> dict:
    joints = {}
    for name, t in subtables(file, root, "joints"):
        cls = JOINT_TYPES[t.string("type", choices=tuple(JOINT_TYPES))]
        m1, m2 = _marker_pair(t, markers)
        if m1.body is m2.body:
            t.fail("markers", f"both markers are on body {m1.body.name!r}", "join markers on two different bodies")
        initial, rate = t.number("initial", None), t.number("initial_rate", None)
        if (initial is not None or rate is not None) and cls.kind not in ("revolute", "cylindrical", "prismatic"):
            t.fail("initial", f"a {cls.kind} joint has no coordinate to start from",
                   "give initial / initial_rate on a revolute, cylindrical or prismatic joint")
        t.finish()
        if cls.kind == "on_path":
            try:
                joints[name] = system.add(cls(m1, m2, name=name))
            except ValueError as exc:
                t.fail("markers", str(exc).split(": ", 1)[-1], "see docs/scenes.md, path markers")
            continue
        joints[name] = system.add(cls(m1, m2, name=name, initial=initial, initial_rate=rate))
    return joints


def _motion(t: TomlTable):
    kind = t.string("motion", choices=("constant_speed", "smooth_start", "table"))
    if kind == "constant_speed":
        return ConstantSpeed(t.number("speed"), t.number("start", 0.0))
    if kind == "smooth_start":
        return SmoothStart(t.number("speed"), t.number("ramp_time", positive=True), t.number("start", 0.0))
    times, values = t.array("times", shape=(-1,)), t.array("values", shape=(-1,))
    if len(times) < 2 or len(values) != len(times) or np.any(np.diff(times) <= 0):
        t.fail("times", "needs >= 2 strictly increasing times and as many values", "fix the table")
    return TabulatedMotion(times, values)


def _drivers(file: Path, root: dict, system, joints: dict) -> dict:
    drivers = {}
    for name, t in subtables(file, root, "drivers"):
        joint = _lookup(t, "joint", joints, "joint")
        if joint.coordinate_kind is None:
            t.fail("joint", f"a {joint.kind} joint has no coordinate to drive", "drive a revolute, cylindrical or prismatic joint")
        drivers[name] = system.add(Driver(joint, _motion(t), name=name))
        t.finish()
    return drivers


def _load_value(t: TomlTable, joints: dict):
    """Constant vector / scalar `value`, or a `table` {x, y, period} over time or `argument` joint."""
    argument = _lookup(t, "argument", joints, "joint") if t.has("argument") else None
    if t.has("table"):
        tt = TomlTable(t.file, f"{t.where}.table", t.raw("table"))
        try:
            value = Table(tt.array("x", shape=(-1,)), tt.array("y"), tt.number("period", None, positive=True))
        except ValueError as exc:
            tt.fail("x", str(exc), "give strictly increasing x and one y row per x")
        tt.finish()
    else:
        value = t.array("value")
        if value.shape not in ((), (3,)):
            t.fail("value", f"must be a number (with `direction`) or 3 numbers, got shape {value.shape}", "fix the value")
    return value, argument


def _forces(file: Path, root: dict, system, markers: dict, joints: dict) -> None:
    kinds = ("point_force", "point_torque", "spring_damper", "joint_force", "joint_friction", "moving_mass")
    for name, t in subtables(file, root, "forces"):
        kind = t.string("type", choices=kinds)
        if kind in ("point_force", "point_torque"):
            marker = _lookup(t, "marker", markers, "marker")
            value, argument = _load_value(t, joints)
            cls = PointForce if kind == "point_force" else PointTorque
            element = cls(marker, value, direction=t.vector("direction", None),
                          frame=t.string("frame", "inertial", ("inertial", "marker")), argument=argument, name=name)
        elif kind == "spring_damper":
            m1, m2 = _marker_pair(t, markers)
            stop = t.raw("bump_stop", None)
            law = None
            if stop is not None:
                st = TomlTable(file, f"forces.{name}.bump_stop", stop)
                law = bump_stop(st.number("clearance", nonnegative=True), st.number("stiffness", nonnegative=True),
                                    st.number("exponent", 1.0, positive=True), st.number("damping", 0.0, nonnegative=True))
                st.finish()
            length = t.number("length", None, nonnegative=True)
            element = SpringDamper(m1, m2, t.number("stiffness", 0.0, nonnegative=True),
                                       t.number("damping", 0.0, nonnegative=True),
                                       length, law=law, name=name)
        elif kind == "joint_force":
            joint = _lookup(t, "joint", joints, "joint")
            if joint.coordinate_kind is None:
                t.fail("joint", f"a {joint.kind} joint has no coordinate", "use a revolute, cylindrical or prismatic joint")
            element = JointForce(joint, stiffness=t.number("stiffness", 0.0), damping=t.number("damping", 0.0),
                                     reference=t.number("reference", 0.0), constant=t.number("constant", 0.0),
                                     name=name)
        elif kind == "moving_mass":
            try:
                element = MovingMass(_lookup(t, "marker", markers, "marker"), t.number("mass", positive=True),
                                         name=name)
            except ValueError as exc:
                t.fail("marker", str(exc).split(": ", 1)[-1].split("; ")[0], "give a marker with `path` and a motion")
        else:
            joint = _lookup(t, "joint", joints, "joint")
            try:
                element = JointFriction(joint, t.number("mu", nonnegative=True), radius=t.number("radius", 0.0),
                                            preload=t.number("preload", 0.0, nonnegative=True),
                                            regularisation=t.number("regularisation", 1e-3, positive=True), name=name)
            except ValueError as exc:
                t.fail("joint", str(exc), "see docs/scenes.md, [forces] joint_friction")
        t.finish()
        system.add(element)


def _check_names(file: Path, root: dict) -> None:
    """Body, marker, joint, driver and force names share one namespace (signal names use them)."""
    seen: dict[str, str] = {}
    for group in ("bodies", "markers", "joints", "drivers", "forces"):
        entries = root.get(group, {})
        for name in entries if isinstance(entries, dict) else ():
            if name in RESERVED_NAMES or "." in name:
                raise InputError(f"{file}: [{group}.{name}]: the name {name!r} is reserved or contains '.'; "
                                 "rename it")
            if name in seen:
                raise InputError(f"{file}: [{group}.{name}]: the name {name!r} is also used in [{seen[name]}]; "
                                 "give every body, marker, joint, driver and force its own name")
            seen[name] = f"{group}.{name}"


def empty_result(system):
    """A Result with no samples but every body, joint, marker and energy of ``system``: what the
    signal names of a run will be (sidprep/solver/results.py ``signal_names``), known before running it."""
    if isinstance(system, AbsoluteNodalModel):
        from sidprep.solver.absolute_nodal.results import initial_result  # deferred: 28 CPU-ms, its kernels
        return initial_result(system)

    z = np.zeros((0, 3))
    return Result(
        t=np.zeros(0),
        bodies={b.name: BodyHistory(b.name, z, np.zeros((0, 3, 3)), z, z, np.zeros((0, b.nq)), np.zeros((0, b.nq)),
                                    np.zeros((0, 6 + b.nq))) for b in system.bodies},
        joints={c.name: JointHistory(c.name, getattr(c, "kind", "driver"), z, z, z, z, np.zeros(0), np.zeros(0),
                                     np.zeros(0)) for c in list(system.joints) + list(system.drivers)},
        markers={m.name: z for b in [system.ground] + list(system.bodies) for m in b.markers},
        energy={k: np.zeros(0) for k in ("kinetic", "strain", "gravity", "spring", "dissipated", "external", "stiffening",
                                         "total")},
        constraint_error=np.zeros(0), effects=None)


def _check_signals(file: Path, scene_signals, system) -> None:
    """Every requested signal must exist (checked on an empty Result of this system) and have values:
    a joint's effort is reported by its driver only, its coordinate and rate only for a joint with a
    coordinate (the results hold NaN for the others)."""
    empty = empty_result(system)
    for name in scene_signals:
        try:
            signal(empty, name)
        except InputError as exc:
            raise InputError(f"{file}: [output] signals: {exc}") from None
        problem = _undefined_joint_signal(name, system)
        if problem:
            raise InputError(f"{file}: [output] signals: {name!r}: {problem}")


def _undefined_joint_signal(name: str, system) -> str | None:
    """Why the joint signal ``name`` has no values in any run of ``system`` (with the fix), or None."""
    entity, _, qty = name.partition(".")
    joint = next((j for j in system.joints if j.name == entity), None)
    if joint is None:
        return None
    drivers = [d.name for d in system.drivers if d.joint is joint]
    if qty == "effort":
        fix = (f"use {' or '.join(n + '.effort' for n in drivers)} (its driver carries the load)" if drivers
               else "the load a joint carries is <joint>.force_local.<x|y|z> and <joint>.torque_local.<x|y|z>")
        return f"joint {entity!r} has no effort of its own, only a driver reports one; {fix}"
    if qty in ("coordinate", "rate") and joint.coordinate_kind is None:
        return (f"a {joint.kind} joint has no coordinate; use <joint>.force.<x|y|z> or the markers' positions, or a "
                "revolute, cylindrical or prismatic joint")
    return None


def scene_name(path: Path, head: TomlTable) -> str:
    """[scene] name, else the folder's name of a file called ``scene.toml``, else the file's stem:
    what the scene's outputs are called (``<name>.results.h5``)."""
    default = path.resolve().parent.name if path.stem == "scene" else path.stem
    name = head.string("name", default or path.stem)
    if not name or name != Path(name).name or name.startswith("."):
        head.fail("name", f"{name!r} is not a file name", 'write e.g. name = "pendulum" (no folders)')
    return name


def load_scene(path, *, t_end: float | None = None) -> Scene:
    """Parse the scene file ``path`` and build its System; ``t_end`` overrides [solver] t_end."""
    path = Path(path)
    root, text = read_toml_text(path, "scene file")
    sha256 = hashlib.sha256(text.encode()).hexdigest()
    if is_absolute_nodal_scene(root):
        an = load_absolute_nodal_scene(root, path, t_end=t_end)
        return Scene(path=path, text=text, sha256=sha256, title=an.model.title, system=an.model, t_end=an.t_end,
                     settings=an.settings, output=an.output,
                     sources={b.name: BodySource("absolute_nodal") for b in an.model.beams},
                     name=scene_name(path, TomlTable(path, "scene", root.get("scene", {}))))
    known = ("scene", "solver", "output", "bodies", "markers", "joints", "drivers", "forces")
    for key in root:
        if key not in known:
            close = difflib.get_close_matches(key, known, n=1)
            raise InputError(f"{path}: unknown top-level table or key `{key}`; "
                             + (f"did you mean [{close[0]}]?" if close else f"use: {', '.join(known)}"))
    _check_names(path, root)
    head = TomlTable(path, "scene", root.get("scene", {}))
    planar = head.raw("planar", "auto")
    if planar not in ("auto", True, False):
        head.fail("planar", f"must be \"auto\", true or false, got {planar!r}",
                  "use \"auto\" (detect planar scenes), true (require one) or false (always 3D)")
    system = System(gravity=head.vector("gravity", [0.0, 0.0, -9.81]), effects=_effects(head, "effects", "auto"),
                    planar=None if planar == "auto" else planar)
    title = head.string("title", path.stem)
    name = scene_name(path, head)
    head.finish()
    output = read_output_settings(path, root)
    t_end, settings = read_solver_settings(TomlTable(path, "solver", root.get("solver", {})), output, t_end)
    sources = _bodies(path, root, system)
    markers = _markers(path, root, system)
    joints = _joints(path, root, system, markers)
    _drivers(path, root, system, joints)
    _forces(path, root, system, markers, joints)
    _check_signals(path, output.signals, system)
    return Scene(path=path, text=text, sha256=sha256, title=title, system=system, t_end=t_end, settings=settings,
                 output=output, sources=sources, name=name)


def simulate(scene: Scene, settings: SolverSettings | None = None, *, t_end: float | None = None, **overrides):
    """Run the scene -> sidprep.solver.Result: its System (or absolute-nodal model) to t_end
    (the scene's unless given) with ``settings`` (the scene's when None) and ``overrides`` of
    their fields by name (e.g. h=1e-4; None keeps the scene's value).

    The solver's own InputErrors (e.g. Newton failure, joints that cannot close) are re-raised
    with the scene file named first.
    """
    given = {key: value for key, value in overrides.items() if value is not None}
    try:
        settings = replace(settings or scene.settings, **given)
        t_end = scene.t_end if t_end is None else t_end
        check_settings(settings, t_end)
        if isinstance(scene.system, AbsoluteNodalModel):
            from sidprep.solver.absolute_nodal.run import simulate_absolute_nodal  # deferred: 28 CPU-ms, its kernels
            return simulate_absolute_nodal(scene.system, t_end, settings)
        return simulate_system(scene.system, t_end, settings)
    except SimulationFailed as exc:
        raise SimulationFailed(f"{scene.path}: {exc}", exc.result) from None
    except InputError as exc:
        raise InputError(f"{scene.path}: {exc}") from None
