"""Path markers on their paths, checked before a run (``sidprep.solver.run.Run``).

A path marker carries its load only while its arc length s lies on the path (0 .. s_end of the
SID's BodyPath).  A marker that starts off the path (a motion starting at s = 20 m on a 15 m
Beam axis, a mass released beyond the end of the rail it slides on) is an input error; one that
a motion drives off the path during the run (a vehicle leaving the bridge) is legitimate and
gets a note naming the time.  A marker that an on_path joint holds on the path and that leaves it
during the run (a mass sliding off the end of its rail) stops the run with an error (``left_path``):
beyond the end the joint has nothing to hold it on.
"""

from __future__ import annotations

import numpy as np

from sidprep.solver.core.curves import motion_profile
from sidprep.solver.compile.layout import Curves, motion_row
from sidprep.solver.model.bodies import PathMarker

#: samples of s(t) over 0 .. t_end when looking for the time a motion leaves its path
MOTION_SAMPLES = 2001
#: a point counts as on the path within this fraction of the path length beyond an end
PATH_END_RTOL = 1e-6


def path_marker_problems(system, t_end: float) -> tuple[list[str], list[str]]:
    """(errors, notes) of the path markers of ``system`` over 0 .. ``t_end`` (s)."""
    errors, notes = [], []
    for body in system.bodies:
        for m in getattr(body, "markers", ()):
            if isinstance(m, PathMarker) and m.motion is not None:
                _motion_on_path(m, t_end, errors, notes)
    for joint in system.joints:
        if joint.kind == "on_path":
            _partner_on_path(joint, errors)
    return errors, notes


def _span(m: PathMarker) -> tuple[float, float, float]:
    s0, s1 = float(m.path.s[0]), float(m.path.s[-1])
    return s0, s1, PATH_END_RTOL * (s1 - s0)


def _motion_on_path(m: PathMarker, t_end: float, errors: list, notes: list) -> None:
    """s(0) on the path (else an error); the first sampled time s(t) leaves it (a note)."""
    curves = Curves()
    kind, params, curve = motion_row(m.motion, curves)
    x, c = ((np.ascontiguousarray(m.motion.x, dtype=float), np.ascontiguousarray(m.motion.c, dtype=float))
            if curve >= 0 else (np.zeros(2), np.zeros((4, 1))))
    s0, s1, tol = _span(m)
    times = np.linspace(0.0, t_end, MOTION_SAMPLES)
    s = np.array([motion_profile(kind, params, x, c, t)[0] for t in times])
    off = (s < s0 - tol) | (s > s1 + tol)
    if off[0]:
        errors.append(f"path marker {m.name} starts at s = {s[0]:g} m, off its path (s = {s0:g} .. {s1:g} m); "
                      "give a motion start on the path")
    elif off.any():
        k = int(np.argmax(off))
        notes.append(f"path marker {m.name} leaves its path (s = {s0:g} .. {s1:g} m) at t = {times[k]:.4g} s "
                     f"(s = {s[k]:.4g} m); from then on its load is off the body")


def _beyond_ends(m: PathMarker, local: np.ndarray) -> np.ndarray:
    """How far the points ``local`` (n, 3) (body frame of the path, m) lie beyond either end of the
    undeformed path of ``m``, along its end tangents (n,; <= 0 over the path)."""
    points = np.asarray(m.path.points)
    out = np.full(len(local), -np.inf)
    for end, inward in ((points[0], points[1] - points[0]), (points[-1], points[-2] - points[-1])):
        out = np.maximum(out, -((local - end) @ (inward / np.linalg.norm(inward))))
    return out


def _partner_on_path(joint, errors: list) -> None:
    """Marker 2 of an on_path joint starts over the path of marker 1 (undeformed, t = 0)."""
    m, partner = joint.marker1, joint.marker2
    body, other = m.body, partner.body
    world = np.asarray(other.position0) + np.asarray(other.rotation0) @ np.asarray(partner.position)
    local = np.asarray(body.rotation0).T @ (world - np.asarray(body.position0))
    s0, s1, tol = _span(m)
    beyond = float(_beyond_ends(m, local[None])[0])
    if beyond > tol:
        errors.append(f"on_path joint {joint.name}: marker {partner.name} starts {beyond:g} m beyond the end "
                      f"of the path of {m.name} (s = {s0:g} .. {s1:g} m); place it over the path")


#: a marker counts as gone from its path once it lies this fraction of the path length beyond an end
#: (the ends of the undeformed path: the deformation moves them far less)
LEFT_PATH_RTOL = 1e-3


def left_path(system, result) -> str | None:
    """The first on_path joint whose marker 2 left the path of marker 1 during the run (beyond an end:
    the joint then has no path to hold it on), with the time, or None."""
    for joint in system.joints:
        if joint.kind != "on_path":
            continue
        m, partner = joint.marker1, joint.marker2
        b = result.bodies.get(m.body.name)
        if b is None:                            # the path on the ground: its frame is the world's
            local = result.markers[partner.name]
        else:
            local = np.einsum("tji,tj->ti", b.rotation, result.markers[partner.name] - b.position)
        s0, s1, _ = _span(m)
        beyond = _beyond_ends(m, local)
        off = beyond > LEFT_PATH_RTOL * (s1 - s0)
        if off.any():
            k = int(np.argmax(off))
            return (f"on_path joint {joint.name}: marker {partner.name} left the path of {m.name} (s = {s0:g} .. "
                    f"{s1:g} m) at t = {result.t[k]:.4g} s ({beyond[k]:.3g} m beyond its end), where the joint has "
                    "no path to hold it on; shorten t_end to before that time or lengthen the path")
    return None
