"""Elastic-like interpolation from a few simulation nodes onto many animation points (Heckmann et al. 2006 section 5).

The displacement field is a polyharmonic spline in 3-D: the kernel phi(r) = r^3 is the fundamental
solution of the triharmonic operator (Delta^3 r^3 ~ delta in R^3), plus an affine part,

    u(x) = sum_i w_i |x - c_i|^3 + a0 + A x,      sum_i w_i = 0,  sum_i w_i c_i^T = 0,

solved per displacement component.  Properties (tested in tests/test_interpolation.py):

* exact at the simulation nodes (interpolation conditions);
* affine fields, hence every (linearised) rigid-body motion u = a + omega x c, are reproduced
  exactly (the side conditions make the kernel weights vanish for them);
* it minimises a smoothness semi-norm (of third derivatives) among all interpolants, so the surface is smooth between nodes, without
  the peaks or cracks of polynomial fits.

When the nodes span fewer than three dimensions (four corners of a plate, nodes along a beam axis),
the affine part lives in their span only; otherwise the system would be singular.

This module depends on numpy only (the solver and the viewer import it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: relative singular value below which the nodes are taken to have no extent in a direction
SPAN_TOLERANCE = 1e-9


@dataclass(frozen=True)
class ElasticInterpolation:
    """Linear map from node displacements to animation point displacements.

    Attributes
    ----------
    weights : (na, nc) float64
        u_animation = weights @ u_nodes, for each displacement component (and each mode or step).
    """

    weights: np.ndarray

    def __call__(self, u_nodes: np.ndarray) -> np.ndarray:
        """Displacements at the animation points.

        Parameters
        ----------
        u_nodes : (nc, ...) node displacements, any trailing shape (3, modes, steps), in m.

        Returns
        -------
        (na, ...) displacements at the animation points, same units.
        """
        u = np.asarray(u_nodes, dtype=float)
        return np.tensordot(self.weights, u, axes=(1, 0))


def kernel(r: np.ndarray) -> np.ndarray:
    """Polyharmonic kernel phi(r) = r^3 (fundamental solution of Delta^3 in 3-D), r scaled."""
    return r**3


def _affine_basis(points: np.ndarray, centre: np.ndarray, axes: np.ndarray, scale: float) -> np.ndarray:
    """(n, 1 + d) columns 1, and the coordinates along the nodes' d spanned axes (scaled)."""
    local = (points - centre) @ axes.T / scale
    return np.hstack([np.ones((len(points), 1)), local])


def elastic_interpolation(nodes: np.ndarray, points: np.ndarray) -> ElasticInterpolation:
    """Build the polyharmonic-spline map from simulation ``nodes`` to animation ``points``.

    Parameters
    ----------
    nodes : (nc, 3) undeformed simulation node positions, m.  At least one; distinct.
    points : (na, 3) undeformed animation point positions, m.

    Returns
    -------
    ElasticInterpolation with weights (na, nc).
    """
    nodes = np.asarray(nodes, dtype=float).reshape(-1, 3)
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    nc = len(nodes)
    centre = nodes.mean(axis=0)
    _, s, vt = np.linalg.svd(nodes - centre, full_matrices=False)
    scale = float(s[0] / np.sqrt(nc)) if nc > 1 and s[0] > 0 else 1.0
    axes = vt[s > SPAN_TOLERANCE * max(s[0], 1e-300)] if nc > 1 else np.zeros((0, 3))
    P = _affine_basis(nodes, centre, axes, scale)
    K = kernel(np.linalg.norm(nodes[:, None, :] - nodes[None, :, :], axis=2) / scale)
    m = P.shape[1]
    system = np.block([[K, P], [P.T, np.zeros((m, m))]])
    Ka = kernel(np.linalg.norm(points[:, None, :] - nodes[None, :, :], axis=2) / scale)
    Pa = _affine_basis(points, centre, axes, scale)
    # weights = [Ka Pa] system^-1 [I; 0]  (system is symmetric)
    rhs = np.hstack([Ka, Pa])
    solved = np.linalg.solve(system, rhs.T)
    return ElasticInterpolation(weights=solved[:nc].T.copy())
