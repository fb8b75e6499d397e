"""One FE model reduced in parts: component mode synthesis by two Craig-Bampton levels.

The cells are split into N connected parts (METIS on the cells' face graph).  In model DOFs
(after the RBE2/RBE3 interfaces, sidprep.reduction.interfaces) part p owns the DOFs its cells
touch; the *coarse* DOFs G are those owned by two or more parts plus the boundary b of the
monolithic reduction (the interface masters).  With I_p the other DOFs of part p, the model is

    K = sum_p T_p^T K_p T_p,     K_p = [[K_II, K_IB], [K_BI, K_BB]]  (B_p = part p's DOFs in G)

1. each part's exact static Schur complement S_p = K_BB - K_BI K_II^-1 K_IB on B_p (a task: one sparse
   partial LDL^T, sidprep.fe.pardiso); their sum S on G is the whole model's exact Schur complement
   (summed as the parts' blocks arrive, as dense blocks between the cuts: ``CutBlocks``);
2. the coarse space (``coarse_space``): b kept; every cut (the coarse DOFs shared by one set of parts)
   reduced to its lowest interface modes, eigenvectors of S and M on the cut (characteristic
   constraint modes; Castanier, Tan & Pierre 2001): u_G = R c;
3. each part: Craig-Bampton on its coarse coordinates c_p (a task), u_I = Psi_p R_p c_p + Phi_p q_p,
   Psi_p = -K_II^-1 K_IB: one constraint mode per coordinate (not per coarse DOF), Phi_p its
   fixed-interface modes up to a cut-off (``PART_CUTOFF``);
4. the reduced parts assembled on [c, q_1 .. q_N] (``assemble_parts``) and a second Craig-Bampton of
   that assembly on b: its fixed-interface modes approximate the monolithic ones as the parts'
   cut-off and the interface modes rise;
5. every model DOF recovered from the parts (``SubstructuredSolver.solve_and_recover``), which gives
   the same ReducedModel as ``craig_bampton`` (basis, K, M, boundary b) with an exact K_ii^-1 by
   substructuring (part tasks around the block LDL^T of the exact S in the driver, ``CutFactor``;
   each part's K_II factor is made once and kept where the part is held, ``HeldPart``) - the
   static columns are the whole model's EXACT constraint modes -K_ii^-1 K_ib from it - and a
   certified eigenvalue count (Wittrick-Williams over the parts, each part's inertia and dynamic
   Schur complement from one sparse LDL^T, the coarse sum's inertia from another), so the checks
   of sidprep.reduction.fe_checks hold against the full model unchanged;
6. the fixed-interface modes X refined by one block inverse iteration with that exact K_ii^-1:
   Rayleigh-Ritz of K_ii, M_ii on span[X, K_ii^-1 M_ii X] (``refined_modes``; a subspace-iteration
   step divides each mode's error by about the square of (its frequency / the parts' cut-off)).

Craig & Bampton 1968; Hurty 1965 (component modes); Wittrick & Williams 1971 (eigenvalue count);
Bathe & Wilson 1972 (subspace iteration); Castanier, Tan & Pierre 2001 (characteristic constraint modes).
"""

from __future__ import annotations

import os
import shutil
import tempfile
from dataclasses import dataclass, replace

import numpy as np
import pymetis
import scipy.linalg as sla
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from sidprep.errors import InputError
from sidprep.fe.assemble import scalar_mass_matrix, stiffness_matrix, vector_mass
from sidprep.fe.linalg import all_cores_blas, available_memory_bytes, estimate_peak_memory, factorize, single_threaded_blas
from sidprep.fe.mesh import FEMesh
from sidprep.fe.topology import face_table
from sidprep.fe.pardiso import Inertia, ldlt_inertia
from sidprep.progress import peak_memory_mb
from sidprep.reduction.craig_bampton import (ReducedModel, block_gram, blockwise, craig_bampton, interior_operator,
    project, reduction_peak_bytes)


#: the parts' fixed-interface modes reach this multiple of the highest fixed-interface frequency of
#: the second level (the component cut-off ratio that governs CMS accuracy): 1e-4 agreement with the
#: monolithic reduction on the piston rod (4 parts) and a bar (8 parts), tests/test_parts.py
PART_CUTOFF = 2.0
#: relative eigenvalue of the Gram matrix below which a direction of [X, K^-1 M X] is dropped
RANK_TOL = 1e-12
#: rows of the Ritz vectors combined at a time (``ritz_vectors``; its temporaries scale with them)
REFINE_ROWS = 65536
#: METIS load imbalance allowed between parts (1.03 = 3 %, its default for k-way partitions)
PART_IMBALANCE = 1.03
#: the coarse blocks and their factor stay in memory up to this fraction of the memory available as
#: their round starts; larger ones go to memory-mapped files (``disk_zeros``): the
#: driver's basis and solve vectors come later (at 2.4M DOF in 16 parts, ~4.4 GB of blocks stayed in
#: memory at 0.25, beside the model's ~5 GB and 0.58 GB per 30 columns of model-size vectors)
COARSE_IN_MEMORY_FRACTION = 0.1
#: dense (nb_p, nb_p) arrays alive at the peak of a part's Schur task (``part_dynamic_schur``): PARDISO's
#: Schur block, the x it is returned in, and its workspace - measured 2.6 (peak RSS over the same
#: LDL^T without the Schur rows: +423 MiB for nb_p = 4581 on a 94k-DOF part of the 2.4M bar in 24)
SCHUR_DENSE_COPIES = 3
#: (n_p, n_coordinates) arrays alive at the peak of a part's reduction beyond ``reduction_peak_bytes``
#: (the basis's constraint modes, the coupling of K and M to the coordinates): measured 1.6 between two
#: parts of the 475k bar in 8 (186 and 360 coordinates, ~60k DOF each: 708 and 839 MiB peak RSS)
COORDINATE_COPIES = 2


# ---------------------------------------------------------------------------------------------
# partition
# ---------------------------------------------------------------------------------------------

