"""Joints between two markers, prescribed joint motion (drivers) and motion profiles.

Every constraint row is written with marker 1 (frame A1, point p1) and marker 2 (A2, p2),
d = p2 - p1, and unit axes x1, y1, z1 / x2, y2, z2 (columns of A1, A2, inertial components).
Two primitives (their time derivatives give the velocity Jacobian rows exactly):

* position along an axis of marker 1:  g = e1 . d,
  g_dot = e1 . (v2 - v1) + (e1 x d) . w1;
* perpendicularity of two axes:         g = a1 . b2,
  g_dot = (a1 x b2) . (w1 - w2).

A row is returned as coefficient vectors (cT1, cR1, cT2, cR2) such that
g_dot = cT1 . v1 + cR1 . w1 + cT2 . v2 + cR2 . w2 with the marker velocities v, w.
The reaction on body 2 (at p2, inertial components) is F2 = -sum lambda_r cT2_r,
T2 = -sum lambda_r cR2_r (the equations carry + B^T lambda on the left-hand side).

Joint axis convention: the z axis of the markers (revolute / cylindrical / prismatic axis,
planar normal).  Markers must coincide/align initially up to what the joint constrains;
``System`` projects the initial state onto the constraints.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sidprep.solver.bodies import Marker
from sidprep.solver.kinematics import cross, jit

# constraint rows as (kind, axis of marker 1, axis of marker 2); kind "p" = position, "a" = angle
_ROWS = {
    "spherical": (("p", 0, None), ("p", 1, None), ("p", 2, None)),
    "revolute": (("p", 0, None), ("p", 1, None), ("p", 2, None), ("a", 0, 2), ("a", 1, 2)),
    "cylindrical": (("p", 0, None), ("p", 1, None), ("a", 0, 2), ("a", 1, 2)),
    "prismatic": (("p", 0, None), ("p", 1, None), ("a", 0, 2), ("a", 1, 2), ("a", 0, 1)),
    "planar": (("p", 2, None), ("a", 2, 0), ("a", 2, 1)),
    "fixed": (("p", 0, None), ("p", 1, None), ("p", 2, None), ("a", 0, 2), ("a", 1, 2), ("a", 0, 1)),
}

#: joint coordinate kinds: rotation about z (angle) and / or translation along z
_COORDINATE = {"revolute": "angle", "cylindrical": "angle", "prismatic": "slide"}


@jit
def _joint_rows(rows, p1, a1, p2, a2):  # pragma: no cover - compiled
    """Rows (kind, axis 1, axis 2) -> g (m,) and c (4, m, 3) = (cT1, cR1, cT2, cR2), module doc."""
    m = rows.shape[0]
    d = p2 - p1
    g = np.empty(m)
    c = np.zeros((4, m, 3))
    for r in range(m):
        e = a1[:, rows[r, 1]].copy()
        if rows[r, 0] == 0:
            g[r] = e @ d
            c[0, r] = -e
            c[1, r] = cross(e, d)
            c[2, r] = e
        else:
            b = a2[:, rows[r, 2]].copy()
            g[r] = e @ b
            axb = cross(e, b)
            c[1, r] = axb
            c[3, r] = -axb
    return g, c


class Joint:
    """A kinematic joint between ``marker1`` and ``marker2`` (see the module docstring).

    Attributes after a simulation: none (reactions are in the Result).
    """

    kind = ""

    def __init__(self, marker1: Marker, marker2: Marker, name: str | None = None):
        if marker1.body is marker2.body:
            raise ValueError(f"joint {name}: both markers are on body '{marker1.body.name}'")
        self.marker1, self.marker2 = marker1, marker2
        self.name = name or f"{self.kind}:{marker1.name}-{marker2.name}"
        self.rows = _ROWS[self.kind]
        self._rows = np.array([[kind == "a", i, -1 if j is None else j] for kind, i, j in self.rows], dtype=np.int64)
        self._angle_ref = 0.0

    @property
    def nrows(self) -> int:
        return len(self.rows)

    def constraint(self, k1, k2):
        """g (m,), cT1, cR1, cT2, cR2 (m, 3) at the marker kinematics k1, k2 = (p, A, ...)."""
        g, c = _joint_rows(self._rows, k1[0], k1[1], k2[0], k2[1])
        return g, c[0], c[1], c[2], c[3]

    # ------------------------------------------------------------ joint coordinate
    @property
    def coordinate_kind(self) -> str | None:
        """"angle" (rad, about z1), "slide" (m, along z1) or None."""
        return _COORDINATE.get(self.kind)

    def coordinate(self, k1, k2):
        """Joint coordinate value and its velocity row (cT1, cR1, cT2, cR2), each (3,).

        angle: rotation of x2 about z1 from x1, continuous across +-pi (unwrapped against the
        last accepted value); slide: z1 . (p2 - p1).
        """
        a1, a2 = k1[1], k2[1]
        z = a1[:, 2]
        zero = np.zeros(3)
        if self.coordinate_kind == "angle":
            raw = np.arctan2(a1[:, 1] @ a2[:, 0], a1[:, 0] @ a2[:, 0])
            value = self._angle_ref + (raw - self._angle_ref + np.pi) % (2 * np.pi) - np.pi
            return value, (zero, -z, zero, z)
        if self.coordinate_kind == "slide":
            d = k2[0] - k1[0]
            return z @ d, (-z, cross(z, d), z, zero)
        raise ValueError(f"joint '{self.name}' ({self.kind}) has no joint coordinate")

    def accept(self, k1, k2) -> None:
        """Store the current angle as the unwrapping reference (called after each step)."""
        if self.coordinate_kind == "angle":
            self._angle_ref = self.coordinate(k1, k2)[0]


class Spherical(Joint):
    """Point coincidence p1 = p2 (3 rows, reactions = force components along x1, y1, z1)."""

    kind = "spherical"


class Revolute(Joint):
    """Rotation about the common z axis (5 rows)."""

    kind = "revolute"


class Cylindrical(Joint):
    """Rotation about and translation along the common z axis (4 rows)."""

    kind = "cylindrical"


class Prismatic(Joint):
    """Translation along z1, no relative rotation (5 rows)."""

    kind = "prismatic"


class Planar(Joint):
    """Marker 2 moves in the x1-y1 plane and rotates about z1 only (3 rows)."""

    kind = "planar"


class Fixed(Joint):
    """No relative motion (6 rows)."""

    kind = "fixed"


JOINT_TYPES = {cls.kind: cls for cls in (Spherical, Revolute, Cylindrical, Prismatic, Planar, Fixed)}


# ---------------------------------------------------------------------------- motion profiles
@dataclass(frozen=True)
class ConstantSpeed:
    """x(t) = start + speed * t (rad or m)."""

    speed: float
    start: float = 0.0

    def __call__(self, t: float):
        """(value, rate, acceleration) at time t."""
        return self.start + self.speed * t, self.speed, 0.0


@dataclass(frozen=True)
class SmoothStart:
    """Speed ramps from 0 to ``speed`` over ``ramp_time`` with (1 - cos(pi t / T)) / 2; the
    acceleration is continuous (zero at both ends of the ramp)."""

    speed: float
    ramp_time: float
    start: float = 0.0

    def __call__(self, t: float):
        w, T = self.speed, self.ramp_time
        if t <= 0.0:
            return self.start, 0.0, 0.0
        if t < T:
            s = np.pi * t / T
            return (self.start + 0.5 * w * (t - T / np.pi * np.sin(s)), 0.5 * w * (1 - np.cos(s)),
                    0.5 * w * np.pi / T * np.sin(s))
        return self.start + w * (t - 0.5 * T), w, 0.0


class TabulatedMotion:
    """x(t) from a table, interpolated with a C2 cubic spline (scipy CubicSpline)."""

    def __init__(self, times, values):
        from scipy.interpolate import CubicSpline

        self.spline = CubicSpline(np.asarray(times, float), np.asarray(values, float))
        self._d1 = self.spline.derivative(1)
        self._d2 = self.spline.derivative(2)

    def __call__(self, t: float):
        return float(self.spline(t)), float(self._d1(t)), float(self._d2(t))


class Driver:
    """Prescribed motion of a joint coordinate: coordinate(joint) - motion(t) = 0.

    ``motion`` is any callable t -> (value, rate, acceleration), e.g. ConstantSpeed,
    SmoothStart, TabulatedMotion.  The driving torque (revolute/cylindrical, N m) or force
    (prismatic, N) acting on body 2 along z1 is reported as -lambda.
    """

    nrows = 1

    def __init__(self, joint: Joint, motion, name: str | None = None):
        if joint.coordinate_kind is None:
            raise ValueError(f"driver on joint '{joint.name}': a {joint.kind} joint has no coordinate")
        self.joint = joint
        self.motion = motion
        self.name = name or f"driver:{joint.name}"
        self.marker1, self.marker2 = joint.marker1, joint.marker2

    def constraint(self, k1, k2, t: float):
        value, row = self.joint.coordinate(k1, k2)
        target = self.motion(t)[0]
        return np.array([value - target]), *(r[None, :] for r in row)

    def rate_term(self, t: float) -> float:
        """b_t in g_dot = B u + b_t."""
        return -self.motion(t)[1]
