"""The surface of a body in its frame K and its motion: one model for the viewer's pages and the
solver's ParaView animation.

A surface is points c (ns, 3) m, triangles (nf, 3) and shapes S (ns, 3, nq): the displacement of
each point per unit modal coordinate (nq = 0 for a rigid body).  A point moves as

    x = r_O + A (c + S q)                         (sid-spec section 5.2, node kinematics)

Depends on numpy and ``sidprep.interpolation`` (numpy only), like the rest of ``sidprep.sid``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sidprep.interpolation import elastic_interpolation
from sidprep.sid.stress import stress_on_points, von_mises


@dataclass(frozen=True)
class Surface:
    """Body-frame surface of one body.

    points (ns, 3) m in K; triangles (nf, 3) int64 (empty: the points are drawn as vertices);
    shapes (ns, 3, nq) m per unit modal coordinate (nq = 0 for rigid bodies); ``source`` says how
    the surface was obtained; stress (ns, 6, nq) Pa per unit modal coordinate at the points, or None.
    """

    points: np.ndarray
    triangles: np.ndarray
    shapes: np.ndarray
    source: str = ""
    stress: np.ndarray | None = None


def node_points(sid) -> tuple[np.ndarray, np.ndarray]:
    """Undeformed node positions (nc, 3) m and node mode shapes phi (nc, 3, nq) of a SID."""
    points = np.array([n.origin.M0[:, 0] for n in sid.nodes], float).reshape(-1, 3)
    phi = np.array([n.phi.M0 for n in sid.nodes], float).reshape(-1, 3, sid.nq)
    return points, phi


def rigid_surface(points, triangles, source: str = "") -> Surface:
    """A surface that does not deform (shapes with nq = 0)."""
    points = np.asarray(points, float)
    return Surface(points, np.asarray(triangles, np.int64), np.zeros((len(points), 3, 0)), source)


def stored_surface(sid) -> Surface | None:
    """The FE surface modes stored in the SID, or None when it has none (e.g. a SID_FEM file)."""
    if sid.surface is None:
        return None
    s = sid.surface
    points = np.asarray(s.points, float)
    return Surface(points, np.asarray(s.triangles, np.int64), np.asarray(s.shapes, float),
                   "FE surface modes stored in the SID",
                   None if sid.stress is None else stress_on_points(sid.stress, points))


def interpolated_surface(sid, points, triangles, source: str) -> Surface:
    """A surface (points (ns, 3) m, triangles) whose points follow the SID's nodes by the elastic
    interpolation (Heckmann et al. 2006 section 5)."""
    nodes, phi = node_points(sid)
    points = np.asarray(points, float)
    return Surface(points, np.asarray(triangles, np.int64), elastic_interpolation(nodes, points)(phi), source)


def node_surface(sid) -> Surface:
    """The SID's nodes as a surface of vertices (no triangles), moving with their mode shapes."""
    nodes, phi = node_points(sid)
    return Surface(nodes, np.zeros((0, 3), np.int64), phi, f"the {len(nodes)} SID nodes")


def sid_surface(sid) -> Surface:
    """A SID's own surface: its stored FE surface modes, else its nodes as vertices."""
    stored = stored_surface(sid)
    return stored if stored is not None else node_surface(sid)


def surface_motion(surface: Surface, r: np.ndarray, A: np.ndarray, q: np.ndarray,
                   scale: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Inertial positions and elastic displacements of the surface points over time.

    x = r_O + A (c + scale S q),  u = A S q (true size).

    Parameters
    ----------
    r : (nt, 3) m;  A : (nt, 3, 3);  q : (nt, nq)

    Returns
    -------
    x : (nt, ns, 3) m;  u : (nt, ns, 3) m, inertial components.
    """
    if surface.shapes.shape[2]:
        local_u = np.einsum("sak,tk->tsa", surface.shapes, q)
    else:
        local_u = np.zeros((len(r),) + surface.points.shape)
    x = r[:, None, :] + np.einsum("tab,tsb->tsa", A, surface.points[None] + scale * local_u)
    return x, np.einsum("tab,tsb->tsa", A, local_u)


def surface_von_mises(surface: Surface, q: np.ndarray) -> np.ndarray | None:
    """Von Mises stress (nt, ns) Pa at the surface points for modal coordinates q (nt, nq),
    sigma = sum_k sigma_k q_k; None for a surface without modal stresses."""
    if surface.stress is None:
        return None
    return von_mises(np.einsum("sck,tk->tsc", surface.stress, q[:, :surface.stress.shape[2]]))
