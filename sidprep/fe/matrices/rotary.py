"""Rotary inertia of 6-DOF nodes (beam and shell rotary mass, CONM2 inertia) as point masses.

The SID invariants integrate the mass of nodes that translate, M = Ms (x) E3 (sid-spec 4.2).  A
6-DOF node o whose rotation node q carries mass (its rotary inertia, and the couplings of a
consistent beam or shell mass) gets 14 auxiliary nodes x_o + d p_k (the 6 axis points and the 8
cube corners of the unit sphere, d = ``AUX_SIZE_RATIO`` times the model's extent) that follow o
and q rigidly, u = u_o + theta_q x (x - x_o): a rigid body without mass of its own whose rotation
rows hold the inertia, which sidprep.fe.matrices.constraints.solid_mass puts on the auxiliary
nodes exactly (the 14 points span the 10 moments up to second order).  Auxiliary nodes carry the
owner's node number and belong to no set, surface or element; the FE code's K and M stay as written.
"""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import scipy.sparse as sp

from sidprep.errors import InputError
from sidprep.fe.matrices.model_dofs import FullModel

#: the auxiliary nodes of one rotary inertia, on the unit sphere (14, 3)
AUX_PATTERN = np.vstack([np.eye(3), -np.eye(3), np.array(list(itertools.product((-1.0, 1.0), repeat=3))) / np.sqrt(3)])
#: their distance from the node, relative to the model's largest extent
AUX_SIZE_RATIO = 1e-2


def inertia_nodes(full: FullModel, K: sp.csr_matrix, M: sp.csr_matrix, skip, path):
    """(FullModel with the auxiliary nodes appended, K and M with their zero rows, rigid bodies
    (owner row, rotation row, auxiliary rows)) of the rotation nodes that carry mass, but the
    rotation nodes ``skip`` (rigid bodies' own).  InputError for mass on a rotation without stiffness."""
    n = full.mesh.n_nodes
    mass = np.asarray(abs(M).sum(axis=1)).ravel().reshape(n, 3).sum(axis=1) > 0
    rotations = np.flatnonzero(full.rotational & mass & ~np.isin(np.arange(n), list(skip)))
    if not len(rotations):
        return full, K, M, []
    stiff = K.diagonal().reshape(n, 3)[rotations]
    massed = M.diagonal().reshape(n, 3)[rotations]
    if ((stiff == 0) & (massed != 0)).any():
        i = int(np.flatnonzero(((stiff == 0) & (massed != 0)).any(axis=1))[0])
        raise InputError(f"{path}: node {int(full.mesh.node_ids[rotations[i]])} has rotary inertia about an axis it "
                         "has no stiffness for (a drilling or torsion DOF connected to nothing); export the model "
                         "without that inertia")
    owners = full.dof(full.mesh.node_ids[rotations], 1) // 3
    d = AUX_SIZE_RATIO * float(np.ptp(full.mesh.points, axis=0).max())
    aux = (full.mesh.points[owners][:, None, :] + d * AUX_PATTERN[None]).reshape(-1, 3)
    k = len(AUX_PATTERN)
    mesh = replace(full.mesh, points=np.vstack([full.mesh.points, aux]),
                   node_ids=np.concatenate([full.mesh.node_ids, np.repeat(full.mesh.node_ids[owners], k)]))
    keys = np.concatenate([full.keys, -1 - np.arange(3 * len(aux))])     # never looked up by (node, DOF)
    grown = FullModel(mesh, np.concatenate([full.rotational, np.zeros(len(aux), bool)]), keys)
    pad = sp.csr_matrix((3 * len(aux), 3 * len(aux)))
    K, M = (sp.block_diag([A, pad], format="csr") for A in (K, M))
    bodies = [(int(o), int(r), n + k * i + np.arange(k)) for i, (o, r) in enumerate(zip(owners, rotations))]
    return grown, K, M, bodies
