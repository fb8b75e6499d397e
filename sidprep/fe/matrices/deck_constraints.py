"""What a deck says about the DOFs its FE code removed: constraint equations, rigid bodies, supports.

An FE code that writes K and M of a constrained model leaves out the DOFs it eliminated: the
dependent DOF of every equation and the supported (SPC'd) DOFs.  sidprep recovers them from the
deck the matrices were written from (sidprep.fe.matrices.constraints):

* CalculiX (ccx 2.x User's Manual): ``*EQUATION`` (the number of terms, then ``node, DOF,
  coefficient`` per term, 4 terms per line; the first term is the dependent one);
  ``*RIGID BODY, NSET= | ELSET=, REF NODE=, ROT NODE=`` and ``*COUPLING, REF NODE=, SURFACE=``
  with ``*KINEMATIC`` on DOFs 1-3 (node or element-face ``*SURFACE``), which ccx makes the same
  rigid body (every node of the set follows the reference node
  and the rotation node's DOFs 1-3, which are the rotation; ccx generates the two nodes when they
  are not given: the reference node at the origin, numbered after the largest node number, then
  the rotation node, then one helper node per dependent node, src/rigidbodies.f and rigidmpc.f);
  ``*BOUNDARY`` (``node or set, first DOF[, last DOF[, value]]``, or ENCASTRE / PINNED);
* Nastran (MSC/NX Quick Reference Guide): ``MPC`` (SID, then G, C, A per term, the first
  dependent), ``RBE2`` (EID, GN, CM, GM...: the GM grids follow GN rigidly in the components CM,
  theta being GN's DOFs 4-6), ``SPC``, ``SPC1`` (with ``THRU``), the PS field of ``GRID`` and
  ``GRDSET`` (every SPC and MPC of the deck: sidprep reads no subcases).

Distributing couplings (``*DISTRIBUTING``, ``*DISTRIBUTING COUPLING``), CalculiX's nonlinear
``*MPC`` types, ``*TIE``, Nastran's RBE3 and RBAR are refused with a one-line InputError that
names the card and what to write instead.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from sidprep.errors import InputError
from sidprep.fe.matrices.keywords import (deck_nodes, element_sets, elements, fields, keyword_blocks, node_sets,
                                          surface_nodes)
from sidprep.fe.matrices.nastran import cards, nastran_real


@dataclass(frozen=True)
class Equation:
    """sum_k a_k u(node_k, dof_k) = 0, the first term dependent; nodes, dofs (1..6), coefs: (k,)."""

    nodes: np.ndarray
    dofs: np.ndarray
    coefs: np.ndarray


@dataclass(frozen=True)
class RigidBody:
    """Nodes that follow a reference node rigidly: u_d = u_ref + theta x (x_d - x_ref) in the DOFs
    ``dofs`` (1..3) of each node; theta is DOF rot_dof .. rot_dof + 2 of node ``rot``: 1-3 of
    CalculiX's rotation node, 4-6 of a Nastran RBE2's independent grid."""

    name: str
    nodes: np.ndarray
    ref: int
    rot: int
    dofs: tuple[int, ...] = (1, 2, 3)
    rot_dof: int = 1


@dataclass(frozen=True)
class DeckConstraints:
    """The constraints of a deck (module docstring), by the deck's node numbers.

    equations, rigid_bodies; supported : (m, 2) node and DOF (1..6) of every SPC'd DOF;
    support_sets : the node-set names the supports were given with; extra_nodes : {node: (3,)
    position} of nodes the constraints use that need not lie on an element (reference and
    rotation nodes; generated ones at the origin, as ccx places them); node_sets : {name: nodes}.
    """

    equations: tuple[Equation, ...] = ()
    rigid_bodies: tuple[RigidBody, ...] = ()
    supported: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), np.int64))
    support_sets: tuple[str, ...] = ()
    extra_nodes: dict = field(default_factory=dict)
    node_sets: dict = field(default_factory=dict)

    @property
    def rotation_nodes(self) -> set[int]:
        """Nodes whose DOFs 1-3 are rotations (CalculiX rigid bodies' rotation nodes)."""
        return {rb.rot for rb in self.rigid_bodies if rb.rot_dof == 1}


#: CalculiX / Abaqus keywords whose constraints sidprep does not recover, and what to write instead
REFUSED_KEYWORDS = {
    "DISTRIBUTING": "export without it (sidprep adds RBE3 interfaces itself: --interface SET:rbe3)",
    "DISTRIBUTINGCOUPLING": "export without it (sidprep adds RBE3 interfaces itself: --interface SET:rbe3)",
    "MPC": "write linear constraints as *EQUATION or a rigid face as *RIGID BODY",
    "TIE": "tie the parts with *EQUATION or shared nodes",
    "CYCLICSYMMETRYMODEL": "export the whole model",
}
#: Nastran cards refused, and what to do
REFUSED_CARDS = {"RBE3": "export without it: sidprep adds RBE3 interfaces itself (--interface SET:rbe3)",
                 "RBAR": "replace it by an RBE2 interface of sidprep (--interface SET:rbe2)"}
#: Abaqus named boundary conditions: the DOFs they fix
NAMED_SUPPORTS = {"ENCASTRE": (1, 6), "PINNED": (1, 3)}


def deck_constraints(path) -> DeckConstraints:
    """The constraints of the deck ``path``: CalculiX / Abaqus (``.inp``) or Nastran (``.bdf``,
    ``.nas``, ``.dat``); other formats state none."""
    suffix = Path(path).suffix.lower()
    if suffix == ".inp":
        return calculix_constraints(path)
    if suffix in (".bdf", ".nas", ".dat"):
        return nastran_constraints(path)
    return DeckConstraints()


def calculix_constraints(path) -> DeckConstraints:
    """*EQUATION, *RIGID BODY and *BOUNDARY of a CalculiX deck (module docstring)."""
    blocks = keyword_blocks(path)
    for b in blocks:
        if b.keyword in REFUSED_KEYWORDS:
            raise InputError(f"{path}: *{b.keyword} is not read by sidprep (the DOFs it removes cannot be "
                             f"recovered); {REFUSED_KEYWORDS[b.keyword]}")
    ids, xyz = deck_nodes(blocks, path)
    positions = dict(zip(ids.tolist(), xyz))
    sets = node_sets(blocks, path)
    equations = [e for b in blocks if b.keyword == "EQUATION" for e in calculix_equations(b, path)]
    next_node = int(ids.max(initial=0)) + 1                 # ccx's nk + 1: generated nodes
    bodies, extra = [], {}
    for k, b in enumerate(blocks):
        if b.keyword == "RIGIDBODY":
            body, next_node = rigid_body(b, rigid_body_nodes(b, blocks, sets, path), positions, next_node, path)
        elif b.keyword == "COUPLING":
            body, next_node = kinematic_coupling(b, blocks[k + 1] if k + 1 < len(blocks) else None, blocks,
                                                 positions, next_node, path)
        else:
            continue
        bodies.append(body)
        extra[body.ref] = positions.get(body.ref, np.zeros(3))
        extra[body.rot] = extra[body.ref]
    for e in equations:
        extra.update({int(n): positions[int(n)] for n in e.nodes if int(n) in positions})
    supported, support_sets = calculix_supports([b for b in blocks if b.keyword == "BOUNDARY"], sets, path)
    return DeckConstraints(tuple(equations), tuple(bodies), supported, support_sets, extra, sets)


def calculix_equations(block, path) -> list[Equation]:
    """The equations of one *EQUATION block (module docstring)."""
    values = [v for v in fields(block.lines) if v]
    out, k = [], 0
    try:
        while k < len(values):
            n = int(values[k])
            terms = values[k + 1:k + 1 + 3 * n]
            if n < 1 or len(terms) != 3 * n:
                raise ValueError
            nodes = np.array([int(t) for t in terms[0::3]], np.int64)
            out.append(Equation(nodes, np.array([int(t) for t in terms[1::3]], np.int64),
                                np.array([float(t) for t in terms[2::3]])))
            k += 1 + 3 * n
    except ValueError:
        raise InputError(f"{path}: an *EQUATION block is not 'number of terms' then 'node, DOF, coefficient' "
                         "per term (node numbers, not set names); fix the deck") from None
    return out


def rigid_body_nodes(block, blocks, sets, path) -> np.ndarray:
    """The node numbers of a *RIGID BODY: its NSET, or the nodes of the elements of its ELSET."""
    p = block.params
    if "NSET" in p:
        if p["NSET"] not in sets:
            raise InputError(f"{path}: *RIGID BODY, NSET={p['NSET']}: no such node set in the deck; define it with "
                             "*NSET")
        return sets[p["NSET"]]
    if "ELSET" in p:
        table, esets = elements(blocks), element_sets(blocks, path)
        if p["ELSET"] not in esets:
            raise InputError(f"{path}: *RIGID BODY, ELSET={p['ELSET']}: no such element set in the deck; define it "
                             "with *ELSET")
        return np.unique(np.concatenate([table[e][1] for e in esets[p["ELSET"]] if e in table] + [np.zeros(0, int)]))
    raise InputError(f"{path}: *RIGID BODY without NSET= or ELSET=; give the rigid body's node or element set")


def rigid_body(block, nodes, positions, next_node: int, path, name=None) -> tuple[RigidBody, int]:
    """The RigidBody of one *RIGID BODY block (or a kinematic coupling) on the node numbers ``nodes``,
    and the next free node number after the nodes ccx generates for it (module docstring)."""
    p = block.params
    ref, rot = (int(p[k]) if p.get(k) else 0 for k in ("REFNODE", "ROTNODE"))
    for label, node in (("REF NODE", ref), ("ROT NODE", rot)):
        if node and node not in positions:
            raise InputError(f"{path}: *{block.keyword}, {label}={node}: node {node} is not in the deck; define it "
                             "with *NODE (its position is the reference point)")
    if not ref:
        ref, next_node = next_node, next_node + 1
    if not rot:
        rot, next_node = next_node, next_node + 1
    nodes = nodes[(nodes != ref) & (nodes != rot)]
    name = name or p.get("NSET") or p.get("ELSET")
    return RigidBody(name, nodes, ref, rot), next_node + len(nodes)


def kinematic_coupling(block, following, blocks, positions, next_node: int, path) -> tuple[RigidBody, int]:
    """A ``*COUPLING, REF NODE=, SURFACE=`` with ``*KINEMATIC`` on DOFs 1-3: ccx makes it a rigid body of
    the surface's nodes on the reference node and a generated rotation node (the same equations and
    frequencies as *RIGID BODY; measured with ccx 2.20)."""
    p = block.params
    if following is None or following.keyword != "KINEMATIC":
        kind = f"*{following.keyword}" if following is not None else "nothing"
        raise InputError(f"{path}: *COUPLING followed by {kind}: sidprep reads kinematic couplings (*KINEMATIC) "
                         "only; export a distributing coupling without it (sidprep adds RBE3 interfaces itself)")
    dofs = set()
    for line in following.lines:
        row = [v.strip() for v in line.split(",") if v.strip()]
        dofs.update(range(int(row[0]), int(row[-1]) + 1))
    if dofs != {1, 2, 3} or "REFNODE" not in p or "SURFACE" not in p:
        raise InputError(f"{path}: *COUPLING {p.get('CONSTRAINTNAME', '')}: sidprep reads kinematic couplings of all "
                         "three translations (*KINEMATIC: 1, 3) with REF NODE= and SURFACE=; write it so or as "
                         "*RIGID BODY")
    return rigid_body(block, surface_nodes(blocks, p["SURFACE"], path), positions, next_node, path,
                      name=p.get("CONSTRAINTNAME") or p["SURFACE"])


def calculix_supports(blocks, sets, path) -> tuple[np.ndarray, tuple[str, ...]]:
    """((m, 2) node and DOF of every DOF fixed by *BOUNDARY, the set names used)."""
    rows, names = [], []
    for b in blocks:
        for line in b.lines:
            row = [f.strip().upper() for f in line.split(",")]
            try:
                first, last = NAMED_SUPPORTS[row[1]] if row[1] in NAMED_SUPPORTS else \
                    (int(row[1]), int(row[2]) if len(row) > 2 and row[2] else int(row[1]))
            except (IndexError, ValueError):
                raise InputError(f"{path}: *BOUNDARY line '{line}' is not 'node or set, first DOF[, last DOF]' "
                                 "(or ENCASTRE / PINNED); fix the deck") from None
            if row[0].lstrip("-").isdigit():
                nodes = [int(row[0])]
            elif row[0] in sets:
                nodes = sets[row[0]].tolist()
                names.append(row[0])
            else:
                raise InputError(f"{path}: *BOUNDARY names the node set {row[0]}, which the deck does not "
                                 "define; define it with *NSET")
            rows += [(n, d) for n in nodes for d in range(first, last + 1)]
    supported = np.unique(np.array(rows, np.int64).reshape(-1, 2), axis=0)
    return supported, tuple(dict.fromkeys(names))


def nastran_constraints(path) -> DeckConstraints:
    """The SPC'd DOFs (SPC, SPC1, GRID / GRDSET PS), MPC equations and RBE2 rigid elements of a
    Nastran deck (module docstring)."""
    rows, grids, default_ps, equations, bodies, positions = [], {}, "", [], [], {}
    for card in cards(path, bulk_only=True):
        name = card[0].rstrip("*").upper()
        if name in REFUSED_CARDS:
            raise InputError(f"{path}: {name} cards are not read by sidprep (the DOFs they make dependent cannot "
                             f"be recovered); {REFUSED_CARDS[name]}")
        try:
            if name == "GRID":
                grids[int(card[1])] = card[7] if len(card) > 7 else ""
                if not card[2].strip("0 "):                # basic coordinates (CP blank or 0)
                    positions[int(card[1])] = np.array([nastran_real(v) if v else 0.0 for v in card[3:6]])
            elif name == "GRDSET":
                default_ps = card[7] if len(card) > 7 else ""
            elif name == "SPC":
                for k in range(2, len(card) - 1, 3):
                    if card[k]:
                        rows += [(int(card[k]), int(c)) for c in card[k + 1]]
            elif name == "SPC1":
                grid_fields = [g for g in card[3:] if g]
                if len(grid_fields) == 3 and grid_fields[1].upper() == "THRU":
                    nodes = range(int(grid_fields[0]), int(grid_fields[2]) + 1)
                else:
                    nodes = [int(g) for g in grid_fields]
                rows += [(n, int(c)) for n in nodes for c in card[2]]
            elif name == "MPC":
                equations.append(mpc_equation(card))
            elif name == "RBE2":
                bodies.append(rbe2_body(card))
        except (ValueError, IndexError):
            raise InputError(f"{path}: a {name} card has a field that is not a number; fix the deck") from None
    for grid, ps in grids.items():
        rows += [(grid, int(c)) for c in (ps or default_ps) if c.isdigit() and c != "0"]
    supported = np.unique(np.array(rows, np.int64).reshape(-1, 2), axis=0)
    used = {int(n) for e in equations for n in e.nodes} | {b.ref for b in bodies}
    missing = sorted(used - set(positions))
    if missing:
        raise InputError(f"{path}: an MPC or RBE2 uses grid {missing[0]}, which has no GRID card in basic "
                         "coordinates (CP 0) in the deck; define it")
    return DeckConstraints(tuple(equations), tuple(bodies), supported, ("SPC",) if len(supported) else (),
                           {n: positions[n] for n in used})


def mpc_equation(card) -> Equation:
    """The Equation of an MPC card: SID, then (G, C, A) triplets, two per 8-field line (QRG, MPC)."""
    terms = []
    for start in range(1, len(card), 8):
        line = card[start:start + 8]
        terms += [line[k:k + 3] for k in (1, 4) if len(line) >= k + 3 and line[k]]
    return Equation(np.array([int(g) for g, _, _ in terms], np.int64), np.array([int(c or 0) for _, c, _ in terms]),
                    np.array([nastran_real(a) for _, _, a in terms]))


def rbe2_body(card) -> RigidBody:
    """The RigidBody of an RBE2 card: EID, GN, CM, GM1, ... (an ALPHA real at the end is ignored)."""
    grids = [int(g) for g in card[4:] if g and "." not in g]
    dofs = tuple(sorted(int(c) for c in card[3] if c in "123"))
    return RigidBody(f"RBE2_{int(card[1])}", np.array(grids, np.int64), int(card[2]), int(card[2]), dofs, 4)
