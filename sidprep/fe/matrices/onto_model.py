"""Imported K and M on the model's nodes: DOF map, units, and the checks made before a reduction.

The reduction works on 3 translational DOFs per node, node-interleaved (DOF 3 i + c of node row i,
sidprep.fe.mesh).  The FE code's rows (node number, DOF 1..6) are permuted onto that numbering
through the model's node numbers (``FEMesh.node_ids``, kept in the SID).  What is accepted:

* every translational DOF of every model node has a row, or the deck MODEL was read from makes it
  dependent (equations, rigid bodies: recovered through u = S u, sidprep.fe.matrices.constraints,
  composed with the interface model as the mesh's ``ties``) or supports it (a clamped export: the
  supported nodes are returned as ``clamped``, and the reduction attaches the frame there);
  reference and rotation nodes of rigid bodies are appended to the model (a rotation node's 3 DOFs
  are the rotation);
* rotational DOFs 4-6 (beam and shell nodes) that carry stiffness: each such node gets a *rotation
  node* appended to the model (same position and node number, its 3 DOFs = rx, ry, rz), so that the
  reduction keeps 3 DOFs per node; their rotary inertia is carried by auxiliary point masses that
  follow the node rigidly (sidprep.fe.matrices.rotary); they belong to no node set or surface, and are interior DOFs
  of the Craig-Bampton step (interfaces couple the translations of their patch: RBE2 with
  components 123).  A rotational DOF the FE code wrote without any stiffness (e.g. a shell's
  drilling DOF) is connected to nothing: it gets a decoupled unit stiffness, which changes no other
  DOF.  Models with rotation nodes need at least one interface (the free-frame supports are
  chosen among the translations of interface masters); beams between them are drawn as tubes
  whose vertices follow the nodes (sidprep.fe.matrices.tubes);
* the mass is that of solid nodes, S^T (Ms (x) E3) S = M (any solid element's consistent or lumped
  mass, point masses; a rigid body's mass folded onto its reference and rotation nodes is unfolded
  onto its nodes): the SID invariants are computed from Ms (sid-spec 4.2).

Checks (InputError, before the reduction): symmetry (reader), a positive diagonal of K and
K_ii K_jj >= K_ij^2 for every stored entry (necessary for a positive semi-definite K), a
non-negative mass diagonal, and the rigid-body energy: the six rigid motions of the free model
must give no strain energy (:func:`rigid_energy_ratio` below ``RIGID_ENERGY_TOL``; for a clamped
export on the rows away from the clamp).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from sidprep.errors import InputError
from sidprep.fe.linalg import rigid_body_modes
from sidprep.fe.matrices import read_matrices
from sidprep.fe.matrices.constraints import solid_mass
from sidprep.fe.matrices.deck import deck_lines
from sidprep.fe.matrices.deck_constraints import DeckConstraints, deck_constraints
from sidprep.fe.matrices.model_dofs import (away_from, clamp_of, clamped_nodes, embedded, full_model, glued_surface,
    model_constraints)
from sidprep.fe.matrices.numbers import indefinite_entries
from sidprep.fe.plausibility import check_imported_units
from sidprep.fe.matrices.rotary import inertia_nodes
from sidprep.fe.matrices.tubes import beam_tubes

#: K_ij^2 > K_ii K_jj (1 + this) for a stored entry: K is indefinite
MINOR_RTOL = 1e-9
#: strain energy of a rigid motion / the same energy without cancellation (|r|^T |K| |r|) above
#: this: K is not free-free (grounded springs, SPCs folded in) or the file lost digits.  CalculiX
#: writes 13 digits: its free models give 1e-14 - 1e-12
RIGID_ENERGY_TOL = 1e-8


@dataclass(frozen=True)
class ImportedModel:
    """K (3n, 3n) N/m and M (3n, 3n) kg of the model's nodes (DOF 3 i + c), the scalar mass Ms
    (n, n) kg with S^T (Ms (x) E3) S = M, the FE code's eigenvalues (rad/s)^2 or None, the reader's
    format and version, the rigid-body energy ratio of K, and ``mesh``: MODEL with its rotation
    nodes and the constraints' extra nodes appended and the constraints as its ``ties`` (module
    docstring; the same mesh when there are none).  ``clamped``: node rows whose DOFs the export
    removed (supports), an interface ``clamp_name`` of ``clamp_kind`` "rbe2" (solid nodes) or "node"
    (a rigid body's reference and rotation nodes) carries the frame there; ``rigid_bodies``: {node-set name: (reference row, rotation row)},
    ``notes``: what was recovered, one line each; ``rotation_of``: (n,) the rotation-node row of each
    6-DOF node's translation row, -1 on the other nodes, -2 on rotation and auxiliary rows; ``unconnected``: the rotational DOFs written without
    any stiffness (given a decoupled unit stiffness)."""

    K: sp.csr_matrix
    M: sp.csr_matrix
    Ms: sp.csr_matrix
    eigenvalues: np.ndarray | None
    fmt: str
    rigid_energy_ratio: float
    mesh: object = None
    clamped: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    clamp_name: str = ""
    clamp_kind: str = ""
    rigid_bodies: dict = field(default_factory=dict)
    notes: tuple[str, ...] = ()
    rotation_of: np.ndarray | None = None
    unconnected: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))


def imported_model(mesh, path, units, n_interfaces: int = 1) -> ImportedModel:
    """Read ``path`` (any format of sidprep.fe.matrices), map it onto ``mesh`` (an FEMesh in metres
    whose ``node_ids`` are the FE code's node numbers), complete it with the constraints of the deck
    MODEL was read from (sidprep.fe.matrices.deck_constraints) and convert it to SI with ``units``
    (sidprep.fe.material.UnitSystem); every check of the module docstring, InputError on failure."""
    fe = read_matrices(path)
    deck = deck_constraints(mesh.source) if mesh.source and Path(mesh.source).is_file() else DeckConstraints()
    full = full_model(fe, mesh, deck, units, path)
    if full.rotational.any() and not n_interfaces:
        raise InputError(f"{path}: {int(full.rotational.sum())} nodes carry rotational DOFs (beams, shells, rigid "
                         "bodies); such models need at least one interface: give --interface NAME (a node set, or "
                         "GRID<number> for one beam or shell node)")
    K, M, present = embedded(fe, full, path)
    check_imported_units(mesh, M, units, path)           # the model's own numbers fit --units (before the run)
    K, M = in_si(K, M, full.rotational, units)
    own_rotations = [int(full.dof(rb.rot, rb.rot_dof)) // 3 for rb in deck.rigid_bodies]
    full, K, M, inertia = inertia_nodes(full, K, M, own_rotations, path)
    lines = deck_lines(mesh.source) if mesh.source and Path(mesh.source).is_file() else np.zeros((0, 2), np.int64)
    full, K, M, followers, tubes = beam_tubes(full, K, M, lines)
    dependent, bodies, constraints = model_constraints(full, deck, mesh.source, units.length_to_m, inertia, followers)
    clamped, clamp_name, clamp_kind = clamp_of(clamped_nodes(full, deck, present, dependent, path), full, deck,
                                               bodies, mesh.source)
    held = np.concatenate([clamped] + [rows for ref, _, rows in bodies if ref in clamped])
    rows = away_from(held, full, present, mesh.source) if len(clamped) else None
    ratio = rigid_energy_ratio(K[present][:, present], rigid_motions(full.mesh.points, full.rotational)[present], rows)
    unconnected = np.zeros(0, np.int64) if not full.rotational.any() else np.setdiff1d(
        np.flatnonzero((K.diagonal() == 0) & np.repeat(full.rotational, 3)), dependent)
    K, present = decoupled_rotations(K, full.rotational, present, dependent, path)
    check_stiffness(K[present][:, present], path)
    check_mass(M[present][:, present], path)
    if ratio > RIGID_ENERGY_TOL:
        raise InputError(f"{path}: the six rigid-body motions of the model give strain energy (ratio "
                         f"{ratio:.1e} > {RIGID_ENERGY_TOL:g}): K is not that of the free model or does not "
                         "belong to MODEL's coordinates; export it without SPCs or springs to ground (a clamped "
                         "export needs its supports in MODEL: *BOUNDARY / SPC), with the same nodes and --units "
                         "as MODEL")
    Ms = solid_mass(M, constraints, full.mesh.points, bodies, path)
    surface = glued_surface(full.mesh, deck, constraints)
    mesh_out = replace(full.mesh, ties=constraints, surface=surface if surface is None else np.vstack([surface, tubes]),
                       rotational=full.rotational if full.rotational.any() else None)
    names = {rb.name: (int(full.row_of(rb.ref)), int(full.dof(rb.rot, rb.rot_dof)) // 3) for rb in deck.rigid_bodies}
    notes = constraint_notes(deck, clamped, clamp_name, path)
    return ImportedModel(K, sp.kron(Ms, sp.identity(3), format="csr"), Ms, fe.eigenvalues, fe.fmt, ratio, mesh_out,
                         clamped, clamp_name, clamp_kind, names, notes, rotation_nodes(full), unconnected)


def rotation_nodes(full) -> np.ndarray:
    """(n,) row of the rotation node of each node row that has one (a 6-DOF node's translations),
    -1 on the other nodes of the model, -2 on the rows that are no node of their own (rotation,
    auxiliary inertia and tube nodes at the places of nodes)."""
    rows = np.flatnonzero(~full.rotational & (full.keys[0::3] >= 0))
    r = full.dof(full.mesh.node_ids[rows], 4)
    out = np.full(full.mesh.n_nodes, -2, np.int64)
    out[rows] = np.where(r >= 0, r // 3, -1)
    return out


def in_si(K: sp.csr_matrix, M: sp.csr_matrix, rotational: np.ndarray, units) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """K (N/m, N/rad, N m/rad) and M (kg, kg m, kg m^2) from the file's units: with u_file = D u_SI
    (D = 1 / L on translations, 1 on rotations) and the energies' units, K_SI = F L D K D
    = (F / L) E K E and M_SI = m L^2 D M D = m E M E, E = L D (F, L, m: force_to_n, length_to_m,
    mass_to_kg)."""
    L, F, m = units.length_to_m, units.force_to_n, units.mass_to_kg
    if rotational.any() and L != 1.0:
        E = sp.diags(np.where(np.repeat(rotational, 3), L, 1.0))
        K, M = (E @ K @ E).tocsr(), (E @ M @ E).tocsr()
    if F != L:
        K = K * (F / L)
    if m != 1.0:
        M = M * m
    return K, M


def decoupled_rotations(K: sp.csr_matrix, rotational: np.ndarray, present: np.ndarray, dependent: np.ndarray,
                        path) -> tuple[sp.csr_matrix, np.ndarray]:
    """K with a unit diagonal on the rotational DOFs that have no stiffness at all (connected to
    nothing: the other DOFs do not change; written or not), and ``present`` with them."""
    d = K.diagonal()
    free = np.setdiff1d(np.flatnonzero((d == 0) & np.repeat(rotational, 3)), dependent)
    if not len(free):
        return K, present
    if abs(K[free]).sum() > 0:
        raise InputError(f"{path}: a rotational DOF has no diagonal stiffness but couples to others; "
                         "K is damaged: write it again")
    return (K + sp.csr_matrix((np.ones(len(free)), (free, free)), shape=K.shape)).tocsr(), np.union1d(present, free)


def rigid_motions(points: np.ndarray, rotational: np.ndarray) -> np.ndarray:
    """(3n, 6) rigid motions about the centroid: t + theta x x at the translational nodes, the
    rotation theta at the rotational ones."""
    R = rigid_body_modes(points).reshape(-1, 3, 6)
    R[rotational] = 0.0
    R[rotational, :, 3:] = np.eye(3)
    return R.reshape(-1, 6)


def constraint_notes(deck, clamped, clamp_name: str, path) -> tuple[str, ...]:
    """One line per kind of recovered DOFs (for the SID metadata and the summary)."""
    notes = []
    if deck.equations:
        notes.append(f"{path}: {len(deck.equations)} constraint equations of the deck: their dependent DOFs are "
                     "recovered from the equations (mode shapes, OBJ, stresses)")
    for rb in deck.rigid_bodies:
        notes.append(f"{path}: rigid body {rb.name} ({len(rb.nodes)} nodes) on reference node {rb.ref} and rotation "
                     f"node {rb.rot}: its nodes follow them; --interface {rb.name} makes the reference node a SID node")
    if len(clamped):
        notes.append(f"{path}: the export is clamped at {len(clamped)} nodes (*BOUNDARY / SPC): the body frame is "
                     f"attached there (frame = {clamp_name}; fixed-interface modes); the FE code wrote no mass for "
                     "these nodes, so the SID's mass lacks their share")
    return tuple(notes)


def check_stiffness(K: sp.csr_matrix, path) -> None:
    """InputError unless K's diagonal is positive and K_ij^2 <= K_ii K_jj on every stored entry."""
    d = K.diagonal()
    if not (d > 0).all():
        i = int(np.flatnonzero(~(d > 0))[0])
        raise InputError(f"{path}: the stiffness matrix has a non-positive diagonal entry (DOF {i // 3 + 1}.{i % 3 + 1} "
                         f"of MODEL's node order: {d[i]:.3g}); K is indefinite or the file is damaged: write it again")
    bad = indefinite_entries(K.indptr, K.indices, K.data, d, MINOR_RTOL)
    if bad:
        raise InputError(f"{path}: the stiffness matrix is indefinite ({bad} entries with "
                         "K_ij^2 > K_ii K_jj); export the stiffness of a stable linear elastic model")


def check_mass(M: sp.csr_matrix, path) -> None:
    """InputError when a diagonal entry of M is negative or all of them are zero."""
    d = M.diagonal()
    if (d < 0).any() or not (d > 0).any():
        i = int(np.argmin(d))
        raise InputError(f"{path}: the mass matrix has a {'negative' if d[i] < 0 else 'zero'} diagonal "
                         f"({d[i]:.3g} at DOF {i}); export a physical mass matrix (density set on every element)")


def rigid_energy_ratio(K: sp.spmatrix, R: np.ndarray, rows: np.ndarray | None = None) -> float:
    """max over the rigid motions r (columns of R, :func:`rigid_motions`) of |r^T K r| / (|r|^T |K| |r|):
    zero for the K of a free model up to the digits of the file, O(1) for a grounded or foreign K.
    ``rows`` (bool): the sums over these rows only; a clamped export's K r holds the clamp's reactions
    on the rows of the nodes next to the clamp and nothing elsewhere."""
    absK = abs(K)
    keep = np.ones(K.shape[0], bool) if rows is None else rows
    energy = np.abs(np.einsum("ik,ik->k", R[keep], (K @ R)[keep]))
    scale = np.einsum("ik,ik->k", np.abs(R[keep]), (absK @ np.abs(R))[keep])
    return float(np.max(energy / scale))


def imported_checks(model: ImportedModel, basis) -> dict:
    """The import's own checks for the check table, JSON-ready: the format read, K's rigid-body energy
    ratio (tolerance ``RIGID_ENERGY_TOL``) and, when the file carries the FE code's eigenvalues, the
    largest relative difference of the basis' elastic eigen-kind frequencies from the FE code's."""
    out = {"matrices_format": model.fmt, "rigid_energy_ratio": model.rigid_energy_ratio,
           "rigid_energy_tol": RIGID_ENERGY_TOL}
    if model.eigenvalues is not None:
        fe_hz = np.sqrt(np.clip(np.sort(model.eigenvalues), 0, None)) / (2 * np.pi)
        ours = basis.frequencies_hz[np.array(basis.kinds) == "eigen"]
        elastic = fe_hz[fe_hz > 1e-3 * fe_hz.max()][:len(ours)]
        out["fe_code_frequencies_hz"] = elastic.tolist()
        out["fe_code_frequency_max_rel_error"] = float(np.max(np.abs(ours[:len(elastic)] / elastic - 1)))
    return out
