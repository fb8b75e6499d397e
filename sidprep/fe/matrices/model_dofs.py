"""The model DOFs of an import: MODEL's nodes completed, the file's rows placed on them, and what
MODEL's deck says of the DOFs without a row.

MODEL's nodes are completed with the nodes the constraints add (reference and rotation nodes of
rigid bodies, nodes of equations on no element) and a *rotation node* per 6-DOF node whose
rotational DOFs carry stiffness (same position and number, its 3 DOFs = rx, ry, rz): every model
node has 3 DOFs, 3 i + c (:class:`FullModel`).  A DOF without a row in the file must be dependent
in the deck's equations or rigid bodies (sidprep.fe.matrices.constraints) or supported
(*BOUNDARY, SPC: a clamped export, whose frame the reduction attaches at the supports).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np
import scipy.sparse as sp

from sidprep.errors import InputError
from sidprep.fe.matrices.record import FEMatrices
from sidprep.fe.matrices.constraints import constraint_map, rigid_equations
from sidprep.fe.matrices.deck import deck_elements


@dataclass(frozen=True)
class FullModel:
    """MODEL's nodes completed: ``mesh`` with the constraints' extra nodes (reference nodes, rotation
    nodes of rigid bodies) and the rotation nodes of 6-DOF nodes appended; ``rotational`` (n,) bool:
    the node's 3 DOFs are rotations; ``keys`` (3n,) 8 node + DOF (1..6) of every model DOF."""

    mesh: object
    rotational: np.ndarray
    keys: np.ndarray

    @cached_property
    def order(self) -> np.ndarray:
        """argsort of ``keys``."""
        return np.argsort(self.keys, kind="stable")

    def dof(self, node, dof) -> np.ndarray:
        """Model DOF index of (node number, DOF 1..6) pairs, -1 where the model has none."""
        key = 8 * np.asarray(node, np.int64) + np.asarray(dof, np.int64)
        pos = np.clip(np.searchsorted(self.keys, key, sorter=self.order), 0, len(self.order) - 1)
        return np.where(self.keys[self.order[pos]] == key, self.order[pos], -1)

    def row_of(self, node: int) -> int:
        """Node row of a node number (its translations, or a rigid body's rotation node)."""
        d = self.dof(node, 1)
        return int(d) // 3 if d >= 0 else -1


def full_model(fe: FEMatrices, mesh, deck, units, path) -> FullModel:
    """FullModel of MODEL, the matrices' DOF map and the deck's constraints (module docstring)."""
    node, dof = fe.dofs[:, 0], fe.dofs[:, 1]
    ids = np.asarray(mesh.node_ids, dtype=np.int64)
    known = np.isin(node, ids)
    extra_ids = np.array(sorted(deck.extra_nodes), np.int64)
    needed = np.unique(np.concatenate([node[~known], extra_ids[~np.isin(extra_ids, ids)]]))
    unknown = needed[~np.isin(needed, extra_ids)]
    if len(unknown):
        raise InputError(f"{path}: {len(unknown)} node(s) of the matrices are not in MODEL {mesh.source} (first: node "
                         f"{int(unknown[0])}); give the deck or mesh the matrices were written from")
    extra_xyz = np.array([deck.extra_nodes[k] for k in needed], float).reshape(-1, 3) * units.length_to_m
    rotation = np.isin(needed, list(deck.rotation_nodes))
    rotating = dof > 3
    stiff = np.zeros(len(dof), bool)
    if rotating.any():
        loaded = np.flatnonzero(rotating)
        stiff[loaded] = np.asarray(abs(fe.K)[loaded].sum(axis=1)).ravel() > 0
    owners = np.unique(node[stiff])                        # nodes that get a rotation node
    base_ids, base_xyz = np.concatenate([ids, needed]), np.vstack([mesh.points, extra_xyz])
    owner_rows = np.argsort(base_ids)[np.searchsorted(base_ids, owners, sorter=np.argsort(base_ids))]
    points = np.vstack([base_xyz, base_xyz[owner_rows]])
    node_ids = np.concatenate([ids, needed, owners])
    rotational = np.concatenate([np.zeros(len(ids), bool), rotation, np.ones(len(owners), bool)])
    first = np.where(np.concatenate([np.zeros(len(ids) + len(needed), bool), np.ones(len(owners), bool)]), 4, 1)
    keys = (8 * np.repeat(node_ids, 3) + np.repeat(first, 3) + np.tile(np.arange(3), len(node_ids))).astype(np.int64)
    full_mesh = mesh if points.shape[0] == mesh.n_nodes else replace(mesh, points=points, node_ids=node_ids)
    return FullModel(full_mesh, rotational, keys)


