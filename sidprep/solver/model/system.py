"""A multibody system (a description): bodies, joints, drivers, force elements.

Usage::

    from sidprep.solver import System, FlexibleBody, Revolute, simulate
    sys = System(gravity=(0, 0, -9.81))
    bar = sys.add(FlexibleBody("bar.sid.h5", name="bar"))
    pivot = sys.add(Revolute(sys.ground.marker(rotation=...), bar.node_marker(node_id=1)))
    res = simulate(sys, 1.0, h=1e-3, effects="auto")
    res.bodies["bar"].q, res.joints[pivot.name].force, res.energy["total"], res.effects.text()

A System holds no per-run state: ``solver.run.simulate`` builds a ``Run`` that owns the
compiled layout, the kept constraint rows, the angle references and the recorder, so that
simulating the same System twice gives identical results.  Equations: docs/solver.md and
``sidprep/solver/core``.
"""

from __future__ import annotations

import numpy as np

from sidprep.solver.model.bodies import FlexibleBody, Ground, RigidBody, MassBody
from sidprep.solver.model.forces import FORCE_ELEMENTS
from sidprep.solver.model.joints import Driver, Joint


class System:
    """A multibody system.  Build it with ``add``; integrate it with ``solver.run.simulate``.

    Parameters
    ----------
    gravity : (3,) m/s^2, inertial components (used when the gravity effect is on)
    effects : "auto" (default), "all", or a list of effect names (sidprep/solver/effects.py), used by
        every flexible body that does not name its own
    planar : None (default: detect a planar scene and integrate its in-plane coordinates only),
        True (require it) or False (always the 3D coordinates); see integrate.planar_coordinates
    """

    def __init__(self, gravity=(0.0, 0.0, -9.81), effects="auto", planar=None):
        self.gravity = np.asarray(gravity, float)
        self.effects = effects
        self.planar = planar
        self.ground = Ground()
        self.bodies: list[MassBody] = []
        self.joints: list[Joint] = []
        self.drivers: list[Driver] = []
        self.forces: list = []

    # ------------------------------------------------------------------ building
    def add(self, item):
        """Add a body, joint, driver or force element; returns it."""
        if isinstance(item, (RigidBody, FlexibleBody)):
            if any(b.name == item.name for b in self.bodies):
                raise ValueError(f"duplicate body name '{item.name}'")
            self.bodies.append(item)
        elif isinstance(item, Joint):
            self.joints.append(item)
        elif isinstance(item, Driver):
            self.drivers.append(item)
        elif isinstance(item, FORCE_ELEMENTS):
            self.forces.append(item)
        else:
            raise TypeError(f"cannot add {type(item).__name__} to a System")
        return item

    def markers(self) -> list:
        """Every marker of the ground and the bodies, in a fixed order."""
        return [m for b in [self.ground] + self.bodies for m in b.markers]

    def check(self) -> None:
        """ValueError when a joint, driver or force uses a body that was not added, or a path
        marker without a motion has no OnPath joint to follow."""
        known = {id(b) for b in self.bodies} | {id(self.ground)}
        for item in self.joints + self.drivers + self.forces:
            for name in ("marker", "marker1", "marker2"):
                mk = getattr(item, name, None)
                if mk is not None and id(mk.body) not in known:
                    raise ValueError(f"'{item.name}': marker '{mk.name}' is on a body not added to the system")
            joint = getattr(item, "joint", None) or getattr(item, "argument", None)
            if joint is not None and joint not in self.joints:
                raise ValueError(f"'{item.name}': joint '{joint.name}' is not added to the system")
        followed = {id(j.marker1) for j in self.joints if j.kind == "on_path"}
        for m in self.markers():
            if getattr(m, "path", None) is not None and m.motion is None and id(m) not in followed:
                raise ValueError(f"path marker '{m.name}' has no motion and no OnPath joint to follow; give it a "
                                 "motion or join a body to it with OnPath")
