"""Eigenmodes of a mechanism linearised at its assembled start (SIMPACK's "eigenvalues at the
current state", with the velocities set to zero).

On the tangent space of the constraints, N spanning the null space of the kept rows B at the
assembled positions x0 (B N = 0), the small free vibrations about x0 obey

    N^T M N  z'' + N^T K N z = 0,   K = -d f / d x  (central differences on the Lie group),

with M and f the system's mass matrix and applied/inertial forces of ``equations.assemble``
(velocities zero, so gyroscopic and damping terms vanish; the geometric stiffness of the
constraint reactions, zero without preload, is not included).  Undamped frequencies
f_k = sqrt(lambda_k) / (2 pi); rigid-body motions of the mechanism give f = 0.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import scipy.linalg

from sidprep.solver.integrators.base import constraint_rows, evaluate, moved_pose
from sidprep.solver.integrators.settings import SolverSettings
from sidprep.solver.run import Run

#: relative finite-difference step on the length-weighted coordinates (central differences)
FD_STEP = 1e-6
#: eigenvalues below this fraction of the largest are rigid-body (zero-frequency) motions
RIGID_TOL = 1e-10


@dataclass(frozen=True)
class MechanismModes:
    """frequencies_hz (k,) ascending, Hz (0 for rigid-body motions and for negative stiffness:
    an unstable or unbalanced pose); shapes (n, k) velocity-coordinate shapes (columns
    mass-normalised on N^T M N); n_rigid the number of rigid-body motions; coordinates
    [(body name, 'v_O.x' | 'omega.x' | 'q.k')] naming the rows of the shapes."""

    frequencies_hz: np.ndarray
    shapes: np.ndarray
    n_rigid: int
    coordinates: tuple


def coordinate_names(system) -> tuple:
    """(body, coordinate) of every velocity coordinate, in the layout's order."""
    names = []
    for b in system.bodies:
        names += [(b.name, f"{k}.{a}") for k in ("v_O", "omega") for a in "xyz"]
        names += [(b.name, f"q.{k + 1}") for k in range(getattr(b, "nq", 0))]
    return tuple(names)


def tangent_stiffness(L, R, A, Q, refs, weights, length) -> np.ndarray:
    """K = -d f / d x (n, n) at zero velocity, central differences of step FD_STEP L / w."""
    n = int(L.uoff[-1])
    zero_u, lam = np.zeros(n), np.zeros(constraint_rows(L))
    K = np.empty((n, n))
    for j in range(n):
        e = FD_STEP * length / weights[j]
        dx = np.zeros(n)
        dx[j] = e
        fp = evaluate(L, *moved_pose(L, R, A, Q, dx), zero_u, 0.0, lam, refs).f
        fm = evaluate(L, *moved_pose(L, R, A, Q, -dx), zero_u, 0.0, lam, refs).f
        K[:, j] = -(fp - fm) / (2 * e)
    return K


def mechanism_modes(system, settings=None, **overrides) -> MechanismModes:
    """The eigenmodes of ``system`` linearised at its assembled start (module doc).

    settings, overrides : as ``solver.run.simulate`` (the effects choose the terms of K).
    """
    run = Run(system, 1.0, replace(settings or SolverSettings(), **overrides))
    state = run.consistent_start()
    L, free, kept = run.L, run.free, run.kept
    lam = np.zeros(len(run.names))
    e = evaluate(L, state.R, state.A, state.Q, np.zeros_like(state.u), 0.0, lam, run.refs)
    M, B = e.M, e.B
    K = tangent_stiffness(L, state.R, state.A, state.Q, run.refs, run.weights, run.length)
    N = scipy.linalg.null_space(B[np.ix_(kept, free)]) if kept.size else np.eye(free.size)
    Nf = np.zeros((M.shape[0], N.shape[1]))
    Nf[free] = N
    Kr = Nf.T @ K @ Nf
    lam_k, z = scipy.linalg.eigh(0.5 * (Kr + Kr.T), Nf.T @ M @ Nf)
    rigid = np.abs(lam_k) <= RIGID_TOL * max(np.abs(lam_k).max(), 1e-300)
    freq = np.sqrt(np.clip(lam_k, 0.0, None)) / (2 * np.pi)
    freq[rigid] = 0.0
    order = np.argsort(freq)
    return MechanismModes(freq[order], Nf @ z[:, order], int(rigid.sum()), coordinate_names(system))
