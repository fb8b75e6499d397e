"""Interfaces on the 6-DOF nodes of an imported shell or beam model (sidprep.fe.matrices.onto_model).

A node whose rotations are DOFs of the FE code's K and M (a beam or shell node: its rotation node
holds rx, ry, rz) carries a master by itself: an interface of one such node is that node's own six
DOFs (kind "node", nothing added; Nastran's a-set grid).  An RBE2 on a patch that holds such nodes
ties their rotations to the master's rotation as well as their translations to its rigid motion
(Nastran RBE2 with components 123456), so a beam end or a shell edge is clamped to the master, and
a straight row of beam nodes can carry rotations about its own line.  An RBE3 averages the
translations, as on solid nodes.  Interfaces are named by a node set of the deck or, for a single
grid, ``GRID<number>`` (Nastran decks carry no node sets).
"""

from __future__ import annotations

import re
from dataclasses import replace

import numpy as np

from sidprep.errors import InputError
from sidprep.reduction.interfaces import Interface

#: an interface name that selects one grid by its number
GRID_NAME = re.compile(r"GRID(\d+)$", re.IGNORECASE)


def six_dof_interface(mesh, spec, rotation_of: np.ndarray | None, unconnected=()) -> Interface | None:
    """The Interface of ``spec`` ("NAME[:rbe2|rbe3]", a node set or GRID<number>) on the 6-DOF nodes
    of ``mesh`` (module docstring), or None when it holds none of them (the usual interfaces apply);
    ``rotation_of``: (n,) rotation-node row of each node row, -1 where the node has none, -2 on the
    rows that are no node of their own (rotation, auxiliary and tube nodes);
    ``unconnected``: rotational DOFs without stiffness (a single node with one cannot be a master)."""
    if not isinstance(spec, str) or rotation_of is None or not (rotation_of >= 0).any():
        return None
    name, _, kind = spec.partition(":")
    nodes = patch_nodes(mesh, name, rotation_of)
    if nodes is None:
        return None
    rot = rotation_of[nodes]
    if not (rot >= 0).any() or (kind or "rbe2").lower() != "rbe2" and len(nodes) > 1:
        return None
    if len(nodes) == 1:
        if np.isin(3 * rot[0] + np.arange(3), unconnected).any():
            raise InputError(f"interface '{name}': a rotation of node {int(mesh.node_ids[nodes[0]])} has no stiffness "
                             "(a beam's torsion or a shell's drilling rotation on nodes that do not resist it), so "
                             "the node cannot carry a 6-DOF master alone; give a node set of at least 3 nodes")
        return Interface(name, np.array([nodes[0], rot[0]]), mesh.points[nodes[0]].copy(), "node")
    return Interface(name, nodes, mesh.points[nodes].mean(axis=0), "rbe2", np.ones(len(nodes)), rot[rot >= 0])


def with_rotations(itf: Interface, rotation_of: np.ndarray | None) -> Interface:
    """``itf`` (a node set or geometric selection) with the rotations of its 6-DOF nodes tied to the
    master when it is an RBE2 (module docstring)."""
    if rotation_of is None or itf.kind != "rbe2":
        return itf
    rot = rotation_of[itf.nodes]
    return replace(itf, rotations=rot[rot >= 0]) if (rot >= 0).any() else itf


def patch_nodes(mesh, name: str, rotation_of: np.ndarray) -> np.ndarray | None:
    """Node rows of the node set ``name``, or the translation row of grid N for GRID<N>; None when
    ``name`` is neither (the caller's message names the valid sets)."""
    if name in mesh.node_sets:
        return np.asarray(mesh.node_sets[name], np.int64)
    match = GRID_NAME.match(name)
    if not match:
        return None
    grid = int(match.group(1))
    rows = np.flatnonzero(mesh.node_ids == grid)          # translations first, then rotation and auxiliary nodes
    if not len(rows):
        raise InputError(f"interface '{name}': grid {grid} is not a node of {mesh.source or 'the model'}; "
                         "give a grid number of the deck")
    if rotation_of[rows[0]] < 0:
        raise InputError(f"interface '{name}': grid {grid} has no rotational DOFs (a solid node), so it cannot carry "
                         "a 6-DOF master alone; give a node set of at least 3 nodes")
    return rows[:1]
