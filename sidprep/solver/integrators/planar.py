"""Planar scenes: integrate only the in-plane coordinates when that is exact.

A scene of rigid bodies is planar when the revolute / cylindrical / planar joint axes share
one normal n along an inertial axis and along a body axis of every body, prismatic axes lie
in the plane, gravity and the initial velocities lie in the plane, and the out-of-plane
coordinates O (translation along n, the two tilts) stay zero under the scene's loads: that
is verified on the full 3D equations at random in-plane states, at PLANAR_SAMPLES times
spread over the run (every constraint row acts either on in-plane coordinates or on O only,
and the O-rows of the equations of motion are balanced by reactions of the O-only rows).  The
O-only rows are dropped; their reactions are recovered at the output samples
(``out_of_plane_reactions``).

Flexible bodies are always run in 3D: a real mesh is never exactly symmetric about the plane,
so its modes mix in-plane and out-of-plane motion, and dropping any of them changes the
answer (a run with a flexible body says so in its notes).
"""

from __future__ import annotations

import numpy as np

from sidprep.solver.equations.rotations import jit
from sidprep.solver.integrators.base import advance_pose, constraint_rows, evaluate, marker_kinematics

#: relative size below which an out-of-plane coupling counts as zero
PLANAR_TOL = 1e-9
#: tolerance of the geometry (parallel joint axes, plane normal along a coordinate axis,
#: gravity and initial velocities in the plane), relative
PLANAR_AXIS_TOL = 1e-9
#: relative size (of the largest row norm, resp. the largest entry of a_I a_I^T) below which
#: the out-of-plane equations count as dependent (independent_equations, minimum_norm_solution)
RANK_TOL = 1e-12
#: relative residual of an out-of-plane equation above which the rows picked once per run no
#: longer span it (minimum_norm_solution falls back to lstsq)
RESIDUAL_TOL = 1e-10
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
        Rt, At, Qt = advance_pose(L, R, A, Q, np.where(free, PLANAR_MOTION * length * rng.standard_normal(n)
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


@jit
def out_of_plane_system(e, ud, lam_full, planar_rows, dropped, fixed):  # pragma: no cover - compiled
    """The out-of-plane equations of motion (the coordinates ``fixed``, no) in the reactions of
    the dropped rows (nd): a (no, nd) = B_F[dropped, fixed]^T and load (no,) = -(M ud - f +
    B_F^T lambda)[fixed] with lambda the planar run's multipliers lam_full (m_all,; zero on the
    dropped rows); e the Evaluation at the sample's state, ud (n,) its accelerations,
    planar_rows the rows the run kept."""
    no, nd = fixed.shape[0], dropped.shape[0]
    load = np.empty(no)
    a = np.empty((no, nd))
    for i in range(no):
        o = fixed[i]
        acc = -e.f[o]
        for j in range(ud.shape[0]):
            acc += e.M[o, j] * ud[j]
        for r in planar_rows:
            acc += e.BF[r, o] * lam_full[r]
        load[i] = -acc
        for d in range(nd):
            a[i, d] = e.BF[dropped[d], o]
    return a, load


@jit
def independent_equations(a):  # pragma: no cover - compiled
    """Rows of a (no, nd) that span its row space: Gram-Schmidt with pivoting on the largest
    remaining norm (QR with column pivoting of a^T), stopped at RANK_TOL times the largest row
    norm; int64 (r,), r the rank of a."""
    no, nd = a.shape
    rest = a.copy()
    norms = np.empty(no)
    for i in range(no):
        norms[i] = np.sqrt(np.sum(rest[i] * rest[i]))
    cutoff = RANK_TOL * max(no, nd) * max(np.max(norms) if no else 0.0, 1e-300)
    chosen = np.zeros(no, np.bool_)
    picked = np.empty(min(no, nd), np.int64)
    r = 0
    while r < picked.shape[0]:
        best, size = -1, cutoff
        for i in range(no):
            if not chosen[i] and norms[i] > size:
                best, size = i, norms[i]
        if best < 0:
            break
        chosen[best], picked[r] = True, best
        r += 1
        q = rest[best] / size
        for i in range(no):
            if not chosen[i]:
                proj = np.sum(rest[i] * q)
                for d in range(nd):
                    rest[i, d] -= proj * q[d]
                norms[i] = np.sqrt(np.sum(rest[i] * rest[i]))
    return np.sort(picked[:r])


@jit
def minimum_norm_solution(a, load, rows):  # pragma: no cover - compiled
    """x (nd,) of least norm with a x = load (a (no, nd) of rank r, load in its range), from the
    independent rows ``rows`` (r,; independent_equations): x = a_I^T z, (a_I a_I^T) z = load_I,
    a Cholesky factorisation of r x r.  numba's lstsq (an SVD) instead when a_I a_I^T is not
    positive definite to RANK_TOL or, with r < no, x leaves a row of a unsolved (solves): the
    rank changed since the rows were picked."""
    r, nd = rows.shape[0], a.shape[1]
    g = np.empty((r, r))  # a_I a_I^T, then its Cholesky factor (lower)
    for i in range(r):
        for j in range(i + 1):
            acc = 0.0
            for d in range(nd):
                acc += a[rows[i], d] * a[rows[j], d]
            g[i, j] = acc
    scale = 1e-300  # the largest entry of a_I a_I^T, on its diagonal
    for i in range(r):
        scale = max(scale, g[i, i])
    z = np.empty(r)
    for j in range(r):
        diag = g[j, j]
        for k in range(j):
            diag -= g[j, k] * g[j, k]
        if diag <= RANK_TOL * scale:
            return lstsq(a, load)
        g[j, j] = np.sqrt(diag)
        for i in range(j + 1, r):
            acc = g[i, j]
            for k in range(j):
                acc -= g[i, k] * g[j, k]
            g[i, j] = acc / g[j, j]
    for i in range(r):  # forward, then backward substitution
        acc = load[rows[i]]
        for k in range(i):
            acc -= g[i, k] * z[k]
        z[i] = acc / g[i, i]
    for i in range(r - 1, -1, -1):
        acc = z[i]
        for k in range(i + 1, r):
            acc -= g[k, i] * z[k]
        z[i] = acc / g[i, i]
    x = np.zeros(nd)
    for i in range(r):
        for d in range(nd):
            x[d] += a[rows[i], d] * z[i]
    if r < a.shape[0] and not solves(a, x, load):
        return lstsq(a, load)
    return x


@jit
def solves(a, x, load):  # pragma: no cover - compiled
    """|a x - load| <= RESIDUAL_TOL (|a| |x| + |load|) in every row of a (no, nd)."""
    for i in range(a.shape[0]):
        acc, size = -load[i], abs(load[i])
        for d in range(a.shape[1]):
            acc += a[i, d] * x[d]
            size += abs(a[i, d] * x[d])
        if abs(acc) > RESIDUAL_TOL * size:
            return False
    return True


@jit
def lstsq(a, load):  # pragma: no cover - compiled
    """numba's np.linalg.lstsq (an SVD) at rcond = machine epsilon times the larger size of a."""
    return np.linalg.lstsq(a, load, rcond=np.finfo(np.float64).eps * max(a.shape[0], a.shape[1]))[0]


@jit
def out_of_plane_reactions(e, ud, lam_full, planar_rows, dropped, fixed, rows):  # pragma: no cover - compiled
    """Multipliers of all 3D rows from those of a planar run (lam_full (m_all,), zero on the
    dropped rows): the reactions of the dropped out-of-plane rows ``dropped`` balance the
    out-of-plane equations of motion (the coordinates ``fixed``; out_of_plane_system), the
    solution of least norm (the dropped rows may be redundant); ``rows`` the independent
    equations, picked once per run (independent_equations of the first sample's system).  The
    equations are consistent (detect_planar checked it), so this is lstsq's answer."""
    full = lam_full.copy()
    if dropped.shape[0] == 0:
        return full
    a, load = out_of_plane_system(e, ud, lam_full, planar_rows, dropped, fixed)
    react = minimum_norm_solution(a, load, rows)
    for d in range(dropped.shape[0]):
        full[dropped[d]] = react[d]
    return full
