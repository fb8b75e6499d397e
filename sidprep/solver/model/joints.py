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
the run assembles the initial state onto the constraints.

This module describes joints, drivers and motion profiles; the rows are evaluated (compiled)
in ``sidprep/solver/core/constraints.pyx`` and the profiles in ``sidprep/solver/core/curves.pyx``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sidprep.solver.model.bodies import Marker, PathMarker

# constraint rows as (kind, axis of marker 1, axis of marker 2); kind "p" = position, "a" = angle
_ROWS = {
    "spherical": (("p", 0, None), ("p", 1, None), ("p", 2, None)),
    "revolute": (("p", 0, None), ("p", 1, None), ("p", 2, None), ("a", 0, 2), ("a", 1, 2)),
    "cylindrical": (("p", 0, None), ("p", 1, None), ("a", 0, 2), ("a", 1, 2)),
    "prismatic": (("p", 0, None), ("p", 1, None), ("a", 0, 2), ("a", 1, 2), ("a", 0, 1)),
    "planar": (("p", 2, None), ("a", 2, 0), ("a", 2, 1)),
    "fixed": (("p", 0, None), ("p", 1, None), ("p", 2, None), ("a", 0, 2), ("a", 1, 2), ("a", 0, 1)),
    "on_path": (("p", 0, None), ("p", 1, None)),
}

#: joint coordinate kinds: rotation about z (angle) and / or translation along z
_COORDINATE = {"revolute": "angle", "cylindrical": "angle", "prismatic": "slide", "on_path": "slide"}


class Joint:
    """A kinematic joint between ``marker1`` and ``marker2`` (see the module docstring);
    ``rows`` lists its constraint rows (kind, axis of marker 1, axis of marker 2)."""

    kind = ""

    def __init__(self, marker1: Marker, marker2: Marker, name: str | None = None, *, initial: float | None = None,
                 initial_rate: float | None = None):
        """``initial`` / ``initial_rate``: the joint coordinate (rad or m) and its rate (rad/s or
        m/s) the run starts from (revolute, cylindrical, prismatic): the start assembles the
        mechanism to them, e.g. a crank angle and a crank speed."""
        if marker1.body is marker2.body:
            raise ValueError(f"joint {name}: both markers are on body '{marker1.body.name}'")
        self.marker1, self.marker2 = marker1, marker2
        self.name = name or f"{self.kind}:{marker1.name}-{marker2.name}"
        if (initial is not None or initial_rate is not None) and self.coordinate_kind is None:
            raise ValueError(f"joint {self.name}: a {self.kind} joint has no coordinate to start from")
        self.initial = None if initial is None else float(initial)
        self.initial_rate = None if initial_rate is None else float(initial_rate)
        self.rows = _ROWS[self.kind]
        self._rows = np.array([[kind == "a", i, -1 if j is None else j] for kind, i, j in self.rows], dtype=np.int64)

    @property
    def nrows(self) -> int:
        return len(self.rows)

    @property
    def coordinate_kind(self) -> str | None:
        """"angle" (rad, rotation of x2 about z1 from x1, continuous across +-pi) or "slide"
        (m, z1 . (p2 - p1)) or None."""
        return _COORDINATE.get(self.kind)


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


class OnPath(Joint):
    """Marker 2 slides freely along the path of marker 1, a path marker without a motion (its
    arc length s is the projection of marker 2 onto the deformed path; Hartweg and Heckmann 2012 eq. 30): the
    two position rows across the path (2 rows; marker 1's z axis is the path tangent).  Its
    coordinate is the slide along the tangent from the contact point (~0; its rate is the
    sliding speed relative to the body's material there, which JointFriction uses)."""

    kind = "on_path"

    def __init__(self, marker1, marker2, name: str | None = None):
        if not isinstance(marker1, PathMarker) or marker1.motion is not None:
            raise ValueError(f"on_path joint {name}: marker 1 must be a path marker without a motion "
                             "(FlexibleBody.path_marker(path) with motion=None)")
        super().__init__(marker1, marker2, name)


JOINT_TYPES = {cls.kind: cls for cls in (Spherical, Revolute, Cylindrical, Prismatic, Planar, Fixed, OnPath)}


# ---------------------------------------------------------------------------- motion profiles
@dataclass(frozen=True)
class ConstantSpeed:
    """x(t) = start + speed * t (rad or m)."""

    speed: float
    start: float = 0.0


@dataclass(frozen=True)
class SmoothStart:
    """Speed ramps from 0 to ``speed`` over ``ramp_time`` with (1 - cos(pi t / T)) / 2; the
    acceleration is continuous (zero at both ends of the ramp)."""

    speed: float
    ramp_time: float
    start: float = 0.0


class TabulatedMotion:
    """x(t) from a table, interpolated with a C2 cubic spline (scipy CubicSpline, not-a-knot);
    kept as its piecewise-polynomial coefficients, evaluated compiled (core/curves.pyx)."""

    def __init__(self, times, values):
        from scipy.interpolate import CubicSpline  # deferred: 0.42 CPU-s of import (paths, tables)

        spline = CubicSpline(np.asarray(times, float), np.asarray(values, float))
        self.x, self.c = spline.x, spline.c  # breakpoints (k+1,), coefficients (4, k)


MOTIONS = (ConstantSpeed, SmoothStart, TabulatedMotion)


class Driver:
    """Prescribed motion of a joint coordinate: coordinate(joint) - motion(t) = 0.

    ``motion`` is a ConstantSpeed, SmoothStart or TabulatedMotion.  The driving torque (revolute/cylindrical, N m) or force
    (prismatic, N) acting on body 2 along z1 is reported as -lambda.
    """

    nrows = 1

    def __init__(self, joint: Joint, motion, name: str | None = None):
        if joint.coordinate_kind is None or joint.kind == "on_path":
            raise ValueError(f"driver on joint '{joint.name}': a {joint.kind} joint has no coordinate to drive"
                             + ("; move a path marker by its motion instead" if joint.kind == "on_path" else ""))
        if not isinstance(motion, MOTIONS):
            raise ValueError(f"driver on joint '{joint.name}': the motion must be a ConstantSpeed, SmoothStart or "
                             f"TabulatedMotion, got {type(motion).__name__}")
        self.joint = joint
        self.motion = motion
        self.name = name or f"driver:{joint.name}"
        self.marker1, self.marker2 = joint.marker1, joint.marker2