def face_graph(cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The cells' adjacency through shared faces in CSR form (xadj (ne + 1,), adjncy)."""

    group, counts, _ = face_table(np.asarray(cells)[:, :4])
    order = np.argsort(group, kind="stable")
    g = group[order]
    pair = np.flatnonzero((g[1:] == g[:-1]) & (counts[g[1:]] == 2))
    a, b = order[pair] // 4, order[pair + 1] // 4
    ne = len(cells)
    A = sp.csr_matrix((np.ones(2 * len(a)), (np.r_[a, b], np.r_[b, a])), shape=(ne, ne))
    return A.indptr.astype(np.int64), A.indices.astype(np.int64)


def partition_cells(cells: np.ndarray, n_parts: int) -> np.ndarray:
    """(ne,) part of every cell: N connected parts of balanced cell count whose shared faces are few
    (METIS k-way on the face graph, contiguous parts; Karypis & Kumar 1998)."""

    ne = len(cells)
    if not 2 <= n_parts <= ne // 2:
        raise InputError(f"parts = {n_parts}: must be between 2 and half the cell count ({ne // 2})")
    xadj, adjncy = face_graph(cells)
    graph = sp.csr_matrix((np.ones(len(adjncy)), adjncy, xadj), shape=(ne, ne))
    if connected_components(graph, directed=False)[0] > 1:
        raise InputError("parts: the mesh is not one connected body through shared faces; reduce it in one "
                         "piece (without parts) or join its pieces")
    options = pymetis.Options(seed=1, contig=1, ufactor=int(round(1000 * (PART_IMBALANCE - 1))))
    _, labels = pymetis.part_graph(n_parts, pymetis.CSRAdjacency(xadj, adjncy), options=options)
    labels = np.asarray(labels, dtype=np.int64)
    if len(np.unique(labels)) != n_parts:
        raise InputError(f"parts = {n_parts}: the mesh has too few cells for {n_parts} connected parts; use fewer parts")
    return labels


# ---------------------------------------------------------------------------------------------
# the parts in model DOFs
# ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class PartFE:
    """A part's FE model as the worker that holds it assembles it (``assembled``): points (np_l, 3) m,
    its nodes; cells (ne_p, nn) into them; material, a Material or GivenMatrices on its nodes' DOFs;
    T (3 np_l, n_p) csr, its nodes' displacements from its model DOFs (rows of the interface
    transformation, sidprep.reduction.interfaces)."""

    points: np.ndarray
    cells: np.ndarray
    material: object
    T: sp.csr_matrix


@dataclass(frozen=True)
class PartModel:
    """One part in model DOFs: what a task needs.

    name : "part k/N"; dofs : (n_p,) its model DOFs (ascending); boundary : (nb_p,) local indices of
    its coarse DOFs (ascending); extent : (3,) bounding-box edges (m) for the memory estimate;
    fe : its FE model (PartFE); K, M : (n_p, n_p) csr, N/m and kg, from its cells only - None in the
    driver, which describes the part; its worker assembles them (``assembled``).
    """

    name: str
    dofs: np.ndarray
    boundary: np.ndarray
    extent: np.ndarray
    fe: PartFE | None = None
    K: sp.csr_matrix | None = None
    M: sp.csr_matrix | None = None

    @property
    def interior(self) -> np.ndarray:
        """(ni_p,) local indices of the part's own DOFs."""
        return np.setdiff1d(np.arange(len(self.dofs)), self.boundary)


def part_dofs(im, cells: np.ndarray) -> np.ndarray:
    """Model DOFs touched by ``cells`` (through the interface transformation T), ascending."""
    nodes = np.unique(cells)
    rows = (3 * nodes[:, None] + np.arange(3)).ravel()
    return np.unique(im.T[rows].indices)


def coarse_dofs(owned: list[np.ndarray], boundary) -> np.ndarray:
    """G: the model DOFs owned by two or more parts, and the monolithic boundary; ascending."""
    count = np.bincount(np.concatenate(owned))
    return np.union1d(np.flatnonzero(count > 1), np.asarray(boundary, dtype=np.int64))


@dataclass(frozen=True)
class GivenMatrices:
    """A part's FE stiffness and mass as given (imported from another FE code, sidprep.fe.matrices)
    on the whole mesh's DOFs: K (3n, 3n) N/m and M (3n, 3n) kg, csr."""

    K: sp.csr_matrix
    M: sp.csr_matrix


def part_fe_matrices(mesh, cells: np.ndarray, material) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """K, M (3n, 3n) of the part of ``cells``: assembled with ``material``, or GivenMatrices."""
    if isinstance(material, GivenMatrices):
        return material.K, material.M
    sub = replace(mesh, cells=cells)
    return stiffness_matrix(sub, material), vector_mass(scalar_mass_matrix(sub, material.rho))


def part_fe(mesh, cells: np.ndarray, material, T: sp.csr_matrix) -> PartFE:
    """The PartFE of ``cells`` (global node indices) with the model DOFs' columns T (3n, n_p) of the
    interface transformation: its nodes renumbered, T's and given matrices' rows cut to them."""
    nodes, local = np.unique(cells, return_inverse=True)
    rows = (3 * nodes[:, None] + np.arange(3)).ravel()
    if isinstance(material, GivenMatrices):
        material = GivenMatrices(material.K[rows][:, rows].tocsr(), material.M[rows][:, rows].tocsr())
    return PartFE(mesh.points[nodes], local.reshape(cells.shape), material, T[rows].tocsr())


def assembled(part: PartModel) -> PartModel:
    """The part with its K = T^T K_fe T and M = T^T M_fe T (K_fe, M_fe from its cells: ``part_fe_matrices``)."""
    if part.K is not None:
        return part
    fe = part.fe
    mesh = FEMesh(fe.points, fe.cells, np.arange(len(fe.points)))
    K_fe, M_fe = part_fe_matrices(mesh, fe.cells, fe.material)
    return replace(part, K=(fe.T.T @ (K_fe @ fe.T)).tocsr(), M=(fe.T.T @ (M_fe @ fe.T)).tocsr())


def part_models(mesh, material, labels: np.ndarray, im, boundary, names=None) -> tuple[list[PartModel], np.ndarray]:
    """Each part described (its DOFs, coarse DOFs and FE model; its matrices T^T K_p T are assembled
    where it is held, ``assembled``) and the coarse DOFs G; ``boundary`` the monolithic reduction's
    boundary DOFs (model indices).  ``material`` : one Material, or one per part (an assembly's
    components: a Material or GivenMatrices); ``names`` : one per part (default "part k/N")."""

    n = int(labels.max()) + 1
    materials = list(material) if isinstance(material, (list, tuple)) else [material] * n
    names = names or [f"part {p + 1}/{n}" for p in range(n)]
    cells = [mesh.cells[labels == p] for p in range(n)]
    owned = [part_dofs(im, c) for c in cells]
    G = coarse_dofs(owned, boundary)
    parts = []
    for c, dofs, mat, name in zip(cells, owned, materials, names):
        fe = part_fe(mesh, c, mat, im.T[:, dofs])
        parts.append(PartModel(name, dofs, np.flatnonzero(np.isin(dofs, G)), np.ptp(fe.points, axis=0), fe))
    return parts, G


class HeldPart:
    """A part as the worker that holds it for a whole run sees it: its description (a PartModel), its
    matrices (assembled here on first use, ``part``) and the factor of its K_II (its own DOFs), made on
    first use - or kept from its Craig-Bampton reduction, which factors the same K_II - and reused by
    every later substructured solve (only right-hand sides travel).  ``release`` drops the matrices
    and the factor, not the description: they are made again when next needed, without the part
    sent again.  ``factorisations`` counts the factors made."""

    def __init__(self, part: PartModel):
        self.description = part
        self._part = None
        self._factor = None
        self.factorisations = 0

    @property
    def part(self) -> PartModel:
        """The part with its K and M (``assembled`` here on first use, and after ``release``)."""
        if self._part is None:
            self._part = assembled(self.description)
        return self._part

    def factor(self):
        """The factor of K_II (made here on first use)."""
        if self._factor is None:
            self.keep(interior_factor(self.part))
        return self._factor

    def keep(self, factor) -> None:
        """Hold ``factor``, a factor of this part's K_II just made."""
        self._factor = factor
        self.factorisations += 1

    def release(self) -> None:
        """Drop the matrices and the factor (not the description)."""
        self._part = self._factor = None

    @property
    def holds(self) -> bool:
        """Whether the part's matrices (and with them, once made, its factor) are held."""
        return self._part is not None


def part_factorisations(held: HeldPart) -> int:
    """The factors of K_II made for the part where it is held (a part task)."""
    return held.factorisations


def part_peak_bytes(part: PartModel, n_coordinates: int = 0) -> float:
    """Estimated peak bytes of the largest task of ``part`` (a PartModel): its Craig-Bampton reduction
    on ``n_coordinates`` coarse coordinates (``coordinates_per_part``; 0: not known yet) or its Schur
    task, a sparse LDL^T of the part with SCHUR_DENSE_COPIES dense (nb_p, nb_p) blocks on its coarse
    DOFs, whichever is larger."""
    return task_peak_bytes(len(part.dofs), len(part.boundary), part.extent, n_coordinates)


def task_peak_bytes(n_dof: int, n_coarse: int, extent=None, n_coordinates: int = 0) -> float:
    """``part_peak_bytes`` of a part of n_dof DOF, n_coarse of them coarse, bounding box ``extent``: the
    reduction (sidprep.reduction.craig_bampton.reduction_peak_bytes) with COORDINATE_COPIES (n_dof,
    n_coordinates) arrays, or the Schur task."""
    schur = estimate_peak_memory(n_dof, None, extent).direct_peak_bytes + SCHUR_DENSE_COPIES * 8.0 * n_coarse ** 2
    reduction = reduction_peak_bytes(n_dof, None, extent) + COORDINATE_COPIES * 8.0 * n_dof * n_coordinates
    return max(reduction, schur)


def coordinates_per_part(parts, coarse: np.ndarray, boundary, n_interface: int) -> np.ndarray:
    """(N,) the coarse coordinates each part's reduction will have (``with_coarse_coordinates``), known
    before any task: the DOFs of b it holds and, per cut it touches, min(n_interface, the cut's DOFs)
    interface modes (``coarse_space``)."""
    b, _ = boundary_positions(coarse, boundary)
    local = part_positions(parts, coarse)
    groups = cut_groups(local, len(coarse), b)
    group_of = np.full(len(coarse), -1)
    for k, g in enumerate(groups):
        group_of[g] = k
    modes = np.array([min(n_interface, len(g)) for g in groups] + [0], dtype=np.int64)   # [-1]: b, counted apart
    return np.array([np.sum(group_of[pos] < 0) + modes[np.unique(group_of[pos])].sum() for pos in local],
                    dtype=np.int64)


class InProcess:
    """Part tasks here (without an executor): fn, [args per part] -> [fn(HeldPart of part p, *args[p])],
    each part's HeldPart kept across calls (its K_II factored once); with ``consume``,
    consume(p, result) instead, and None.  The executor's counterpart: sidprep.jobs.parts.PartTasks."""

    def __init__(self, parts):
        self.held = [HeldPart(part) for part in parts]

    def __call__(self, fn, args, consume=None, meanwhile=None) -> list | None:
        """``args``: a list (every part) or {part index: args} (those parts; results in its order);
        ``meanwhile()`` first (the executor runs it while the tasks run)."""
        args = args if isinstance(args, dict) else dict(enumerate(args))
        if meanwhile is not None:
            meanwhile()
        if consume is None:
            return [fn(self.held[p], *a) for p, a in args.items()]
        for p, a in args.items():
            consume(p, fn(self.held[p], *a))
        return None


# ---------------------------------------------------------------------------------------------
# the coarse space: exact static Schur complements, interface modes of the cuts
# ---------------------------------------------------------------------------------------------

class BlockSum:
    """sum_p P_p^T B_p P_p (n, n) csr (``S``), the dense blocks B_p (len(pos), len(pos)) added at
    ``positions`` (-1: that row and column dropped) as they arrive (``add``), row by row into the
    sparsity pattern of the sum (``sum_pattern``): the peak is the sum and the blocks in flight, not
    every block at once nor their triplets (24 bytes an entry)."""

    def __init__(self, positions, n: int):
        self.kept = [np.flatnonzero(np.asarray(pos) >= 0) for pos in positions]
        self.cols = [np.asarray(pos)[k] for pos, k in zip(positions, self.kept)]
        self.S = sum_pattern(self.cols, n)

    def add(self, p: int, B: np.ndarray) -> None:
        S, k, cols = self.S, self.kept[p], self.cols[p]
        for i, r in zip(k, cols):
            start, stop = S.indptr[r], S.indptr[r + 1]
            S.data[start + np.searchsorted(S.indices[start:stop], cols)] += B[i, k]


def summed_blocks(positions, blocks, n: int) -> sp.csr_matrix:
    """sum_p P_p^T B_p P_p (n, n) csr of the dense blocks B_p at ``positions`` (``BlockSum``)."""
    total = BlockSum(positions, n)
    for p, B in enumerate(blocks):
        total.add(p, B)
    return total.S


def sum_pattern(positions, n: int) -> sp.csr_matrix:
    """The zero (n, n) csr matrix (sorted indices) with the pattern of sum_p P_p^T B_p P_p: row r holds
    the union of the positions of the parts that hold r.  Rows held by the same parts share that
    union (a cut), so no product of index sets is formed."""
    sizes = [len(pos) for pos in positions]
    owners = sp.csr_matrix((np.ones(sum(sizes), dtype=np.int8),
                            (np.concatenate(positions), np.repeat(np.arange(len(sizes)), sizes))),
                           shape=(n, len(sizes)))
    keys = [owners.indices[owners.indptr[r]:owners.indptr[r + 1]].tobytes() for r in range(n)]
    union = {key: np.unique(np.concatenate([positions[p] for p in np.frombuffer(key, dtype=owners.indices.dtype)]
                                           or [np.zeros(0, np.int64)])) for key in set(keys)}
    counts = np.array([len(union[key]) for key in keys], dtype=np.int64)
    indptr = np.r_[0, np.cumsum(counts)]
    index_type = np.int32 if indptr[-1] < 2**31 else np.int64
    indices = np.empty(indptr[-1], dtype=index_type)
    for r, key in enumerate(keys):
        indices[indptr[r]:indptr[r + 1]] = union[key]
    S = sp.csr_matrix((np.zeros(len(indices)), indices, indptr.astype(index_type)), shape=(n, n))
    S.has_sorted_indices = True
    return S


def cut_groups(local, n_coarse: int, fixed: np.ndarray) -> list[np.ndarray]:
    """The cuts: the coarse DOFs (positions in G) not in ``fixed``, grouped by the set of parts that
    share them (an interface between two parts, or the edge where three meet)."""
    owners = sp.csr_matrix((np.ones(sum(len(pos) for pos in local)),
                            (np.concatenate(local), np.repeat(np.arange(len(local)), [len(pos) for pos in local]))),
                           shape=(n_coarse, len(local)))
    free = np.setdiff1d(np.arange(n_coarse), fixed)
    keys = [owners.indices[owners.indptr[g]:owners.indptr[g + 1]].tobytes() for g in free]
    _, group = np.unique(np.array(keys, dtype=object), return_inverse=True)
    return [free[group == k] for k in range(int(group.max(initial=-1)) + 1)]


def interface_modes(S: np.ndarray, M: np.ndarray, count: int) -> np.ndarray:
    """(ng, min(count, ng)) the lowest eigenvectors of S phi = lambda M phi on one cut, M-normalised:
    S the exact static Schur complement of the whole model on the cut (the other coarse DOFs held),
    M the model's mass on it - the cut's smoothest displacement fields first (characteristic
    constraint modes of the cut; Castanier, Tan & Pierre 2001, with the cut's own mass)."""
    n = S.shape[0]
    if count >= n:
        return np.eye(n)
    _, phi = sla.eigh(0.5 * (S + S.T), 0.5 * (M + M.T), subset_by_index=(0, count - 1))
    return phi


def boundary_positions(coarse: np.ndarray, boundary) -> tuple[np.ndarray, np.ndarray]:
    """(positions in G of the boundary b, positions of G \\ b), both ascending: the numbering of the
    exact static Schur complement's positions (``static_schur``) and of the coarse space's cuts."""
    b = np.searchsorted(coarse, np.asarray(boundary, dtype=np.int64))
    return b, np.setdiff1d(np.arange(len(coarse)), b)


def part_positions(parts, coarse: np.ndarray) -> tuple:
    """Per part, the positions in G (``coarse``) of its coarse DOFs B_p."""
    return tuple(np.searchsorted(coarse, part.dofs[part.boundary]) for part in parts)


@dataclass(frozen=True)
class CoarseSpace:
    """The coarse DOFs G and the coordinates c = [u_b, eta_1, ..., eta_k] of the second level: u_G = R c.

    coarse : (nG,) model DOFs, ascending; local : per part, positions of its B_p in G; fixed : (nb,)
    positions of b in G (c starts with u_b in b's order); R : (nG, nc) csr, identity on b, a cut's
    interface modes on its DOFs.
    """

    coarse: np.ndarray
    local: tuple
    fixed: np.ndarray
    R: sp.csr_matrix

    @property
    def n_boundary(self) -> int:
        return len(self.fixed)

    @property
    def free(self) -> np.ndarray:
        """Positions in G of G \\ b, ascending."""
        return np.setdiff1d(np.arange(len(self.coarse)), self.fixed)

    def columns(self, p: int) -> np.ndarray:
        """Positions in c of the coordinates that move part p's coarse DOFs."""
        return np.unique(self.R[self.local[p]].indices)

    def part_map(self, p: int) -> sp.csr_matrix:
        """(nb_p, len(columns(p))) csr: part p's coarse DOFs from its coordinates."""
        return self.R[self.local[p]][:, self.columns(p)].tocsr()


def coarse_space(parts, coarse: np.ndarray, boundary, S: CutBlocks, M_model, n_interface: int) -> CoarseSpace:
    """The coarse space of ``parts`` from the whole model's exact static Schur complement S on G \\ b
    (``static_schur``, its blocks between the cuts): b kept, every cut reduced to its ``n_interface``
    lowest interface modes (S itself is factored for the substructured solve by ``schur_factor``)."""

    b, free = boundary_positions(coarse, boundary)
    local = part_positions(parts, coarse)
    blocks = [sp.csr_matrix((np.ones(len(b)), (b, np.arange(len(b)))), shape=(len(coarse), len(b)))]
    for k, cut in enumerate(S.groups):
        g = free[cut]
        with all_cores_blas():                            # no part task runs yet
            phi = interface_modes(S.block(k), M_model[coarse[g]][:, coarse[g]].toarray(), n_interface)
        rows, cols = np.nonzero(np.ones_like(phi, dtype=bool))
        blocks.append(sp.csr_matrix((phi.ravel(), (g[rows], cols)), shape=(len(coarse), phi.shape[1])))
    return CoarseSpace(coarse, local, b, sp.hstack(blocks, format="csr"))


def schur_factor(S: CutBlocks):
    """The factor of the exact static Schur complement on G \\ b (``static_schur``) for the substructured
    solve (``CutFactor``, out of core when S is; S is consumed); None when G \\ b is empty.
    LinAlgError unless S is positive definite (a part, or the body, free to move)."""
    if not S.groups:
        return None
    factor = S.eliminate(keep=True)
    if factor is None or factor.negative:
        raise np.linalg.LinAlgError("the coarse Schur complement is not positive definite: a part or the body can "
                                    "move freely")
    return factor


# ---------------------------------------------------------------------------------------------
# level 1: one part (a task)
# ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class PartReduction:
    """A part's Craig-Bampton reduction as a task returns it (no factor: it does not travel).

    K, M : (nc_p + nm_p,) square dense, on [c_p, q_p] (its coarse coordinates, its modal ones);
    modes : (ni_p, nm_p) fixed-interface modes on the part's own DOFs, M_II-normalised;
    frequencies_hz : (nm_p,); peak_memory_mb : the worker's peak.
    """

    K: np.ndarray
    M: np.ndarray
    modes: np.ndarray
    frequencies_hz: np.ndarray
    peak_memory_mb: float = 0.0

    @property
    def top_hz(self) -> float:
        return float(self.frequencies_hz[-1]) if len(self.frequencies_hz) else 0.0


def with_coarse_coordinates(part: PartModel, R: sp.csr_matrix) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """T^T K T, T^T M T of the part on [its own DOFs, its coarse coordinates c_p]: T = diag(I, R),
    R (nb_p, nc_p) its coarse DOFs from c_p (CoarseSpace.part_map)."""
    own = part.interior
    n_i, n_c = len(own), R.shape[1]
    R = R.tocoo()
    T = sp.csr_matrix((np.r_[np.ones(n_i), R.data], (np.r_[own, part.boundary[R.row]], np.r_[np.arange(n_i), n_i + R.col])),
                      shape=(len(part.dofs), n_i + n_c))
    return (T.T @ (part.K @ T)).tocsr(), (T.T @ (part.M @ T)).tocsr()


def reduce_part(held: HeldPart, R: sp.csr_matrix, n_modes: int | None = None, fmax: float | None = None,
                memory_limit: float | None = None) -> PartReduction:
    """Craig-Bampton of one part on its coarse coordinates (``with_coarse_coordinates``): n_modes
    fixed-interface modes or all below fmax (Hz); ``memory_limit`` : bytes the worker may use (the
    reduction refuses to start beyond it).  One constraint mode per coarse coordinate.  Its factor of
    K_II (the part's own DOFs come first, unchanged) is kept in ``held`` for the later solves.  A task."""

    part = held.part
    n_i = len(part.dofs) - len(part.boundary)
    n_modes = None if n_modes is None else min(n_modes, n_i - 1)
    K, M = with_coarse_coordinates(part, R)
    try:
        with single_threaded_blas():                      # one BLAS thread per task (a worker per core)
            cb = craig_bampton(K, M, np.arange(n_i, K.shape[0]), n_modes=n_modes, fmax=fmax,
                               memory_limit=memory_limit, extent=part.extent)
    except InputError as exc:
        raise InputError(f"{part.name}: {exc}") from None
    held.keep(cb.interior_factor)
    return PartReduction(cb.K, cb.M, cb.basis[:n_i, cb.n_boundary:].copy(), cb.fixed_interface_hz, peak_memory_mb())


def short_parts(reductions: list[PartReduction], parts: list[PartModel], f_needed: float) -> list[int]:
    """Parts whose fixed-interface modes stop below ``f_needed`` Hz while they have more."""
    return [p for p, (r, part) in enumerate(zip(reductions, parts))
            if r.top_hz < f_needed and len(r.frequencies_hz) < len(part.dofs) - len(part.boundary) - 1]


# ---------------------------------------------------------------------------------------------
# level 2: assembly, second Craig-Bampton, recovery
# ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Assembly:
    """The reduced parts on [c, q_1, ..., q_N]: K, M (n_asm, n_asm) csr; space : the CoarseSpace of c;
    offsets : (N + 1,) start of each q_p."""

    K: sp.csr_matrix
    M: sp.csr_matrix
    space: CoarseSpace
    offsets: np.ndarray


def assemble_parts(reductions: list[PartReduction], space: CoarseSpace) -> Assembly:
    """Sum every part's reduced K, M into the coarse coordinates and its own modal ones (step 2)."""
    offsets = space.R.shape[1] + np.cumsum([0] + [r.modes.shape[1] for r in reductions])
    index = [np.r_[space.columns(p), np.arange(offsets[p], offsets[p + 1])] for p in range(len(reductions))]
    n = int(offsets[-1])
    return Assembly(summed_blocks(index, [r.K for r in reductions], n), summed_blocks(index, [r.M for r in reductions], n),
                    space, offsets)


def static_schur(parts, coarse: np.ndarray, boundary, tasks=None, out_of_core: bool | None = None) -> CutBlocks:
    """The whole model's exact static Schur complement on G \\ b as dense blocks between its cuts
    (``CutBlocks``, positions in G \\ b; ``out_of_core``: see there): the sum of the parts'
    (``part_dynamic_schur`` at sigma 0 on ``tasks``, a function fn, [args per part], consume ->
    [results], or ``InProcess``), each added as it arrives: for ``coarse_space`` and ``schur_factor``."""

    b, free = boundary_positions(coarse, boundary)
    local = part_positions(parts, coarse)
    slot = np.full(len(coarse), -1)
    slot[free] = np.arange(len(free))
    positions = [slot[pos] for pos in local]
    total = CutBlocks([slot[g] for g in cut_groups(local, len(coarse), b)], len(free), positions,
                      out_of_core=out_of_core)
    (tasks or InProcess(parts))(part_dynamic_schur, [(0.0,)] * len(parts),
                                lambda p, inertia: total.add(positions[p], inertia.schur))
    return total


def count_below(parts, coarse: np.ndarray, held, sigma: float, tasks=None) -> int | None:
    """Eigenvalues below ``sigma`` of the whole model with the DOFs ``held`` removed: Sylvester's law of
    inertia with every part's own DOFs eliminated (Wittrick-Williams over the parts) - the negative
    pivots of every part's (K - sigma M)_II (a sparse LDL^T, sidprep.fe.pardiso) plus those of the
    sum of their exact dynamic Schur complements on G (``part_dynamic_schur`` on ``tasks``, see
    ``static_schur``), held as dense blocks between the cuts as the parts' blocks arrive and
    eliminated cut by cut (``CutBlocks``).  None when a pivot was perturbed or is zero."""

    local = part_positions(parts, coarse)
    held_at = np.flatnonzero(np.isin(coarse, [] if held is None else held))
    blocks = CutBlocks(cut_groups(local, len(coarse), held_at), len(coarse), local, count_only=True)
    below = perturbed = 0

    def add(p: int, inertia: Inertia) -> None:
        nonlocal below, perturbed
        below, perturbed = below + inertia.n_negative, perturbed + inertia.n_perturbed
        blocks.add(local[p], inertia.schur)

    (tasks or InProcess(parts))(part_dynamic_schur, [(sigma,)] * len(parts), add)
    with all_cores_blas():                                # the part tasks are done
        coarse_count = None if perturbed else blocks.negative_pivots()
    return None if coarse_count is None else int(below + coarse_count)


class CutBlocks:
    """A symmetric matrix on n coarse positions as dense blocks between groups of them (the cuts,
    ``cut_groups``): block (i, j), i <= j, exists when a part holds DOFs of both.  The parts' Schur
    complements are added as they arrive (``add``); ``eliminate`` runs a block LDL^T group by group
    (fewest neighbours first), so the memory is the blocks of the sum (for a chain of parts, two cuts
    per part) - no sparse factor with its symbolic analysis of the whole coarse matrix.

    ``arriving``: the positions of every block to be added (one per part).  ``count_only`` (for
    ``negative_pivots``): a group is eliminated as soon as its blocks are all in and it has at most
    two neighbours (its elimination adds at most the one block it joins them by, and drops two),
    while the other parts' blocks arrive - the peak is the front of the elimination, not the whole
    matrix.  ``out_of_core`` (default: when the blocks will exceed COARSE_IN_MEMORY_FRACTION of the
    available memory; never for a count): the blocks, and the factor's L and W, in memory-mapped
    temporary files (``disk_zeros``)."""

    def __init__(self, groups: list[np.ndarray], n: int, arriving: list, count_only: bool = False,
                 out_of_core: bool | None = None):
        self.groups = [np.asarray(g, dtype=np.int64) for g in groups]
        self.sizes = [len(g) for g in groups]
        self.n = n
        self.group = np.full(n, -1)
        self.offset = np.zeros(n, dtype=np.int64)
        for k, g in enumerate(self.groups):
            self.group[g], self.offset[g] = k, np.arange(len(g))
        self.blocks: dict = {}
        self.neighbours = {k: set() for k in range(len(self.sizes))}   # the groups not eliminated yet
        self.pending = np.zeros(len(self.sizes), dtype=np.int64)       # blocks still to come per group
        for pos in arriving:
            touched = self.groups_at(pos)
            self.pending[touched] += 1
            self.join(touched)
        self.count_only = count_only
        if out_of_core is None:
            out_of_core = not count_only and self.planned_bytes() > COARSE_IN_MEMORY_FRACTION * available_memory_bytes()
        if out_of_core:
            check_disk_room(self.planned_bytes())
        self.zeros = disk_zeros if out_of_core else np.zeros
        self.negative: int | None = 0
        self.steps: list = []

    def planned_bytes(self) -> int:
        """Bytes of the blocks once every part's is in (before any elimination)."""
        pairs = sum(self.sizes[i] * self.sizes[j] for i in self.neighbours for j in self.neighbours[i] if i < j)
        return 8 * (pairs + sum(size * size for size in self.sizes))

    def groups_at(self, pos: np.ndarray) -> np.ndarray:
        """The groups holding any of the positions ``pos`` (-1 or in no group: none)."""
        g = self.group[pos[pos >= 0]]
        return np.unique(g[g >= 0])

    def join(self, touched) -> None:
        """Record the groups ``touched`` as each other's neighbours."""
        for i in touched:
            self.neighbours[i].update(j for j in touched if j != i)

    def add(self, pos: np.ndarray, B: np.ndarray) -> None:
        """Add the dense block B (len(pos), len(pos)) at the positions ``pos`` (-1 or in no group: dropped)."""
        g = np.where(pos >= 0, self.group[pos], -1)
        rows = {k: np.flatnonzero(g == k) for k in np.unique(g[g >= 0])}
        for i, ri in rows.items():
            for j, rj in rows.items():
                if i <= j:
                    if (i, j) not in self.blocks:
                        self.blocks[(i, j)] = self.zeros((self.sizes[i], self.sizes[j]))
                    block = self.blocks[(i, j)]
                    block[np.ix_(self.offset[pos[ri]], self.offset[pos[rj]])] += B[np.ix_(ri, rj)]
        self.pending[list(rows)] -= 1
        if self.count_only:
            with single_threaded_blas():                  # the other parts' tasks run meanwhile
                self.eliminate_complete()

    def eliminate_complete(self) -> None:
        """Eliminate, counting only, every group whose blocks are all in and that has at most two neighbours."""
        while self.negative is not None:
            ready = [k for k, near in self.neighbours.items() if self.pending[k] == 0 and len(near) <= 2]
            if not ready:
                return
            self.eliminate_group(min(ready, key=lambda g: (len(self.neighbours[g]), self.sizes[g])), keep=False)

    def stored(self, a: np.ndarray) -> np.ndarray:
        """``a``, or a copy out of core when the blocks are."""
        if self.zeros is np.zeros:
            return a
        out = disk_zeros(a.shape)
        out[...] = a
        return out

    def block(self, k: int) -> np.ndarray:
        """The dense symmetric diagonal block of group k (before ``eliminate``)."""
        return self.blocks.get((k, k), np.zeros((self.sizes[k], self.sizes[k])))

    def negative_pivots(self) -> int | None:
        """Negative eigenvalues of the matrix, or None when a pivot is zero (``eliminate``).  Consumes it."""
        factor = self.eliminate(keep=False)
        return None if factor is None else factor.negative

    def eliminate(self, keep: bool) -> CutFactor | None:
        """The block LDL^T of the groups left, group after group, fewest neighbours first
        (``eliminate_group``).  A CutFactor: the negative pivots (Sylvester's law, Haynsworth's inertia
        additivity over the groups) and, with ``keep``, the steps its ``solve`` needs; None when a
        pivot is zero.  Consumes the blocks."""
        if keep and self.count_only:
            raise ValueError("a CutBlocks for a count is eliminated as its blocks arrive: it keeps no factor")
        while self.neighbours and self.negative is not None:
            self.eliminate_group(min(self.neighbours, key=lambda g: (len(self.neighbours[g]), self.sizes[g])), keep)
        return None if self.negative is None else CutFactor(self.n, self.negative, self.steps)

    def eliminate_group(self, k: int, keep: bool) -> None:
        """One step of the block LDL^T: A_kk = L D L^T (Bunch-Kaufman, scipy.linalg.ldl) and its
        neighbours' blocks updated by A_kn^T A_kk^-1 A_kn = W^T D^-1 W, W = L^-1 P^T A_kn (level-3
        triangular solves; LAPACK's dsytrs with as many right-hand sides is level-2: 6.5 s against
        1.4 s for a 2600-DOF cut); its negative pivots added to ``negative`` (None when a pivot is
        zero), with ``keep`` the step appended to ``steps`` (its L and W out of core when the blocks are)."""
        blocks = self.blocks
        near = sorted(self.neighbours.pop(k))
        L, D, perm = sla.ldl(self.block(k), lower=True, overwrite_a=True, check_finite=False)
        blocks.pop((k, k), None)
        D = tridiagonal_bands(D)                        # (3, nk), not the dense (nk, nk): kept in memory
        count = block_diagonal_negatives(D)
        if count is None:
            self.negative = None
            return
        self.negative += count
        L = L[perm]                                     # unit lower triangular: A_kk[perm][:, perm] = L D L^T
        W = np.zeros((self.sizes[k], 0))
        if near:
            A = np.hstack([blocks.pop((k, i)) if k < i else blocks.pop((i, k)).T for i in near])  # A_k,near
            W = sla.solve_triangular(L, A[perm], lower=True, unit_diagonal=True, check_finite=False)
            del A
            DW = block_diagonal_solve(D, W)
            at = np.cumsum([0] + [self.sizes[i] for i in near])
            for i in near:
                self.neighbours[i].discard(k)
            for a, i in enumerate(near):
                for b, j in enumerate(near[a:], start=a):
                    update = W[:, at[a]:at[a + 1]].T @ DW[:, at[b]:at[b + 1]]
                    if (i, j) not in blocks:
                        blocks[(i, j)] = self.zeros(update.shape)
                    blocks[(i, j)] -= update
            self.join(near)
            del DW
        if keep:
            self.steps.append(EliminationStep(self.groups[k], [self.groups[i] for i in near], self.stored(L), D, perm,
                                              self.stored(W)))


def disk_zeros(shape: tuple) -> np.ndarray:
    """A float64 array of zeros mapped from a temporary file that has no name (the kernel frees it with
    the map): the page cache keeps what memory allows and the rest is written out and read back when
    used - out of core, as MUMPS's OOC factors.  The file's blocks are reserved first
    (``posix_fallocate``): a map of a sparse file on a full disk kills the process with SIGBUS at the
    first page written (the 2.4M row once, with 9 GB free) - here it is an InputError instead."""
    nbytes = 8 * int(np.prod(shape))
    with tempfile.TemporaryFile(prefix="sidprep-coarse-") as fh:
        try:
            os.posix_fallocate(fh.fileno(), 0, max(nbytes, 1))
        except OSError as exc:
            raise InputError(no_disk_room(nbytes, exc.strerror)) from None
        return np.memmap(fh, dtype=np.float64, mode="w+", shape=shape)


def check_disk_room(nbytes: float) -> None:
    """InputError when the temporary directory has less than ``nbytes`` free (before the blocks of an
    out-of-core coarse problem are made; their factor takes about as much again, ``disk_zeros``)."""
    free = shutil.disk_usage(tempfile.gettempdir()).free
    if nbytes > free:
        raise InputError(no_disk_room(nbytes, f"{free / 1024.0**3:.3g} GB free"))


def no_disk_room(nbytes: float, why: str) -> str:
    """The one-line error of an out-of-core coarse problem without room on disk."""
    return (f"coarse problem out of core: {nbytes / 1024.0**3:.3g} GB do not fit in the temporary directory "
            f"{tempfile.gettempdir()} ({why}); set TMPDIR to a disk with room, or use more memory")


@dataclass(frozen=True)
class EliminationStep:
    """One group's elimination in a block LDL^T: rows (its positions), near (its neighbours' positions,
    in the order of W's columns), A_kk[perm][:, perm] = L D L^T (D as ``tridiagonal_bands``),
    W = L^-1 A_k,near[perm]."""

    rows: np.ndarray
    near: list
    L: np.ndarray
    D: np.ndarray
    perm: np.ndarray
    W: np.ndarray


@dataclass(frozen=True)
class CutFactor:
    """A block LDL^T of a symmetric matrix on n positions (``CutBlocks.eliminate``): negative, its
    negative eigenvalues; steps, the eliminations in order."""

    n: int
    negative: int
    steps: list

    def solve(self, b: np.ndarray) -> np.ndarray:
        """x = A^-1 b, b (n,) or (n, k): block forward elimination, then back substitution in reverse
        (z_k = L^-1 b_k[perm], b_near -= W^T D^-1 z_k; x_k[perm] = L^-T D^-1 (z_k - W x_near))."""
        shape = np.shape(b)
        v = np.array(b, dtype=float).reshape(self.n, -1)
        z = []
        for s in self.steps:
            z.append(sla.solve_triangular(s.L, v[s.rows][s.perm], lower=True, unit_diagonal=True, check_finite=False))
            if s.near:
                near = np.concatenate(s.near)
                v[near] -= s.W.T @ block_diagonal_solve(s.D, z[-1])
        x = np.zeros_like(v)
        for s, z_k in zip(reversed(self.steps), reversed(z)):
            if s.near:
                z_k = z_k - s.W @ x[np.concatenate(s.near)]
            y = sla.solve_triangular(s.L, block_diagonal_solve(s.D, z_k), lower=True, trans="T", unit_diagonal=True,
                                     check_finite=False)
            x[s.rows[s.perm]] = y
        return x.reshape(shape)


def tridiagonal_bands(D: np.ndarray) -> np.ndarray:
    """(3, n) the bands of the tridiagonal (n, n) D in ``scipy.linalg.solve_banded``'s (1, 1) layout:
    superdiagonal (first entry 0), diagonal, subdiagonal (last entry 0).  A Bunch-Kaufman D (1 x 1 and
    2 x 2 blocks) stored so: O(n) against the dense D's n^2, as large as L and kept in memory when L is out
    of core (``CutBlocks``)."""
    bands = np.zeros((3, len(D)))
    bands[0, 1:], bands[1], bands[2, :-1] = np.diag(D, 1), np.diag(D), np.diag(D, -1)
    return bands


def block_diagonal_negatives(D: np.ndarray) -> int | None:
    """Negative eigenvalues of the block-diagonal D (1 x 1 and 2 x 2 blocks; ``tridiagonal_bands``) of a
    Bunch-Kaufman L D L^T (scipy.linalg.ldl), or None when D is singular."""
    d, e = D[1], np.r_[D[0, 1:], 0.0]
    negative, k, n = 0, 0, len(d)
    while k < n:
        if e[k] == 0.0:
            if d[k] == 0.0:
                return None
            negative, k = negative + int(d[k] < 0), k + 1
        else:                                            # 2 x 2 block: det < 0 -> one of each sign
            det = d[k] * d[k + 1] - e[k] * e[k]
            if det == 0.0:
                return None
            negative, k = negative + (1 if det < 0 else 2 * int(d[k] < 0)), k + 2
    return negative


def block_diagonal_solve(D: np.ndarray, W: np.ndarray) -> np.ndarray:
    """D^-1 W for the block-diagonal D (``tridiagonal_bands``, (3, n)) of ``block_diagonal_negatives``, W (n, k)."""
    return sla.solve_banded((1, 1), D, W, check_finite=False)


def part_dynamic_schur(held: HeldPart, sigma: float) -> Inertia:
    """The Inertia of the part's (K - sigma M)_II (#{its eigenvalues below sigma}, perturbed pivots) with
    the part's exact dynamic Schur complement (K - sigma M)_BB - (K - sigma M)_BI (K - sigma M)_II^-1
    (K - sigma M)_IB (nb_p, nb_p) on its coarse DOFs, from one sparse LDL^T of K - sigma M.  A task."""

    part = held.part
    with single_threaded_blas():                          # one BLAS thread per task (a worker per core)
        K = (part.K - sigma * part.M).tocsr() if sigma else part.K
        return ldlt_inertia(K, part.boundary)


def interior_factor(part: PartModel):
    """The factor of the part's K_II (its own DOFs)."""
    own = part.interior
    return factorize(part.K[own][:, own])


def part_coarse_load(held: HeldPart, r: np.ndarray) -> np.ndarray:
    """K_BI K_II^-1 r (nb_p, k): the part's share of the coarse right-hand side, r (ni_p, k) on its own
    DOFs, with the factor ``held`` keeps (the driver holds none).  A task."""
    part = held.part
    with single_threaded_blas():                          # one BLAS thread per task (a worker per core)
        y = np.asarray(held.factor().solve(r)).reshape(r.shape)
        return part.K[part.boundary][:, part.interior] @ y


def part_interior_solve(held: HeldPart, r: np.ndarray, u_B: np.ndarray) -> np.ndarray:
    """K_II^-1 ([r, 0] - K_IB u_B) (ni_p, k'): the part's own DOFs given its coarse DOFs u_B (nb_p, k')
    and the load r (ni_p, k), k <= k', on its own DOFs in the first k columns (the others: a
    recovery with no load), with the factor ``held`` keeps.  A task."""
    part = held.part
    rhs = -(part.K[part.interior][:, part.boundary] @ u_B)
    rhs[:, :r.shape[1]] += r
    with single_threaded_blas():
        return np.asarray(held.factor().solve(rhs)).reshape(rhs.shape)


class SubstructuredSolver:
    """Exact solves with K_ii of the whole model (i = every model DOF but the boundary b) from the
    parts and ``coarse_factor``, the factor of the exact static Schur complement S on the coarse DOFs
    G \\ b (``coarse_space``):

        g = r_G - sum_p K_GI K_II^-1 r_p,   S x_G = g,   x_p = K_II^-1 (r_p - K_IG x_G)

    two rounds of part tasks (``part_coarse_load``, ``part_interior_solve`` on ``tasks``: fn,
    [args per part] -> [fn(HeldPart, *args) per part], default ``InProcess``) around the coarse solve;
    each part's K_II is factored once, where the part is held (the driver holds no part factor).
    It is the ``interior_factor`` of the parts' ReducedModel (``solve``), recovers every model DOF
    from coarse coordinates and modal coordinates in the same second round (``solve_and_recover``)
    and counts eigenvalues over the parts (``eigenvalue_count``).
    """

    def __init__(self, parts, reductions, assembly: Assembly, boundary, n_model: int, coarse_factor, tasks=None):

        self.parts, self.reductions, self.assembly = parts, reductions, assembly
        self.tasks = tasks or InProcess(parts)
        self.space = assembly.space
        self.boundary = np.asarray(boundary, dtype=np.int64)
        interior = np.ones(n_model, bool)
        interior[self.boundary] = False
        self.row = np.cumsum(interior) - 1                 # model DOF -> row of K_ii
        self.free_coarse = self.space.free
        self.schur = coarse_factor

    def own_rows(self, p: int) -> np.ndarray:
        """Rows of K_ii of part p's own DOFs."""
        part = self.parts[p]
        return self.row[part.dofs[part.interior]]

    def solve(self, r: np.ndarray, overwrite_r: bool = False) -> np.ndarray:
        """x = K_ii^-1 r, r (ni,) or (ni, k) in the rows of K_ii (model DOFs but b, ascending);
        ``overwrite_r``: x is written into r (float64, C-contiguous), no (ni, k) array more."""
        shape = np.shape(r)
        x, _ = self.solve_and_recover(np.asarray(r, dtype=float).reshape(shape[0], -1), None, overwrite_r)
        return x.reshape(shape)

    def solve_and_recover(self, r: np.ndarray, U: np.ndarray | None, overwrite_r: bool = False,
                          out: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None]:
        """(K_ii^-1 r (ni, k), the model-DOF vectors (n_model, m) of the assembly vectors U (n_asm, m),
        written into ``out`` if given); r (ni, k) in the rows of K_ii; U None: no recovery;
        ``overwrite_r``: see ``solve``.  The recovery (u_G = R c; each part's own DOFs
        u_I = -K_II^-1 K_IB u_B + Phi_p q_p, step 5) rides on the solve's second round."""
        space, n = self.space, len(self.parts)
        coarse, free = space.coarse, self.free_coarse
        slot = np.full(len(coarse), -1)
        slot[free] = np.arange(len(free))
        cols = [slot[space.local[p]] for p in range(n)]
        g = r[self.row[coarse[free]]].copy()

        def subtract(p: int, load: np.ndarray) -> None:
            keep = cols[p] >= 0
            g[cols[p][keep]] -= load[keep]

        r_parts = [r[self.own_rows(p)] for p in range(n)]      # each part's load, sent in both rounds
        if r.shape[1]:
            self.tasks(part_coarse_load, [(r_p,) for r_p in r_parts], subtract)
        with all_cores_blas():                            # between two rounds of part tasks
            x_G = np.asarray(self.schur.solve(g)).reshape(g.shape) if self.schur is not None and r.shape[1] else g
        x = r if overwrite_r else np.empty_like(r)       # every row of x is written below; r is in g, r_parts
        x[self.row[coarse[free]]] = x_G
        u_B = [np.where((c >= 0)[:, None], x_G[np.maximum(c, 0)], 0.0) for c in cols]
        if U is None:
            out = None
        else:                                              # recovery: u_G = R c, no load on the parts
            out = np.zeros((len(self.row), U.shape[1])) if out is None else out
            u_G = space.R @ U[:space.R.shape[1]]
            out[coarse] = u_G
            u_B = [np.hstack([u, u_G[space.local[p]]]) for p, u in enumerate(u_B)]
        k = r.shape[1]

        def place(p: int, x_p: np.ndarray) -> None:
            x[self.own_rows(p)] = x_p[:, :k]
            if U is not None:
                a, part = self.assembly, self.parts[p]
                out[part.dofs[part.interior]] = self.reductions[p].modes @ U[a.offsets[p]:a.offsets[p + 1]] + x_p[:, k:]

        self.tasks(part_interior_solve, list(zip(r_parts, u_B)), place)
        return x, out

    def constraint_modes_and_recovery(self, K_model, U: np.ndarray, out: np.ndarray | None = None) -> tuple:
        """((ni, nb) the whole model's exact constraint modes on the interior, -K_ii^-1 K_ib; the
        model-DOF vectors of the assembly vectors U, written into ``out`` if given): two rounds of part
        tasks for both."""
        interior = np.ones(K_model.shape[0], bool)
        interior[self.boundary] = False
        K_ib = K_model[self.boundary][:, interior].T      # K symmetric: no copy of K's interior rows
        return self.solve_and_recover(-K_ib.toarray(), U, overwrite_r=True, out=out)

    def eigenvalue_count(self, red, sigma: float) -> int | None:
        """Eigenvalues of the whole model below ``sigma`` (held DOFs removed), over the parts (``count_below``)."""
        return count_below(self.parts, self.space.coarse, red.held, sigma, self.tasks)


def second_level(assembly: Assembly, n_modes=None, fmax=None):
    """Step 3: Craig-Bampton of the assembled parts on the monolithic boundary b (c's first coordinates)."""
    return craig_bampton(assembly.K, assembly.M, np.arange(assembly.space.n_boundary), n_modes=n_modes, fmax=fmax)


def parts_reduced_model(K_model, M_model, boundary, parts, reductions, assembly, level2, coarse_factor, tasks=None):
    """Step 4: the ReducedModel of the whole model in model DOFs, as ``craig_bampton`` returns it
    (basis with the boundary columns first: the EXACT constraint modes by the substructured solve;
    then the refined fixed-interface modes; K, M projected from the model matrices), with the
    substructured K_ii solver as its factor (``coarse_factor``, ``tasks``: see there).  The list
    ``reductions`` is emptied once the basis is recovered: the parts' modes, (n, ~60) together, are
    not kept beside it (the driver's peak)."""

    n = K_model.shape[0]
    solver = SubstructuredSolver(parts, reductions, assembly, boundary, n, coarse_factor, tasks)
    nb = len(boundary)
    basis = np.zeros((n, level2.basis.shape[1]))
    psi, _ = solver.constraint_modes_and_recovery(K_model, level2.basis[:, nb:], out=basis[:, nb:])
    reductions.clear()                                    # the solver's too: the recovery is done
    interior = np.ones(n, bool)
    interior[boundary] = False
    basis[boundary, :nb] = np.eye(nb)
    basis[interior, :nb] = psi
    f, basis[interior, nb:] = refined_modes(K_model, M_model, interior, solver, basis[interior, nb:])
    return ReducedModel(basis, project(K_model, basis), project(M_model, basis),
                        np.asarray(boundary, dtype=np.int64), f, solver)


def refined_modes(K, M, interior, solver, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Step 6: the lowest len(X.T) eigenpairs of K_ii, M_ii in span[X, K_ii^-1 M_ii X] (Rayleigh-Ritz
    after one block inverse iteration); (frequencies Hz (nm,), modes (ni, nm) M_ii-normalised,
    written over X).
    V = [X, Y] is never formed: its Gram matrices are formed GRAM_BLOCK columns at a time from X and
    Y, Y = K_ii^-1 (M_ii X) is solved in the buffer of M_ii X (``blockwise``), and the Ritz vectors X R_X + Y R_Y
    ([R_X; R_Y] = diag(d) C Z, small) are written over X: the peak is about 2 x (ni, nm) beside X
    (Y and the solve's per-part loads)."""

    nm = X.shape[1]
    if nm == 0:
        return np.zeros(0), X
    m_ii, k_ii = interior_operator(M, interior).matmat, interior_operator(K, interior).matmat
    Y = solver.solve(blockwise(m_ii, X), overwrite_r=True)
    with all_cores_blas():                                # no part task runs
        G, H = block_gram(m_ii, (X, Y)), block_gram(k_ii, (X, Y))
    d = 1.0 / np.sqrt(np.diag(G))                          # columns of unit M_ii norm
    G, H = d[:, None] * G * d, d[:, None] * H * d
    s, W = np.linalg.eigh(0.5 * (G + G.T))
    keep = s > RANK_TOL * s.max()                        # X and K^-1 M X are nearly parallel
    C = W[:, keep] / np.sqrt(s[keep])                    # V diag(d) C is M_ii-orthonormal
    lam, Z = sla.eigh(C.T @ (0.5 * (H + H.T)) @ C, subset_by_index=(0, nm - 1))
    R = d[:, None] * (C @ Z)                             # (2 nm, nm): the Ritz vectors in V's columns
    return np.sqrt(np.abs(lam)) / (2 * np.pi), ritz_vectors(X, Y, R)


def ritz_vectors(X: np.ndarray, Y: np.ndarray, R: np.ndarray) -> np.ndarray:
    """X R[:nm] + Y R[nm:] written over X (ni, nm), REFINE_ROWS rows at a time: no (ni, nm) temporary."""
    nm = X.shape[1]
    for s in range(0, len(X), REFINE_ROWS):
        X[s:s + REFINE_ROWS] = X[s:s + REFINE_ROWS] @ R[:nm] + Y[s:s + REFINE_ROWS] @ R[nm:]
    return X
