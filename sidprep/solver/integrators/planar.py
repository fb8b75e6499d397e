"""Planar scenes: integrate only the in-plane coordinates when that is exact.

A scene of rigid bodies is planar when the revolute / cylindrical / planar joint axes share
one normal n along an inertial axis and along a body axis of every body, prismatic axes lie
in the plane, gravity and the initial velocities lie in the plane, and the out-of-plane
coordinates O (translation along n, the two tilts) stay zero under the scene's loads: that
is verified on the full 3D equations at random in-plane states, at PLANAR_SAMPLES times
spread over the run (every constraint row acts either on in-plane coordinates or on O only,
and the O-rows of the equations of motion are balanced by reactions of the O-only rows).  The
O-only rows are dropped; their reactions are recovered at the output samples (core/planar.pyx
``out_of_plane_reactions``).

Flexible bodies are always run in 3D: a real mesh is never exactly symmetric about the plane,
so its modes mix in-plane and out-of-plane motion, and dropping any of them changes the
answer (a run with a flexible body says so in its notes).
"""

from __future__ import annotations

import numpy as np

from sidprep.solver.integrators.base import constraint_rows, evaluate, marker_kinematics, moved_pose

#: relative size below which an out-of-plane coupling counts as zero
PLANAR_TOL = 1e-9
#: tolerance of the geometry (parallel joint axes, plane normal along a coordinate axis,
#: gravity and initial velocities in the plane), relative
PLANAR_AXIS_TOL = 1e-9
#: random in-plane test states, at times evenly spread over [0, t_end]
PLANAR_SAMPLES = 8
#: size of the random in-plane test displacements, in system lengths L
PLANAR_MOTION = 1e-4
AXES = "xyz"


def plane_normal(system, L, R, A, Q) -> np.ndarray | None:
    """Common unit normal (inertial) of the joint axes: revolute / cylindrical z, planar-joint
    normal; prismatic axes must lie in the plane.  None without such a joint or if they differ."""
    AM = marker_kinematics(L, R, A, Q).AM
    index = {id(m): k for k, m in enumerate(system.markers())}

    def axes(kinds):
        return [AM[index[id(j.marker1)]][:, 2] for j in system.joints if j.kind in kinds]

    normals, slides = axes(("revolute", "cylindrical", "planar")), axes(("prismatic",))
    if not normals:
        return None
    n = normals[0]
    if any(np.linalg.norm(np.cross(n, z)) > PLANAR_AXIS_TOL for z in normals) or any(
            abs(n @ z) > PLANAR_AXIS_TOL for z in slides):
        return None
    return n


def planar_coordinates(system, L, state, refs, kept, weights, length, t_end):
    """(free coordinate indices, kept row indices, note) of an exact planar run, or
    (None, None, note) when the scene is not planar (the note says why when it matters)."""
    if not system.bodies:
        return None, None, ""
    flexible = [b.name for b in system.bodies if b.nq]
    R, A, Q, u = state.R, state.A, state.Q, state.u
    n_vec = plane_normal(system, L, R, A, Q)
    if n_vec is None or abs(system.gravity @ n_vec) > PLANAR_AXIS_TOL * max(np.linalg.norm(system.gravity), 1.0):
        return None, None, ""
    ax = int(np.argmax(np.abs(n_vec)))
    if abs(abs(n_vec[ax]) - 1.0) > PLANAR_AXIS_TOL:
        return None, None, ""
    if flexible:
        return None, None, (f"planar scene (normal {AXES[ax]}) run in 3D: flexible bodies ({', '.join(flexible)}) keep "
                            "all their modes and out-of-plane motion")
    n = int(L.uoff[-1])
    free = np.zeros(n, bool)
    for i in range(len(system.bodies)):
        nk = A[i].T @ n_vec
        axk = int(np.argmax(np.abs(nk)))
        if abs(abs(nk[axk]) - 1.0) > PLANAR_AXIS_TOL:
            return None, None, ""
        s = int(L.uoff[i])
        free[[s + a for a in range(3) if a != ax]] = True
        free[s + 3 + axk] = True
    out = ~free
    if np.any(np.abs(u[out]) > PLANAR_AXIS_TOL * max(np.max(np.abs(u)), 1e-300)):
        return None, None, ""
    rng = np.random.default_rng(0)
    m_all = constraint_rows(L)
    rows = None
    for t in np.linspace(0.0, t_end, PLANAR_SAMPLES):
        Rt, At, Qt = moved_pose(L, R, A, Q, np.where(free, PLANAR_MOTION * length * rng.standard_normal(n)
                                                       / weights, 0.0))
        vel = np.where(free, u + rng.standard_normal(n) / weights, 0.0)
        e = evaluate(L, Rt, At, Qt, vel, t, np.zeros(m_all), refs)
        M, f, B = e.M, e.f, e.B[kept]
        inplane = np.linalg.norm(B[:, free], axis=1) > PLANAR_TOL * np.linalg.norm(B, axis=1)
        if rows is not None and np.any(rows != inplane):
            return None, None, ""
        rows = inplane
        acc = np.where(free, rng.standard_normal(n) / weights, 0.0)
        lam = rng.standard_normal(B.shape[0]) * inplane
        load = M @ acc - f + B.T @ lam
        size = np.abs(M @ acc) + np.abs(f) + np.abs(B.T) @ np.abs(lam)
        if not np.all(np.isfinite(size)):
            return None, None, ""
        b_out = B[~inplane][:, out]
        react = np.linalg.lstsq(b_out.T, -load[out], rcond=None)[0] if b_out.size else np.zeros(0)
        if np.any(np.abs(load[out] + b_out.T @ react) > 1e-6 * np.max(size)):
            return None, None, ""
    note = (f"planar scene (normal {AXES[ax]}): integrated {int(free.sum())} of {n} coordinates, the in-plane "
            f"translations and the rotation about {AXES[ax]}")
    return np.flatnonzero(free), kept[rows], note


