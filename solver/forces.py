"""Force elements: point forces / torques on markers, spring-dampers, bump stops, joint forces,
regularised Coulomb friction in joints.  Gravity is a body effect (see effects.py).

Every element implements ``apply(ctx)``: it reads marker kinematics / joint coordinates from
the evaluation context and adds marker loads (inertial components) with ``ctx.add_load``;
``power(ctx)`` returns (power put into the system, power dissipated), W, for the energy
balance in the results.

Signals (magnitudes as functions of time or of a joint coordinate): a number or vector
(constant), a callable ``f(x)``, or a :class:`Table`.
"""

from __future__ import annotations

import numpy as np

from sidprep.solver.bodies import Marker
from sidprep.solver.joints import Joint


class Table:
    """Piecewise-linear table y(x); y (n,) or (n, k); ``period`` wraps x (e.g. 4*pi for a gas
    force over the crank angle of a four-stroke engine)."""

    def __init__(self, x, y, period: float | None = None):
        self.x = np.asarray(x, float)
        self.y = np.asarray(y, float)
        if self.x.ndim != 1 or len(self.x) < 2 or np.any(np.diff(self.x) <= 0):
            raise ValueError("table x must be strictly increasing with at least 2 entries")
        if self.y.shape[0] != len(self.x):
            raise ValueError("table y must have one row per x value")
        self.period = period

    def __call__(self, x: float):
        if self.period:
            x = self.x[0] + (x - self.x[0]) % self.period
        if self.y.ndim == 1:
            return float(np.interp(x, self.x, self.y))
        return np.array([np.interp(x, self.x, col) for col in self.y.T])


def _signal(value):
    """A callable x -> value from a constant, a callable or a Table."""
    if callable(value):
        return value
    const = np.asarray(value, float)
    return lambda x: const


class _MarkerLoad:
    """Force (``torque=False``) or torque on one marker, see PointForce / PointTorque."""

    torque = False

    def __init__(self, marker: Marker, value, *, direction=None, frame: str = "inertial",
                 argument: Joint | None = None, name: str | None = None):
        if frame not in ("inertial", "marker"):
            raise ValueError(f"frame must be 'inertial' or 'marker', got {frame!r}")
        self.marker = marker
        self.signal = _signal(value)
        self.direction = None if direction is None else np.asarray(direction, float)
        self.frame = frame
        self.argument = argument
        self.name = name or f"{type(self).__name__}:{marker.name}"

    def vector(self, ctx) -> np.ndarray:
        """The load vector in inertial components at the current state."""
        x = ctx.t if self.argument is None else ctx.joint_coordinate(self.argument)[0]
        v = self.signal(x)
        v = np.asarray(v, float) * (self.direction if self.direction is not None else 1.0)
        if v.shape != (3,):
            raise ValueError(f"{self.name}: the load must be a 3-vector (or a scalar with direction)")
        return ctx.kin(self.marker)[1] @ v if self.frame == "marker" else v

    def apply(self, ctx) -> None:
        v = self.vector(ctx)
        if self.torque:
            ctx.add_load(self.marker, torque=v)
        else:
            ctx.add_load(self.marker, force=v)

    def power(self, ctx):
        vel, omega = ctx.marker_velocity(self.marker)
        return float(self.vector(ctx) @ (omega if self.torque else vel)), 0.0


class PointForce(_MarkerLoad):
    """Force on a marker, N.

    value : (3,) constant, callable f(x) -> (3,) or scalar, or Table; x is the time (s) or,
        with ``argument=joint``, that joint's coordinate (rad or m), e.g. a gas force over the
        crank angle.  A scalar value is multiplied by ``direction``.
    frame : "inertial" or "marker" (a follower load, components in the marker frame).
    """


class PointTorque(_MarkerLoad):
    """Torque on a marker, N m; same arguments as PointForce."""

    torque = True


