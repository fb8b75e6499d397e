"""The description of a scene of absolute-nodal beams (Kisu Lee): beams, supports,
drivers, nodal forces, and its checks.  The formulation: sidprep/solver/absolute_nodal/__init__.py."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sidprep.errors import InputError

#: smallest number of elements per beam (the end slopes need three nodes, eq. 3-4)
MIN_ELEMENTS = 2


@dataclass(frozen=True)
class Beam:
    """One straight, uniform beam.

    length (m), mass (kg), EI (N m^2), EA (N); elements >= 2; points = (start, end) point names
    (beams sharing a point are joined by a revolute); angle (rad) of start -> end from the X axis
    and rate (rad/s) of the initially straight beam.
    """

    name: str
    length: float
    mass: float
    EI: float
    EA: float
    elements: int
    points: tuple[str, str]
    angle: float = 0.0
    rate: float = 0.0


@dataclass(frozen=True)
class Support:
    """A pinned point at a fixed position (m)."""

    name: str
    point: str
    position: tuple[float, float] = (0.0, 0.0)


@dataclass(frozen=True)
class Driver:
    """Prescribed angle of beam ``beam``'s tangent at support ``support`` (a motor clamping the beam):

    psi(t) = psi0 + speed t + delta (tau - sin(2 pi tau) / (2 pi)), tau = min(t / duration, 1);
    psi0 = the beam's initial angle; speed (rad/s) must equal the beam's initial rate.
    """

    name: str
    support: str
    beam: str
    speed: float = 0.0
    delta: float = 0.0
    duration: float = 0.0


@dataclass(frozen=True)
class NodalForce:
    """A constant force (N, inertial X-Y) at a point."""

    name: str
    point: str
    force: tuple[float, float]


@dataclass(frozen=True)
class AbsoluteNodalModel:
    """Planar beams, supports, drivers and loads; gravity (m/s^2, X-Y).

    gravity_zero: "origin" (V_g = -sum m g . x) or "hanging" (zero for every beam hanging straight
    along gravity from the supports, the paper's choice).
    """

    beams: tuple[Beam, ...]
    supports: tuple[Support, ...] = ()
    drivers: tuple[Driver, ...] = ()
    forces: tuple[NodalForce, ...] = ()
    gravity: tuple[float, float] = (0.0, -9.81)
    gravity_zero: str = "origin"
    title: str = "absolute nodal beams"


def check_model(model: AbsoluteNodalModel) -> None:
    if not model.beams:
        raise InputError("absolute-nodal model: no beams; add at least one beam")
    names = [b.name for b in model.beams]
    if len(set(names)) != len(names):
        raise InputError("absolute-nodal model: duplicate beam names; give every beam its own name")
    for b in model.beams:
        for what, v in (("length", b.length), ("mass", b.mass), ("EI", b.EI), ("EA", b.EA)):
            if not (np.isfinite(v) and v > 0):
                raise InputError(f"beam {b.name!r}: {what} must be > 0, got {v!r}; give a positive SI value")
        if b.elements < MIN_ELEMENTS:
            raise InputError(f"beam {b.name!r}: elements = {b.elements}; use at least {MIN_ELEMENTS} "
                             "(the end slopes come from a quadratic through three nodes)")
        if b.points[0] == b.points[1]:
            raise InputError(f"beam {b.name!r}: both ends at point {b.points[0]!r}; give two different points")
    points = {p for b in model.beams for p in b.points}
    for s in model.supports:
        if s.point not in points:
            raise InputError(f"support {s.name!r}: unknown point {s.point!r}; use a beam end point: {sorted(points)}")
    for f in model.forces:
        if f.point not in points:
            raise InputError(f"force {f.name!r}: unknown point {f.point!r}; use a beam end point: {sorted(points)}")
    if model.gravity_zero not in ("origin", "hanging"):
        raise InputError(f"gravity_zero {model.gravity_zero!r}; use \"origin\" or \"hanging\"")
    beams = {b.name: b for b in model.beams}
    sup = {s.name: s for s in model.supports}
    for d in model.drivers:
        if d.support not in sup or d.beam not in beams or sup[d.support].point not in beams[d.beam].points:
            raise InputError(f"driver {d.name!r}: needs a support and a beam that ends at it; "
                             f"supports: {sorted(sup)}, beams: {sorted(beams)}")
        if abs(d.speed - beams[d.beam].rate) > 1e-12:
            raise InputError(f"driver {d.name!r}: speed {d.speed} rad/s differs from beam {d.beam!r}'s initial rate "
                             f"{beams[d.beam].rate} rad/s; make them equal (consistent initial velocities)")