def embedded(fe: FEMatrices, full: FullModel, path) -> tuple[sp.csr_matrix, sp.csr_matrix, np.ndarray]:
    """K and M permuted onto the model DOFs (zero rows where the file has none) and the (p,) model
    DOFs that have a row, sorted."""
    target = full.dof(fe.dofs[:, 0], fe.dofs[:, 1])
    keep = np.flatnonzero(target >= 0)          # rotational DOFs 4-6 without stiffness have no rotation node
    dropped = np.setdiff1d(np.arange(len(target)), keep)
    if len(dropped) and abs(fe.K[dropped]).sum() > 0:
        raise InputError(f"{path}: a rotational DOF of node {int(fe.dofs[dropped[0], 0])} has no stiffness but "
                         "couples to others; K is damaged: write it again")
    if len(np.unique(target[keep])) != len(keep):
        raise InputError(f"{path}: a node DOF appears twice in the DOF map; the file is damaged: write it again")
    n = len(full.keys)
    if len(keep) == n and np.array_equal(target, np.arange(n)):
        return fe.K, fe.M, np.arange(n)                   # the FE code numbered the DOFs as MODEL does
    P = sp.csr_matrix((np.ones(len(keep)), (target[keep], keep)), shape=(n, fe.K.shape[0]))
    return (P @ fe.K @ P.T).tocsr(), (P @ fe.M @ P.T).tocsr(), np.sort(target[keep])


def model_constraints(full: FullModel, deck, path, length_to_m: float = 1.0, extra_bodies=(), followers=()):
    """(dependent model DOFs (nd,), rigid bodies as (ref row, rot row, node rows), Constraints or
    None) of the deck's equations and rigid bodies on the model DOFs, of ``extra_bodies`` (rigid
    bodies in rows, after the deck's) and of ``followers`` (massless nodes that follow a node
    rigidly, same layout: equations only); ``path``: the deck.  An equation's coefficients on rotations
    carry a length (translation per radian): times ``length_to_m`` in SI."""
    equations, bodies = [], []
    for e in deck.equations:
        dofs = full.dof(e.nodes, e.dofs)
        if (dofs < 0).any():
            k = int(np.flatnonzero(dofs < 0)[0])
            raise InputError(f"{path}: a constraint equation uses DOF {int(e.dofs[k])} of node {int(e.nodes[k])}, "
                             "which the model does not have (no such node in the deck, or a rotation of a solid "
                             "node); fix the equation's node number or DOF")
        rotation = np.repeat(full.rotational, 3)[dofs]
        equations.append((dofs, np.where(rotation, e.coefs * length_to_m, e.coefs)))
    for rb in deck.rigid_bodies:
        rows = full.dof(rb.nodes, 1) // 3
        if (rows < 0).any():
            raise InputError(f"{path}: rigid body {rb.name} holds node {int(rb.nodes[rows < 0][0])}, which is "
                             "on no element of the model; keep its nodes to nodes of the elements")
        ref, rot = full.row_of(rb.ref), int(full.dof(rb.rot, rb.rot_dof)) // 3
        if ref < 0 or rot < 0 or not full.rotational[rot]:
            raise InputError(f"{path}: rigid body {rb.name}: the matrices have no rows for the translations of its "
                             f"reference node {rb.ref} or the rotations of node {rb.rot} (DOF {rb.rot_dof}-"
                             f"{rb.rot_dof + 2}); give REF NODE= and ROT NODE= in the deck (CalculiX), keep GN's "
                             "six DOFs in the a-set (Nastran RBE2), and write the matrices again")
        equations += rigid_equations(full.mesh.points, rows, ref, rot, [d - 1 for d in rb.dofs])
        bodies.append((ref, rot, rows))
    for ref, rot, rows in extra_bodies:
        equations += rigid_equations(full.mesh.points, rows, ref, rot)
        bodies.append((ref, rot, rows))
    for ref, rot, rows in followers:
        equations += rigid_equations(full.mesh.points, rows, ref, rot)
    if not equations:
        return np.zeros(0, np.int64), bodies, None
    constraints = constraint_map(equations, len(full.keys), path, lambda d: describe_dof(full, d))
    return constraints.dependent, bodies, constraints


def describe_dof(full: FullModel, d: int) -> str:
    """'DOF c of node N' for a model DOF index."""
    return f"DOF {int(full.keys[d] % 8)} of node {int(full.keys[d] // 8)}"


