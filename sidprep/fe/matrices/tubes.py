"""Beams drawn as thin tubes in the SID surface (the OBJ and the surface mode shapes).

A line element (CBAR, CBEAM, CROD, ..., B31) between two 6-DOF nodes gets a ring of ``TUBE_SIDES``
vertices around each end, in the plane normal to its axis, of radius ``TUBE_RADIUS_RATIO`` times
the model's largest extent; the rings' quadrilaterals (two triangles each, outward) join the two
ends.  The vertices follow their node rigidly, u = u_o + theta_q x (x - x_o) with q the node's
rotation node (sidprep.fe.matrices.model_dofs), so the tube bends and twists with the beam's
nodes.  They carry the node's number, no mass and no stiffness, and belong to no set: the FE
code's K and M stay as written.  Lines on nodes without rotations (trusses on solid nodes) are not
drawn.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import scipy.sparse as sp

from sidprep.fe.matrices.model_dofs import FullModel

#: vertices of one ring
TUBE_SIDES = 6
#: tube radius, relative to the model's largest extent
TUBE_RADIUS_RATIO = 5e-3


def beam_tubes(full: FullModel, K: sp.csr_matrix, M: sp.csr_matrix, lines: np.ndarray):
    """(FullModel with the ring vertices appended, K and M with their zero rows, followers (node row,
    rotation row, ring rows) for the constraint equations, (nt, 3) tube triangles) of the line
    elements ``lines`` (ne, 2) node numbers (module docstring)."""
    rows = (full.dof(lines.ravel(), 1) // 3).reshape(-1, 2)
    rots = (full.dof(lines.ravel(), 4) // 3).reshape(-1, 2)
    keep = ((rows >= 0) & (rots >= 0)).all(axis=1) if len(lines) else np.zeros(0, bool)
    rows, rots = rows[keep], rots[keep]
    if not len(rows):
        return full, K, M, [], np.zeros((0, 3), np.int64)
    x = full.mesh.points
    axis = x[rows[:, 1]] - x[rows[:, 0]]
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    helper = np.where(np.abs(axis[:, 2:3]) < 0.9, [0.0, 0.0, 1.0], [1.0, 0.0, 0.0])
    e2 = np.cross(axis, helper)
    e2 /= np.linalg.norm(e2, axis=1, keepdims=True)
    e3 = np.cross(axis, e2)
    phi = 2 * np.pi * np.arange(TUBE_SIDES) / TUBE_SIDES
    r = TUBE_RADIUS_RATIO * float(np.ptp(x, axis=0).max())
    ring = r * (np.cos(phi)[None, :, None] * e2[:, None] + np.sin(phi)[None, :, None] * e3[:, None])  # (ne, s, 3)
    vertices = x[rows][:, :, None, :] + ring[:, None]                   # (ne, 2 ends, s, 3)
    n, k = full.mesh.n_nodes, TUBE_SIDES
    first = n + k * np.arange(2 * len(rows)).reshape(-1, 2)             # first ring row per element end
    followers = [(int(o), int(q), int(f) + np.arange(k)) for o, q, f in zip(rows.ravel(), rots.ravel(), first.ravel())]
    nxt = (np.arange(k) + 1) % k
    a, b = first[:, 0:1] + np.arange(k), first[:, 0:1] + nxt
    c, d = first[:, 1:2] + nxt, first[:, 1:2] + np.arange(k)
    triangles = np.concatenate([np.stack([a, b, c], -1), np.stack([a, c, d], -1)], axis=1).reshape(-1, 3)
    mesh = replace(full.mesh, points=np.vstack([x, vertices.reshape(-1, 3)]),
                   node_ids=np.concatenate([full.mesh.node_ids, np.repeat(full.mesh.node_ids[rows.ravel()], k)]))
    start = min(0, int(full.keys.min()))
    keys = np.concatenate([full.keys, start - 1 - np.arange(3 * 2 * k * len(rows))])    # never looked up
    grown = FullModel(mesh, np.concatenate([full.rotational, np.zeros(2 * k * len(rows), bool)]), keys)
    pad = sp.csr_matrix((6 * k * len(rows), 6 * k * len(rows)))
    K, M = (sp.block_diag([A, pad], format="csr") for A in (K, M))
    return grown, K, M, followers, triangles.astype(np.int64)