class SpringDamper:
    """Spring-damper between two markers along their connecting line.

    Tension T = stiffness (l - length) + damping l_dot + law(l - length, l_dot) (N), acting
    as -T e on marker 2 and +T e on marker 1, e = (p2 - p1) / l.  ``length`` defaults to the
    initial distance.  ``law`` adds a nonlinear tension (e.g. ``bump_stop``).
    """

    def __init__(self, marker1: Marker, marker2: Marker, stiffness: float = 0.0, damping: float = 0.0,
                 length: float | None = None, law=None, name: str | None = None):
        self.marker1, self.marker2 = marker1, marker2
        self.stiffness, self.damping, self.length = float(stiffness), float(damping), length
        self.law = law
        self.name = name or f"spring:{marker1.name}-{marker2.name}"

    def _distance(self, ctx) -> np.ndarray:
        return ctx.kin(self.marker2)[0] - ctx.kin(self.marker1)[0]

    def at_start(self, ctx) -> None:
        """Resolve the default unstretched length: the marker distance once the joints are assembled."""
        if self.length is None:
            self.length = float(np.linalg.norm(self._distance(ctx)))

    def _state(self, ctx):
        d = self._distance(ctx)
        length = float(np.linalg.norm(d))
        e = d / length
        rate = float(e @ (ctx.marker_velocity(self.marker2)[0] - ctx.marker_velocity(self.marker1)[0]))
        return length - self.length, rate, e

    def tension(self, ctx):
        """(total tension, its dissipative part), N."""
        x, rate, _ = self._state(ctx)
        damp = self.damping * rate
        t = self.stiffness * x + damp
        if self.law is not None:
            t += self.law(x, rate)
        return t, damp

    def apply(self, ctx) -> None:
        _, _, e = self._state(ctx)
        t = self.tension(ctx)[0]
        ctx.add_load(self.marker2, force=-t * e)
        ctx.add_load(self.marker1, force=t * e)

    def potential(self, ctx) -> float:
        """Energy of the linear spring part, J."""
        return 0.5 * self.stiffness * self._state(ctx)[0] ** 2

    def power(self, ctx):
        _, rate, _ = self._state(ctx)
        t, damp = self.tension(ctx)
        conservative = self.stiffness * self._state(ctx)[0]
        return -(t - conservative - damp) * rate, damp * rate


def bump_stop(clearance: float, stiffness: float, exponent: float = 1.0, damping: float = 0.0):
    """Nonlinear law for SpringDamper: a stop engaging when the deflection x = l - length drops
    below -clearance; tension = -stiffness (-(x + clearance))^exponent - damping * rate while
    engaged (pushes the markers apart)."""

    def law(x: float, rate: float) -> float:
        pen = -(x + clearance)
        if pen <= 0.0:
            return 0.0
        return -stiffness * pen**exponent - damping * rate

    return law


class JointForce:
    """A generalised force along a joint coordinate: Q = law(x, x_dot, t) (N m for angles,
    N for slides), acting on body 2 (and -Q on body 1); e.g. a rotational spring, a motor
    torque or an actuator."""

    def __init__(self, joint: Joint, law, name: str | None = None):
        if joint.coordinate_kind is None:
            raise ValueError(f"joint force on '{joint.name}': a {joint.kind} joint has no coordinate")
        self.joint, self.law = joint, law
        self.name = name or f"jointforce:{joint.name}"

    def value(self, ctx) -> float:
        x, xd = ctx.joint_coordinate(self.joint)
        return float(self.law(x, xd, ctx.t))

    def apply(self, ctx) -> None:
        ctx.add_joint_load(self.joint, self.value(ctx))

    def power(self, ctx):
        return self.value(ctx) * ctx.joint_coordinate(self.joint)[1], 0.0


class JointFriction:
    """Regularised Coulomb friction in a revolute/cylindrical (torque) or prismatic (force) joint.

    Friction = -mu N tanh(x_dot / regularisation), with N the magnitude of the joint's
    transverse reaction (revolute: radial force times ``radius`` -> torque; prismatic: lateral
    force) plus ``preload`` (N); evaluated from the current multipliers (implicitly coupled).
    """

    def __init__(self, joint: Joint, mu: float, *, radius: float = 0.0, preload: float = 0.0,
                 regularisation: float = 1e-3, name: str | None = None):
        if joint.kind not in ("revolute", "cylindrical", "prismatic"):
            raise ValueError(f"friction needs a revolute, cylindrical or prismatic joint, got {joint.kind}")
        if joint.kind != "prismatic" and radius <= 0:
            raise ValueError(f"friction in rotational joint '{joint.name}' needs radius > 0 (m)")
        self.joint, self.mu, self.radius = joint, float(mu), float(radius)
        self.preload, self.regularisation = float(preload), float(regularisation)
        self.name = name or f"friction:{joint.name}"

    def value(self, ctx) -> float:
        lam = ctx.joint_multipliers(self.joint)
        normal = float(np.hypot(lam[0], lam[1])) + self.preload
        arm = 1.0 if self.joint.kind == "prismatic" else self.radius
        xd = ctx.joint_coordinate(self.joint)[1]
        return -self.mu * normal * arm * np.tanh(xd / self.regularisation)

    def apply(self, ctx) -> None:
        ctx.add_joint_load(self.joint, self.value(ctx))

    def power(self, ctx):
        return 0.0, -self.value(ctx) * ctx.joint_coordinate(self.joint)[1]
