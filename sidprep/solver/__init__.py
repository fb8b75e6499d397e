"""Floating-frame-of-reference (FFR) multibody solver that consumes SID files.

The package reads as the flow of a simulation: ``equations`` (the one compiled implementation of
the body equations, constraints, force elements, energies and rotations) -> ``model`` (bodies,
markers, joints, drivers, force elements, effect names, System: descriptions and checks) -> ``compile``
(a System into the kernels' tables) -> ``integrators`` (settings, generalised-alpha, Runge-Kutta,
consistent start, planar scenes) -> ``run`` (``simulate(system, t_end, settings)``: one
simulation, owning its state) -> ``Result`` (results.py) ; scene files on top (scene.py,
absolute_nodal/).  Each layer imports only those before it (tests/test_layering.py).

Never imports sidprep's FE side (mesh, assemble, linalg, reduce, ...): its only inputs from
there are SID files, read through ``sidprep.sid.model`` and ``sidprep.sid.io`` (numpy/h5py only).
The public names below are imported on first use::

    from sidprep.solver import System, FlexibleBody, Revolute, SolverSettings, simulate
"""

from __future__ import annotations

import importlib

from sidprep.lazy import submodule

_PUBLIC = {
    "sidprep.solver.model.system": ("System",),
    "sidprep.solver.model.bodies": ("Ground", "RigidBody", "FlexibleBody", "Marker", "PathMarker"),
    "sidprep.solver.model.joints": ("Spherical", "Revolute", "Cylindrical", "Prismatic", "Planar", "Fixed", "OnPath",
                                    "JOINT_TYPES", "Driver", "ConstantSpeed", "SmoothStart", "TabulatedMotion"),
    "sidprep.solver.model.forces": ("PointForce", "PointTorque", "SpringDamper", "BumpStop", "bump_stop",
                                    "JointForce", "JointFriction", "MovingMass", "Table"),
    "sidprep.solver.model.effects": ("EFFECTS",),
    "sidprep.solver.integrators.settings": ("SolverSettings", "METHODS"),
    "sidprep.solver.results": ("Result", "BodyHistory", "JointHistory"),
    "sidprep.solver.run": ("simulate",),
}
_WHERE = {name: module for module, names in _PUBLIC.items() for name in names}
__all__ = sorted(_WHERE)


def __getattr__(name: str):
    if name in _WHERE:
        return getattr(importlib.import_module(_WHERE[name]), name)
    return submodule(__name__, name)                  # the solver's modules on first use (sidprep.lazy)
