"""Imported K and M on the model's nodes: DOF map, units, and the checks made before a reduction.

The reduction works on 3 translational DOFs per node, node-interleaved (DOF 3 i + c of node row i,
sidprep.fe.mesh).  The FE code's rows (node number, DOF 1..6) are permuted onto that numbering
through the model's node numbers (``FEMesh.node_ids``, kept in the SID).  What is accepted:

* every translational DOF of every model node has a row (a DOF the FE code removed by an SPC or
  made dependent by an MPC has none: InputError; export the free, unconstrained model);
* rotational DOFs 4-6 (beam and shell nodes) that carry stiffness: each such node gets a *rotation
  node* appended to the model (same position and node number, its 3 DOFs = rx, ry, rz), so that the
  reduction keeps 3 DOFs per node; rotation nodes carry no mass (rotary inertia is refused: the SID
  invariants are built on translations), belong to no node set or surface, and are interior DOFs
  of the Craig-Bampton step (interfaces couple the translations of their patch: RBE2 with
  components 123).  A rotational DOF the FE code wrote without any stiffness (e.g. a shell's
  drilling DOF) is connected to nothing: it gets a decoupled unit stiffness, which changes no other
  DOF.  Models with rotation nodes need at least one interface (the free-frame supports are
  chosen among the translations of interface masters);
* the translational mass is isotropic, M = Ms (x) E3 (any solid element's consistent or lumped
  mass, point masses): the SID invariants are computed from Ms (sid-spec 4.2).

Checks (InputError, before the reduction): symmetry (reader), a positive diagonal of K and
K_ii K_jj >= K_ij^2 for every stored entry (necessary for a positive semi-definite K), a
non-negative mass diagonal, and the rigid-body energy: the six rigid motions of the free model
must give no strain energy (:func:`rigid_energy_ratio` below ``RIGID_ENERGY_TOL``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp

from sidprep.errors import InputError
from sidprep.fe.linalg import rigid_body_modes
from sidprep.fe.matrices import FEMatrices, read_matrices
from sidprep.fe.matrices.numbers import indefinite_entries
from sidprep.fe.plausibility import check_imported_units

#: K_ij^2 > K_ii K_jj (1 + this) for a stored entry: K is indefinite
MINOR_RTOL = 1e-9
#: |M_xx - M_yy|, |M_xy| ... / max |M| above this: the translational mass is not Ms (x) E3
ISOTROPIC_MASS_RTOL = 1e-9
#: strain energy of a rigid motion / the same energy without cancellation (|r|^T |K| |r|) above
#: this: K is not free-free (grounded springs, SPCs folded in) or the file lost digits.  CalculiX
#: writes 13 digits: its free models give 1e-14 - 1e-12
RIGID_ENERGY_TOL = 1e-8


@dataclass(frozen=True)
class ImportedModel:
    """K (3n, 3n) N/m and M (3n, 3n) kg of the model's nodes (DOF 3 i + c), the scalar mass Ms
    (n, n) kg with M = Ms (x) E3, the FE code's eigenvalues (rad/s)^2 or None, the reader's format
    and version, the rigid-body energy ratio of K, and ``mesh``: MODEL with its rotation nodes
    appended (module docstring; the same mesh when there are none)."""

    K: sp.csr_matrix
    M: sp.csr_matrix
    Ms: sp.csr_matrix
    eigenvalues: np.ndarray | None
    fmt: str
    rigid_energy_ratio: float
    mesh: object = None


def imported_model(mesh, path, units, n_interfaces: int = 1) -> ImportedModel:
    """Read ``path`` (any format of sidprep.fe.matrices), map it onto ``mesh`` (an FEMesh in metres
    whose ``node_ids`` are the FE code's node numbers) and convert it to SI with ``units``
    (sidprep.fe.material.UnitSystem); every check of the module docstring, InputError on failure."""
    fe = read_matrices(path)
    K, M, owners = model_dofs(fe, mesh, path)
    if len(owners) and not n_interfaces:
        raise InputError(f"{path}: {len(owners)} nodes have rotational DOFs (beams, shells); such models need "
                         "at least one interface: give --interface NAME")
    check_imported_units(mesh, M, units, path)           # the model's own numbers fit --units (before the run)
    rotating = rotation_mesh(mesh, owners)
    if units.force_to_n != units.length_to_m:
        K = K * (units.force_to_n / units.length_to_m)
    if units.mass_to_kg != 1.0:
        M = M * units.mass_to_kg
    ratio = rigid_energy_ratio(K, rigid_motions(mesh.points, owners))
    K = decoupled_rotations(K, 3 * mesh.n_nodes, path)
    check_stiffness(K, path)
    check_mass(M, path)
    if len(owners) and abs(M[3 * mesh.n_nodes:]).sum() > 0:
        raise InputError(f"{path}: rotational DOFs carry mass (rotary inertia of beams or shells); sidprep's SID "
                         "invariants are built on translations: export the model with lumped translational mass")
    Ms = scalar_mass(M, path)
    if ratio > RIGID_ENERGY_TOL:
        raise InputError(f"{path}: the six rigid-body motions of the model give strain energy (ratio "
                         f"{ratio:.1e} > {RIGID_ENERGY_TOL:g}): K is not that of the free model or does not "
                         "belong to MODEL's coordinates; export it without *BOUNDARY/SPC or springs to ground, "
                         "with the same nodes and --units as MODEL")
    return ImportedModel(K, M, Ms, fe.eigenvalues, fe.fmt, ratio, rotating)


def model_dofs(fe: FEMatrices, mesh, path) -> tuple[sp.csr_matrix, sp.csr_matrix, np.ndarray]:
    """K and M permuted onto the model's DOFs 3 i + c, rotation nodes appended (module docstring),
    and the (p,) mesh rows of the rotation nodes' owners."""
    node, dof = fe.dofs[:, 0], fe.dofs[:, 1]
    ids = np.asarray(mesh.node_ids, dtype=np.int64)
    sorter = np.argsort(ids)
    pos = np.clip(np.searchsorted(ids, node, sorter=sorter), 0, len(ids) - 1)
    row = sorter[pos]
    unknown = ids[row] != node
    if unknown.any():
        raise InputError(f"{path}: {int(len(np.unique(node[unknown])))} node(s) of the matrices are not in MODEL "
                         f"{mesh.source} (first: node {int(node[unknown][0])}); give the deck or mesh the "
                         "matrices were written from")
    rotation = dof > 3
    stiff = np.zeros(len(dof), bool)
    if rotation.any():
        loaded = np.flatnonzero(rotation)
        stiff[loaded] = np.asarray(abs(fe.K)[loaded].sum(axis=1)).ravel() > 0
    owners = np.unique(row[stiff])                       # nodes that get a rotation node
    slot = np.full(mesh.n_nodes, -1)
    slot[owners] = mesh.n_nodes + np.arange(len(owners))
    keep = np.flatnonzero(~rotation | (slot[row] >= 0))
    target = np.where(dof[keep] > 3, 3 * slot[row[keep]] + dof[keep] - 4, 3 * row[keep] + dof[keep] - 1)
    n = 3 * (mesh.n_nodes + len(owners))
    present = np.zeros(n, bool)
    present[target] = True
    if len(np.unique(target)) != len(target):
        raise InputError(f"{path}: a node DOF appears twice in the DOF map; the file is damaged: write it again")
    if not present[:3 * mesh.n_nodes].all():
        missing = np.flatnonzero(~present[:3 * mesh.n_nodes])
        raise InputError(f"{path}: {len(missing)} of the {3 * mesh.n_nodes} translational DOFs of MODEL {mesh.source} "
                         f"have no row (first: node {int(ids[missing[0] // 3])} DOF {missing[0] % 3 + 1}): removed by "
                         "an SPC/*BOUNDARY or an MPC, or the matrices come from another model; export the free, "
                         "unconstrained model (sidprep adds its own interfaces)")
    if len(keep) == fe.K.shape[0] and np.array_equal(target, np.arange(n)):
        return fe.K, fe.M, owners                         # the FE code numbered the DOFs as MODEL does
    P = sp.csr_matrix((np.ones(len(keep)), (target, keep)), shape=(n, fe.K.shape[0]))
    return (P @ fe.K @ P.T).tocsr(), (P @ fe.M @ P.T).tocsr(), owners


def decoupled_rotations(K: sp.csr_matrix, first: int, path) -> sp.csr_matrix:
    """K with a unit diagonal on the rotational DOFs (from ``first`` on) that have no stiffness at all
    (connected to nothing: the other DOFs do not change)."""
    free = np.flatnonzero(K.diagonal()[first:] == 0) + first
    if not len(free):
        return K
    if abs(K[free]).sum() > 0:
        raise InputError(f"{path}: a rotational DOF has no diagonal stiffness but couples to others; "
                         "K is damaged: write it again")
    return (K + sp.csr_matrix((np.ones(len(free)), (free, free)), shape=K.shape)).tocsr()


def rotation_mesh(mesh, owners: np.ndarray):
    """MODEL with a rotation node appended per owner (same position and node number; in no set,
    on no surface or element)."""
    if not len(owners):
        return mesh
    return replace(mesh, points=np.vstack([mesh.points, mesh.points[owners]]),
                   node_ids=np.concatenate([mesh.node_ids, mesh.node_ids[owners]]))


def rigid_motions(points: np.ndarray, owners: np.ndarray) -> np.ndarray:
    """(3 (n + p), 6) rigid motions about the centroid: translations t + theta x x at the n nodes,
    the rotation theta at the p rotation nodes."""
    R = rigid_body_modes(points)
    if not len(owners):
        return R
    Rr = np.zeros((len(owners), 3, 6))
    Rr[:, :, 3:] = np.eye(3)
    return np.vstack([R, Rr.reshape(-1, 6)])


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


def scalar_mass(M: sp.csr_matrix, path) -> sp.csr_matrix:
    """Ms (n, n) with M = Ms (x) E3, checked to ISOTROPIC_MASS_RTOL (module docstring)."""
    Ms = M[0::3, 0::3].tocsr()
    scale = float(np.abs(M.data).max())
    worst = 0.0
    for a in range(3):
        for b in range(3):
            block = M[a::3, b::3] - Ms if a == b else M[a::3, b::3]
            worst = max(worst, float(abs(block).max()) / scale)
    if worst > ISOTROPIC_MASS_RTOL:
        raise InputError(f"{path}: the translational mass is not the same in x, y and z (relative difference "
                         f"{worst:.1e}): rotary inertia or offsets couple the directions; sidprep reduces "
                         "solid models (consistent or lumped solid mass, point masses)")
    return Ms


def rigid_energy_ratio(K: sp.spmatrix, R: np.ndarray) -> float:
    """max over the rigid motions r (columns of R, :func:`rigid_motions`) of |r^T K r| / (|r|^T |K| |r|):
    zero for the K of a free model up to the digits of the file, O(1) for a grounded or foreign K."""
    absK = abs(K)
    energy = np.abs(np.einsum("ik,ik->k", R, K @ R))
    scale = np.einsum("ik,ik->k", np.abs(R), absK @ np.abs(R))
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
