"""Scene files of absolute-nodal beams: the [beams], [supports], [drivers] and [forces] tables
(docs/scenes.md), with the [solver] and [output] tables every scene has (sidprep/solver/scene_tables.py)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from sidprep.errors import InputError
from sidprep.solver.absolute_nodal.model import AbsoluteNodalModel, Beam, Driver, NodalForce, Support
from sidprep.solver.integrators.settings import SolverSettings
from sidprep.solver.results import signal
from sidprep.solver.scene_tables import OutputSettings, read_output_settings, read_solver_settings
from sidprep.tables import TomlTable, subtables

#: RK4 step of a scene that gives none, s (the two-link manipulator of Kisu Lee's paper resolved)
DEFAULT_STEP = 2.5e-4
#: the top-level tables of an absolute-nodal scene file
SCENE_TABLES = ("scene", "solver", "output", "beams", "supports", "drivers", "forces")


@dataclass(frozen=True)
class AbsoluteNodalScene:
    """A parsed absolute-nodal scene: the model, t_end (s), the RK4 settings and the output settings."""

    model: AbsoluteNodalModel
    t_end: float
    settings: SolverSettings
    output: OutputSettings


def is_absolute_nodal_scene(root: dict) -> bool:
    """True when a parsed scene TOML describes absolute-nodal beams (it has [beams.<name>] tables)."""
    return "beams" in root


def _angle(t, key: str, default: float = 0.0) -> float:
    """``key`` in rad or ``key_deg`` in degrees (not both); rad."""
    if t.has(key) and t.has(key + "_deg"):
        t.fail(key, f"given both as {key} (rad) and {key}_deg", "keep one of them")
    if t.has(key + "_deg"):
        return math.radians(t.number(key + "_deg"))
    return t.number(key, default)


def load_absolute_nodal_scene(root: dict, source, t_end: float | None = None) -> AbsoluteNodalScene:
    """Parse a scene TOML (already read: ``root``) of absolute-nodal beams.

    Tables: [scene] title, gravity = [gx, gy] (m/s^2, X-Y plane), gravity_zero = "origin" |
    "hanging"; [solver] method = "rk4", t_end (s), step (s); [output] as every scene;
    [beams.<name>] length (m), mass (kg), EI (N m^2), EA (N), elements, points = [start, end],
    angle (rad) | angle_deg, rate (rad/s) | rate_deg; [supports.<name>] point, position = [x, y];
    [drivers.<name>] support, beam, speed (rad/s) | speed_deg, delta | delta_deg, duration (s);
    [forces.<name>] point, force = [fx, fy] (N).  ``t_end`` overrides [solver] t_end.
    """
    source = Path(source)
    for key in root:
        if key not in SCENE_TABLES:
            raise InputError(f"{source}: unknown top-level table `{key}` in an absolute-nodal scene; "
                             f"use: {', '.join(SCENE_TABLES)}")
    head = TomlTable(source, "scene", root.get("scene", {}))
    title = head.string("title", source.stem)
    head.string("name", None)                    # what the outputs are called: read by sidprep/solver/scene.py
    gravity = tuple(head.array("gravity", [0.0, -9.81], shape=(2,)))
    zero = head.string("gravity_zero", "origin", ("origin", "hanging"))
    head.finish()
    output = read_output_settings(source, root)
    t_end, settings = read_solver_settings(TomlTable(source, "solver", root.get("solver", {})), output, t_end,
                                           methods=("rk4",), numbers={"step": "h"}, flags=(),
                                           defaults={"method": "rk4", "h": DEFAULT_STEP})
    beams = []
    for name, t in subtables(source, root, "beams"):
        points = t.strings("points")
        if len(points) != 2:
            t.fail("points", f"needs two point names, got {len(points)}", 'write e.g. points = ["pin", "elbow"]')
        beams.append(Beam(name, t.number("length", positive=True), t.number("mass", positive=True),
                          t.number("EI", positive=True), t.number("EA", positive=True), t.integer("elements", 4),
                          tuple(points), _angle(t, "angle"), _angle(t, "rate")))
        t.finish()
    if not beams:
        raise InputError(f"{source}: no [beams.<name>] tables; add at least one beam")
    supports = []
    for name, t in subtables(source, root, "supports"):
        supports.append(Support(name, t.string("point"), tuple(t.array("position", [0.0, 0.0], shape=(2,)))))
        t.finish()
    drivers = []
    for name, t in subtables(source, root, "drivers"):
        drivers.append(Driver(name, t.string("support"), t.string("beam"), _angle(t, "speed"), _angle(t, "delta"),
                              t.number("duration", 0.0, nonnegative=True)))
        t.finish()
    forces = []
    for name, t in subtables(source, root, "forces"):
        forces.append(NodalForce(name, t.string("point"), tuple(t.array("force", shape=(2,)))))
        t.finish()
    model = AbsoluteNodalModel(tuple(beams), tuple(supports), tuple(drivers), tuple(forces), gravity, zero, title)
    from sidprep.solver.absolute_nodal.results import initial_result  # deferred: its kernels, 28 CPU-ms of
    # imports that a scene of floating-frame bodies (which imports this module) does not need
    try:                                                 # validate before the long work
        first = initial_result(model)
        for name in output.signals:
            signal(first, name)
    except InputError as exc:
        where = "[output] signals: " if "signal" in str(exc) else ""
        raise InputError(f"{source}: {where}{exc}") from None
    return AbsoluteNodalScene(model, t_end, settings, output)