def clamped_nodes(full: FullModel, deck, present: np.ndarray, dependent: np.ndarray, path) -> np.ndarray:
    """Node rows whose translations the export removed as supports (*BOUNDARY, SPC): checked that
    every model DOF without a row is a dependent or a supported one, and that supports hold whole
    nodes (module docstring)."""
    n = len(full.keys)
    has_row = np.zeros(n, bool)
    has_row[present] = True
    on_dep = np.zeros(n, bool)
    on_dep[dependent] = True
    if (has_row & on_dep).any():
        d = int(np.flatnonzero(has_row & on_dep)[0])
        raise InputError(f"{path}: {describe_dof(full, d)} is dependent in the deck's constraints but the matrices "
                         "have a row for it: they were written from another deck; give MODEL = the deck of the run")
    supported = np.zeros(n, bool)
    if len(deck.supported):
        dofs = full.dof(deck.supported[:, 0], deck.supported[:, 1])
        supported[dofs[dofs >= 0]] = True
    missing = ~has_row & ~on_dep
    unexplained = missing & ~supported
    translational = np.repeat(~full.rotational, 3)
    if (unexplained & translational).any():
        lost = (~has_row & translational).reshape(-1, 3)[~full.rotational]
        if lost.all(axis=0).any():
            gone = ", ".join(str(c + 1) for c in np.flatnonzero(lost.all(axis=0)))
            raise InputError(f"{path}: every node of MODEL lacks DOF {gone} (GRDSET / SPC on all nodes: a planar or "
                             "one-direction model); a SID needs the 3D motion of every node (its invariants are 3D): "
                             "export the 3D model with all translations")
        d = int(np.flatnonzero(unexplained & translational)[0])
        raise InputError(f"{path}: {int((unexplained & translational).sum())} of the translational DOFs of MODEL "
                         f"{full.mesh.source} have no row (first: {describe_dof(full, d)}) and the deck neither "
                         "supports (SPC/*BOUNDARY) nor constrains them (*EQUATION/*RIGID BODY): the matrices come "
                         "from another model, or the deck is not MODEL; give the deck the matrices were written from")
    clamp = (missing & supported).reshape(-1, 3)
    partial = clamp.any(axis=1) & ~clamp.all(axis=1)
    if partial.any():
        i = int(np.flatnonzero(partial)[0])
        raise InputError(f"{path}: node {int(full.mesh.node_ids[i])} is supported in DOF "
                         f"{', '.join(str(c + 1) for c in np.flatnonzero(clamp[i]))} only (a roller or symmetry "
                         "support); the body frame attaches at clamped nodes (all three translations): clamp whole "
                         "nodes or export the free model")
    return np.flatnonzero(clamp.all(axis=1))


def clamp_of(clamped: np.ndarray, full: FullModel, deck, bodies, path) -> tuple[np.ndarray, str, str]:
    """(node rows, name, interface kind) of the clamp: whole solid nodes (an RBE2 carries the frame,
    named after the *BOUNDARY / SPC set), or a rigid body's reference and rotation nodes both
    supported (its 6 DOFs are the frame, named after the rigid body)."""
    if not len(clamped):
        return clamped, "", ""
    rotations = clamped[full.rotational[clamped]]
    nodes = clamped[~full.rotational[clamped]]
    pairs = {ref: (rot, rb.name) for (ref, rot, _), rb in zip(bodies, deck.rigid_bodies)}
    if not len(rotations) and not set(nodes.tolist()) & set(pairs):
        return clamped, deck.support_sets[0] if len(deck.support_sets) == 1 else "CLAMP", "rbe2"
    if len(nodes) == 1 and len(rotations) == 1 and pairs.get(int(nodes[0]), (None,))[0] == rotations[0]:
        return np.array([nodes[0], rotations[0]]), pairs[int(nodes[0])][1], "node"
    raise InputError(f"{path}: the supports hold a rigid body's reference node without its rotation node (a pin: "
                     "the body turns freely) or mix rotation nodes and solid nodes; clamp the reference node and the "
                     "rotation node (*BOUNDARY, REF, 1, 3 and ROT, 1, 3) or whole solid nodes")


def glued_surface(mesh, deck, constraints):
    """MODEL's outer surface without the faces glued by node-to-node equations (u_a = u_b in one DOF
    between coincident nodes: inside the body), or the surface unchanged."""
    pairs = np.array([e.nodes for e in deck.equations if len(e.nodes) == 2 and e.dofs[0] == e.dofs[1]
                      and np.isclose(e.coefs[0], -e.coefs[1])], np.int64).reshape(-1, 2)
    if constraints is None or mesh.surface is None or not len(pairs):
        return mesh.surface
    ids, first = np.unique(mesh.node_ids, return_index=True)     # translations come before rotation nodes
    pos = np.clip(np.searchsorted(ids, pairs), 0, len(ids) - 1)
    rows = first[pos]
    found = (ids[pos] == pairs).all(axis=1)
    rows = rows[found & np.isclose(mesh.points[rows[:, 0]], mesh.points[rows[:, 1]]).all(axis=1)]
    glued, partner = np.zeros(mesh.n_nodes, bool), np.zeros(mesh.n_nodes, bool)
    glued[rows[:, 0]], partner[rows[:, 1]] = True, True
    tri = mesh.surface
    return tri[~(glued[tri].all(axis=1) | partner[tri].all(axis=1))]


def away_from(nodes: np.ndarray, full: "FullModel", present: np.ndarray, source) -> np.ndarray:
    """(len(present),) bool: the DOFs of nodes that share no element of the deck ``source`` with ``nodes``."""
    near = np.zeros(len(full.keys), bool)
    ids = set(full.mesh.node_ids[nodes].tolist())
    for e in deck_elements(source):
        touching = np.isin(e, list(ids)).any(axis=1)
        rows = full.dof(np.repeat(e[touching].ravel(), 3), np.tile([1, 2, 3], e[touching].size))
        near[rows[rows >= 0]] = True
    return ~near[present]
