#!/usr/bin/env python3
"""Writes scene.toml of the robotic portal (README.md): the robots' accelerate-travel-stop cycles
as tabulated motions along the beams; and carriage.obj, the robots' surface for the animation
(the carriage box and a stem down to the tool point).

    python make_scene.py      # scene.toml and carriage.obj (committed)
"""

from __future__ import annotations

import numpy as np

#: portal (m): two 30 m runway beams at y = 0 and 15 m and a 15 m cross beam at x = 30 m, 7 m high
LENGTH, WIDTH, HEIGHT = 30.0, 15.0, 7.0
#: steel box girder about 1.3 x 0.5 m: A (m^2), Iy (vertical bending), Iz, J (m^4)
SECTION = "general:0.07,1.6e-2,4e-3,1.0e-2"
#: robots: rigid carriages hanging under the beams (kg, principal inertia about the centre of
#: mass of a 1.2 x 1.0 x 1.5 m box, kg m^2), on a vertical spring-damper of SUSPENSION_HZ with
#: SUSPENSION_ZETA damping at HANG m below the beam's axis, a tool point TOOL m below the carriage;
#: their cycles (start s, end s in m) on each beam, and the cycle timing (s)
ROBOT_MASS, ROBOT_INERTIA, ROBOT_BOX = 1500.0, (406.0, 461.0, 305.0), (1.2, 1.0, 1.5)
SUSPENSION_HZ, SUSPENSION_ZETA, HANG, TOOL, G = 8.0, 0.1, 0.5, 2.0, 9.81
CYCLES = {"r1": ("runway_a", 5.0, 20.0), "r2": ("runway_a", 25.0, 12.0),
          "r3": ("runway_b", 5.0, 20.0), "r4": ("runway_b", 25.0, 12.0)}
RAMP, TRAVEL, DWELL, T_END = 1.5, 4.0, 2.0, 24.0


def cycle(start: float, end: float, dt: float = 0.05):
    """(times, positions) of go - dwell - return - dwell cycles with a trapezoidal speed profile
    (ramps of RAMP s, constant speed for TRAVEL s) until T_END."""
    speed = (end - start) / (RAMP + TRAVEL)
    move = 2 * RAMP + TRAVEL

    def one_way(t):  # distance covered after t s of a move, as a fraction of the stroke
        t = np.clip(t, 0.0, move)
        up = np.minimum(t, RAMP)
        flat = np.clip(t - RAMP, 0.0, TRAVEL)
        down = np.clip(t - RAMP - TRAVEL, 0.0, RAMP)
        return (0.5 * up**2 / RAMP + flat + down - 0.5 * down**2 / RAMP) * speed / (end - start)

    t = np.arange(0.0, T_END + dt / 2, dt)
    period = 2 * (move + DWELL)
    phase = np.mod(t, period)
    frac = np.where(phase < move + DWELL, one_way(phase), 1.0 - one_way(phase - move - DWELL))
    return t, start + (end - start) * frac


def beam(name: str, position, rotation) -> str:
    return f"""[bodies.{name}]
type = "beam"
length = {LENGTH if name.startswith("runway") else WIDTH}
section = "{SECTION}"
material = "steel"
bc = "clamped-clamped"               # welded to its columns
modes = "xz:1-3,xy:1-2,torsion:1"    # five bending forms, one torsion
damping = 0.02
position = {list(position)}
rotation = {list(rotation)}

[markers.{name}_base]
body = "{name}"

[markers.{name}_column]
body = "ground"
position = {list(position)}
rotation = {list(rotation)}

[joints.{name}_columns]
type = "fixed"
markers = ["{name}_column", "{name}_base"]

"""


def robot(name: str, beam_name: str, start: float, end: float, beam_y: float) -> str:
    """A robot (Hartweg and Heckmann 2012 section 2.2's subsystem): its guide point moving along the beam's axis,
    the carriage held upright by a prismatic joint (vertical slide) on it and carried by a
    spring-damper preloaded with the carriage's weight, and its tool point."""
    t, s = cycle(start, end)
    fmt = lambda a: ", ".join(f"{v:.6g}" for v in a)  # noqa: E731
    k = ROBOT_MASS * (2 * np.pi * SUSPENSION_HZ) ** 2
    c = 2 * SUSPENSION_ZETA * np.sqrt(k * ROBOT_MASS)
    return f"""[markers.{name}]
body = "{beam_name}"
path = "axis"
motion = "table"
times = [{fmt(t)}]
values = [{fmt(s)}]

[bodies.{name}_carriage]
type = "rigid"
mass = {ROBOT_MASS}
inertia = {list(ROBOT_INERTIA)}
obj = "carriage.obj"
position = [{start}, {beam_y}, {HEIGHT - HANG}]

[markers.{name}_seat]
body = "{name}_carriage"

[markers.{name}_tool]
body = "{name}_carriage"
position = [0.0, 0.0, {-TOOL}]

[joints.{name}_guide]
type = "prismatic"                   # vertical slide on the moving guide point
markers = ["{name}", "{name}_seat"]

[forces.{name}_suspension]
type = "spring_damper"
markers = ["{name}", "{name}_seat"]
stiffness = {k:.6g}
damping = {c:.6g}
length = {HANG - ROBOT_MASS * G / k:.6g}         # preloaded with the carriage's weight

"""


def scene() -> str:
    head = f"""# Robotic portal (Hartweg and Heckmann 2012 section 3): see README.md.  Made by make_scene.py.
[scene]
title = "robotic portal"
gravity = [0.0, 0.0, -9.81]
effects = "auto"

[solver]
t_end = {T_END}
method = "genalpha"
step = 2e-3
rho_inf = 0.9
static_start = true

[output]
rate = 100
signals = ["r1.position.z", "r1_tool.position.z", "r2.position.z", "runway_a.q.1", "runway_b.q.1", "cross.q.1"]

"""
    parts = [head, beam("runway_a", (0.0, 0.0, HEIGHT), (0.0, 0.0, 0.0)),
             beam("runway_b", (0.0, WIDTH, HEIGHT), (0.0, 0.0, 0.0)),
             beam("cross", (LENGTH, 0.0, HEIGHT), (0.0, 0.0, np.pi / 2))]
    beam_y = {"runway_a": 0.0, "runway_b": WIDTH}
    parts += [robot(name, beam_name, a, b, beam_y[beam_name]) for name, (beam_name, a, b) in CYCLES.items()]
    return "".join(parts)


def write_carriage_obj(path: str = "carriage.obj") -> None:
    """The carriage's surface in its body frame (centre of mass at the origin): the box and a
    0.1 m stem from its bottom to the tool point."""
    import trimesh

    box = trimesh.creation.box(extents=ROBOT_BOX)
    stem_length = TOOL - ROBOT_BOX[2] / 2
    stem = trimesh.creation.box(extents=(0.1, 0.1, stem_length))
    stem.apply_translation((0.0, 0.0, -ROBOT_BOX[2] / 2 - stem_length / 2))
    trimesh.util.concatenate([box, stem]).export(path)


if __name__ == "__main__":
    with open("scene.toml", "w") as f:
        f.write(scene())
    write_carriage_obj()
