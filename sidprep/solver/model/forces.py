"""Force elements (descriptions): point forces / torques on markers, spring-dampers with bump
stops, joint forces, regularised Coulomb friction in joints.  Gravity is a body effect
(effects.py).  Every element is evaluated compiled, with its power and potential energy, in
``sidprep/solver/core/forces.pyx``: no element takes a slow path.

Signals (magnitudes over time or over a joint coordinate) are a number or 3-vector (constant)
or a :class:`Table`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sidprep.solver.model.bodies import Marker, PathMarker
from sidprep.solver.model.joints import Joint


class Table:
    """Piecewise-linear table y(x); y (n,) or (n, k); ``period`` wraps x (e.g. 4*pi for a gas
    force over the crank angle of a four-stroke engine).  ``table(x)`` evaluates it."""

    def __init__(self, x, y, period: float | None = None):
        self.x = np.asarray(x, float)
        self.y = np.asarray(y, float)
        if self.x.ndim != 1 or len(self.x) < 2 or np.any(np.diff(self.x) <= 0):
            raise ValueError("table x must be strictly increasing with at least 2 entries")
        if self.y.shape[0] != len(self.x) or self.y.ndim > 2:
            raise ValueError("table y must have one row (a number or a vector) per x value")
        if period is not None and period <= 0:
            raise ValueError(f"table period must be > 0, got {period}")
        self.period = period

    @property
    def columns(self) -> int:
        return 1 if self.y.ndim == 1 else self.y.shape[1]

    def coefficients(self) -> np.ndarray:
        """Piecewise-polynomial coefficients (2, n - 1, columns) in the form of scipy's PPoly:
        y = c[0] (x - x_i) + c[1] on [x_i, x_i+1]."""
        y = self.y.reshape(len(self.x), -1)
        return np.stack([np.diff(y, axis=0) / np.diff(self.x)[:, None], y[:-1]])

    def __call__(self, x: float):
        from scipy.interpolate import PPoly  # deferred: 0.42 CPU-s of import (paths, tables)

        if self.period:
            x = self.x[0] + (x - self.x[0]) % self.period
        out = PPoly(self.coefficients(), self.x)(x)      # the end pieces extrapolate, as compiled
        return float(out[0]) if self.y.ndim == 1 else out


def _constant_or_table(value, what: str):
    """A Table, or the constant as a float array (a number or a 3-vector)."""
    if isinstance(value, Table):
        return value
    if callable(value):
        raise ValueError(f"{what}: a Python function cannot run in the compiled solver; give a number, a "
                         "3-vector or a Table(x, y, period)")
    return np.asarray(value, float)


class MarkerLoad:
    """Force (``torque=False``) or torque on one marker, see PointForce / PointTorque."""

    torque = False

    def __init__(self, marker: Marker, value, *, direction=None, frame: str = "inertial",
                 argument: Joint | None = None, name: str | None = None):
        if frame not in ("inertial", "marker"):
            raise ValueError(f"frame must be 'inertial' or 'marker', got {frame!r}")
        self.name = name or f"{type(self).__name__}:{marker.name}"
        self.marker = marker
        self.value = _constant_or_table(value, self.name)
        self.direction = None if direction is None else np.asarray(direction, float)
        columns = self.value.columns if isinstance(self.value, Table) else self.value.size
        if columns == 1 and self.direction is None:
            raise ValueError(f"{self.name}: a scalar load needs a direction (3-vector)")
        if columns not in (1, 3) or (columns == 3 and self.direction is not None):
            raise ValueError(f"{self.name}: the load must be a 3-vector, or a scalar with a direction")
        if argument is not None and argument.coordinate_kind is None:
            raise ValueError(f"{self.name}: the argument joint '{argument.name}' has no coordinate")
        self.frame = frame
        self.argument = argument


class PointForce(MarkerLoad):
    """Force on a marker, N.

    value : (3,) constant, or a scalar with ``direction``, or a Table (y rows 3-vectors or
        scalars) over x = the time (s) or, with ``argument=joint``, that joint's coordinate (rad
        or m), e.g. a gas force over the crank angle.
    frame : "inertial" or "marker" (a follower load, components in the marker frame).
    """


class PointTorque(MarkerLoad):
    """Torque on a marker, N m; same arguments as PointForce."""

    torque = True


@dataclass(frozen=True)
class BumpStop:
    """A stop engaging when the spring deflection x = l - length drops below -clearance:
    tension -stiffness (-(x + clearance))^exponent + damping * rate while engaged (pushes the
    markers apart; the damping resists the rate like the spring's own).  clearance m,
    stiffness N/m^exponent, damping N s/m."""

    clearance: float
    stiffness: float
    exponent: float = 1.0
    damping: float = 0.0


def bump_stop(clearance: float, stiffness: float, exponent: float = 1.0, damping: float = 0.0) -> BumpStop:
    """A BumpStop for ``SpringDamper(law=...)``."""
    return BumpStop(float(clearance), float(stiffness), float(exponent), float(damping))


class SpringDamper:
    """Spring-damper between two markers along their connecting line.

    Tension T = stiffness (l - length) + damping l_dot (+ a BumpStop ``law``) (N), acting as
    -T e on marker 2 and +T e on marker 1, e = (p2 - p1) / l.  ``length`` None: the marker
    distance once the joints are assembled (resolved by each run).
    """

    def __init__(self, marker1: Marker, marker2: Marker, stiffness: float = 0.0, damping: float = 0.0,
                 length: float | None = None, law: BumpStop | None = None, name: str | None = None):
        self.name = name or f"spring:{marker1.name}-{marker2.name}"
        if law is not None and not isinstance(law, BumpStop):
            raise ValueError(f"{self.name}: law must be a BumpStop (bump_stop(...)); Python functions cannot run in "
                             "the compiled solver")
        self.marker1, self.marker2 = marker1, marker2
        self.stiffness, self.damping, self.length = float(stiffness), float(damping), length
        self.law = law


class JointForce:
    """A generalised force along a joint coordinate x (N m for angles, N for slides), acting on
    body 2 (and the reaction on body 1):

        Q = constant - stiffness (x - reference) - damping x_dot + table(x)

    e.g. a rotational spring-damper, a motor torque or a force over the stroke.
    """

    def __init__(self, joint: Joint, *, stiffness: float = 0.0, damping: float = 0.0, reference: float = 0.0,
                 constant: float = 0.0, table: Table | None = None, name: str | None = None):
        if joint.coordinate_kind is None:
            raise ValueError(f"joint force on '{joint.name}': a {joint.kind} joint has no coordinate")
        if table is not None and (not isinstance(table, Table) or table.columns != 1):
            raise ValueError(f"joint force on '{joint.name}': table must be a Table of scalars")
        self.joint = joint
        self.stiffness, self.damping = float(stiffness), float(damping)
        self.reference, self.constant = float(reference), float(constant)
        self.table = table
        self.name = name or f"jointforce:{joint.name}"


class JointFriction:
    """Regularised Coulomb friction in a revolute/cylindrical (torque) or prismatic / on_path (force) joint.

    Friction = -mu N arm tanh(x_dot / regularisation), with N the magnitude of the joint's
    transverse reaction (the multipliers of its two transverse position rows) plus ``preload``
    (N), arm = ``radius`` (m) for rotational joints, 1 for prismatic ones; evaluated from the
    current multipliers (implicitly coupled).
    """

    def __init__(self, joint: Joint, mu: float, *, radius: float = 0.0, preload: float = 0.0,
                 regularisation: float = 1e-3, name: str | None = None):
        if joint.kind not in ("revolute", "cylindrical", "prismatic", "on_path"):
            raise ValueError(f"friction needs a revolute, cylindrical, prismatic or on_path joint, got {joint.kind}")
        if joint.kind in ("revolute", "cylindrical") and radius <= 0:
            raise ValueError(f"friction in rotational joint '{joint.name}' needs radius > 0 (m)")
        if regularisation <= 0:
            raise ValueError(f"friction in joint '{joint.name}': regularisation must be > 0 (rad/s or m/s)")
        self.joint, self.mu, self.radius = joint, float(mu), float(radius)
        self.preload, self.regularisation = float(preload), float(regularisation)
        self.name = name or f"friction:{joint.name}"


class MovingMass:
    """A point mass carried along a body path at the prescribed arc length s(t) of its
    PathMarker (Hartweg and Heckmann 2012 section 2, a moving mass whose along-path motion is driven): its inertia
    m (g - a) acts on the body at the path point, with the full acceleration a of that point
    including the convective terms (2 s_dot Phi' q_dot, s_dot^2 (p'' + Phi'' q), s_ddot (p' + Phi' q)
    and those of the body's rotation), and its mass joins the body's mass matrix (m J^T J).

    Energy (generalised-alpha): the mass's kinetic energy 1/2 m |v|^2 and potential -m g . r
    are in energy.kinetic / energy.gravity while it is on the path, and the work of the drive
    that moves it along the path, m (a - g) . (s_dot dr/ds), is in energy.external.
    """

    def __init__(self, marker, mass: float, *, name: str | None = None):
        if not isinstance(marker, PathMarker):
            raise ValueError(f"moving mass {name}: its marker '{marker.name}' is not a path marker; "
                             "make one with FlexibleBody.path_marker")
        if not mass > 0:
            raise ValueError(f"moving mass {name}: mass must be > 0 kg, got {mass}")
        self.marker, self.mass = marker, float(mass)
        self.name = name or f"mass:{marker.name}"


FORCE_ELEMENTS = (PointForce, PointTorque, SpringDamper, JointForce, JointFriction, MovingMass)
