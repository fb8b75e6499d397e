"""One FE model reduced in parts: component mode synthesis by two Craig-Bampton levels.

The cells are split into N connected parts (METIS on the cells' face graph).  In model DOFs
(after the RBE2/RBE3 interfaces, sidprep.reduction.interfaces) part p owns the DOFs its cells
touch; the *coarse* DOFs G are those owned by two or more parts plus the boundary b of the
monolithic reduction (the interface masters).  With I_p the other DOFs of part p, the model is

    K = sum_p T_p^T K_p T_p,     K_p = [[K_II, K_IB], [K_BI, K_BB]]  (B_p = part p's DOFs in G)

1. each part: Craig-Bampton on B_p (a task: sidprep.jobs.parts), u_I = Psi_p u_B + Phi_p q_p,
   Psi_p = -K_II^-1 K_IB, Phi_p its fixed-interface modes up to a cut-off;
2. the reduced parts assembled on [u_G, q_1 .. q_N] (``assemble_parts``): the G block of K is the
   exact Schur complement of the whole model onto G, and K_Gq = 0 (constraint modes are
   K-orthogonal to fixed-interface modes);
3. a second Craig-Bampton of that assembly on b: its constraint modes are EXACT constraint modes of
   the whole model (static condensation keeps q = 0), its fixed-interface modes approximate the
   monolithic ones as the parts' cut-off rises (``PART_CUTOFF``);
4. every model DOF recovered from the parts (``SubstructuredSolver.recover``), which gives the
   same ReducedModel as ``craig_bampton`` (basis, K, M, boundary b) with an exact K_ii^-1 by
   substructuring and a certified eigenvalue count (Wittrick-Williams over the parts), so the
   checks of sidprep.reduction.fe_checks hold against the full model unchanged;
5. the fixed-interface modes X refined by one block inverse iteration with that exact K_ii^-1:
   Rayleigh-Ritz of K_ii, M_ii on span[X, K_ii^-1 M_ii X] (``refined_modes``; a subspace-iteration
   step divides each mode's error by about the square of (its frequency / the parts' cut-off)).

Craig & Bampton 1968; Hurty 1965 (component modes); Wittrick & Williams 1971 (eigenvalue count);
Bathe & Wilson 1972 (subspace iteration).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pymetis
import scipy.linalg as sla
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from sidprep.errors import InputError
from sidprep.fe.assemble import scalar_mass_matrix, stiffness_matrix, vector_mass
from sidprep.fe.linalg import factorize, single_threaded_blas
from sidprep.fe.mesh import _face_table
from sidprep.fe.pardiso import ldlt_inertia
from sidprep.progress import peak_memory_mb
from sidprep.reduction.craig_bampton import ReducedModel, craig_bampton, interior_operator, project


#: the parts' fixed-interface modes reach this multiple of the highest fixed-interface frequency of
#: the second level (the component cut-off ratio that governs CMS accuracy): 1e-4 agreement with the
#: monolithic reduction on the piston rod (4 parts) and a bar (8 parts), tests/test_parts.py
PART_CUTOFF = 2.0
#: relative eigenvalue of the Gram matrix below which a direction of [X, K^-1 M X] is dropped
RANK_TOL = 1e-12
#: METIS load imbalance allowed between parts (1.03 = 3 %, its default for k-way partitions)
PART_IMBALANCE = 1.03


# ---------------------------------------------------------------------------------------------
# partition
# ---------------------------------------------------------------------------------------------

def face_graph(cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The cells' adjacency through shared faces in CSR form (xadj (ne + 1,), adjncy)."""

    group, counts, _ = _face_table(np.asarray(cells)[:, :4])
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
class PartModel:
    """One part in model DOFs: what a task needs.

    name : "part k/N"; dofs : (n_p,) its model DOFs (ascending); K, M : (n_p, n_p) csr, N/m and kg,
    assembled from its cells only; boundary : (nb_p,) local indices of its coarse DOFs (ascending);
    extent : (3,) bounding-box edges (m) for the memory estimate.
    """

    name: str
    dofs: np.ndarray
    K: sp.csr_matrix
    M: sp.csr_matrix
    boundary: np.ndarray
    extent: np.ndarray

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


def part_models(mesh, material, labels: np.ndarray, im, boundary, names=None) -> tuple[list[PartModel], np.ndarray]:
    """Each part's model matrices (T^T K_p T restricted to its DOFs, K_p from its cells) and the
    coarse DOFs G; ``boundary`` the monolithic reduction's boundary DOFs (model indices).
    ``material`` : one Material, or one per part (an assembly's components: a Material or
    GivenMatrices); ``names`` : one per part (default "part k/N")."""

    n = int(labels.max()) + 1
    materials = list(material) if isinstance(material, (list, tuple)) else [material] * n
    names = names or [f"part {p + 1}/{n}" for p in range(n)]
    cells = [mesh.cells[labels == p] for p in range(n)]
    owned = [part_dofs(im, c) for c in cells]
    G = coarse_dofs(owned, boundary)
    parts = []
    for c, dofs, mat, name in zip(cells, owned, materials, names):
        T = im.T[:, dofs]
        K_fe, M_fe = part_fe_matrices(mesh, c, mat)
        K = (T.T @ (K_fe @ T)).tocsr()
        M = (T.T @ (M_fe @ T)).tocsr()
        x = mesh.points[np.unique(c)]
        parts.append(PartModel(name, dofs, K, M, np.flatnonzero(np.isin(dofs, G)), np.ptp(x, axis=0)))
    return parts, G


# ---------------------------------------------------------------------------------------------
# level 1: one part (a task)
# ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class PartReduction:
    """A part's Craig-Bampton reduction as a task returns it (no factor: it does not travel).

    K, M : (nb_p + nm_p,) square dense, on [u_B, q_p]; modes : (ni_p, nm_p) fixed-interface modes on
    the part's own DOFs, M_II-normalised; frequencies_hz : (nm_p,); peak_memory_mb : the worker's peak.
    """

    K: np.ndarray
    M: np.ndarray
    modes: np.ndarray
    frequencies_hz: np.ndarray
    peak_memory_mb: float = 0.0

    @property
    def top_hz(self) -> float:
        return float(self.frequencies_hz[-1]) if len(self.frequencies_hz) else 0.0


def reduce_part(part: PartModel, n_modes: int | None = None, fmax: float | None = None,
                memory_limit: float | None = None) -> PartReduction:
    """Craig-Bampton of one part on its coarse DOFs: n_modes fixed-interface modes or all below fmax
    (Hz); ``memory_limit`` : bytes the worker may use (the reduction refuses to start beyond it)."""

    n_modes = None if n_modes is None else min(n_modes, len(part.dofs) - len(part.boundary) - 1)
    try:
        with single_threaded_blas():                      # one BLAS thread per task (a worker per core)
            cb = craig_bampton(part.K, part.M, part.boundary, n_modes=n_modes, fmax=fmax,
                               memory_limit=memory_limit, extent=part.extent)
    except InputError as exc:
        raise InputError(f"{part.name}: {exc}") from None
    interior = np.ones(len(part.dofs), bool)
    interior[part.boundary] = False
    return PartReduction(cb.K, cb.M, cb.basis[interior, cb.n_boundary:].copy(), cb.fixed_interface_hz,
                         peak_memory_mb())


def short_parts(reductions: list[PartReduction], parts: list[PartModel], f_needed: float) -> list[int]:
    """Parts whose fixed-interface modes stop below ``f_needed`` Hz while they have more."""
    return [p for p, (r, part) in enumerate(zip(reductions, parts))
            if r.top_hz < f_needed and len(r.frequencies_hz) < len(part.dofs) - len(part.boundary) - 1]


# ---------------------------------------------------------------------------------------------
# level 2: assembly, second Craig-Bampton, recovery
# ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Assembly:
    """The reduced parts on [u_G, q_1, ..., q_N]: K, M (n_asm, n_asm) csr; coarse : (nG,) model DOFs
    of u_G; local : per part, positions of its B_p in u_G; offsets : (N + 1,) start of each q_p."""

    K: sp.csr_matrix
    M: sp.csr_matrix
    coarse: np.ndarray
    local: tuple
    offsets: np.ndarray


def assemble_parts(parts: list[PartModel], reductions: list[PartReduction], coarse: np.ndarray) -> Assembly:
    """Sum every part's reduced K, M into the coarse DOFs and its own modal coordinates (step 2)."""
    nG = len(coarse)
    offsets = nG + np.cumsum([0] + [r.modes.shape[1] for r in reductions])
    local = tuple(np.searchsorted(coarse, part.dofs[part.boundary]) for part in parts)
    index = [np.r_[pos, np.arange(offsets[p], offsets[p + 1])] for p, pos in enumerate(local)]
    n = int(offsets[-1])
    return Assembly(summed_blocks(index, [r.K for r in reductions], n), summed_blocks(index, [r.M for r in reductions], n),
                    coarse, local, offsets)


class SubstructuredSolver:
    """Exact solves with K_ii of the whole model (i = every model DOF but the boundary b) from the
    parts' interior factors and the factor of the Schur complement S on the coarse DOFs G \\ b
    (the assembly's G block, step 2):

        y_p = K_II^-1 r_p,   S x_G = r_G - sum_p K_GI y_p,   x_p = y_p - K_II^-1 K_IG x_G

    It is the ``interior_factor`` of the parts' ReducedModel (``solve``), recovers every model DOF
    from coarse displacements and modal coordinates (``recover``) and counts eigenvalues over the
    parts (``eigenvalue_count``).
    """

    def __init__(self, parts, reductions, assembly: Assembly, boundary, n_model: int, tasks=None):

        self.parts, self.reductions, self.assembly, self.tasks = parts, reductions, assembly, tasks
        self.boundary = np.asarray(boundary, dtype=np.int64)
        interior = np.ones(n_model, bool)
        interior[self.boundary] = False
        self.row = np.cumsum(interior) - 1                 # model DOF -> row of K_ii
        self.free_coarse = np.flatnonzero(~np.isin(assembly.coarse, self.boundary))   # G \ b in u_G
        self.factors, self.K_IB = [], []
        for part in parts:
            own = part.interior
            self.factors.append(factorize(part.K[own][:, own]))
            self.K_IB.append(part.K[own][:, part.boundary].tocsc())
        S = assembly.K[self.free_coarse][:, self.free_coarse]
        self.schur = factorize(S) if S.shape[0] else None

    def _part_solve(self, p: int, rhs: np.ndarray) -> np.ndarray:
        return np.asarray(self.factors[p].solve(rhs)).reshape(rhs.shape)

    def solve(self, r: np.ndarray) -> np.ndarray:
        """x = K_ii^-1 r, r (ni,) or (ni, k) in the rows of K_ii (model DOFs but b, ascending)."""
        shape = np.shape(r)
        r = np.asarray(r, dtype=float).reshape(shape[0], -1)
        slot = np.full(len(self.assembly.coarse), -1)
        slot[self.free_coarse] = np.arange(len(self.free_coarse))
        g = r[self.row[self.assembly.coarse[self.free_coarse]]].copy()
        y, cols = [], []
        for p, part in enumerate(self.parts):
            y.append(self._part_solve(p, r[self.row[part.dofs[part.interior]]]))
            cols.append(slot[self.assembly.local[p]])
            keep = cols[p] >= 0
            g[cols[p][keep]] -= self.K_IB[p][:, keep].T @ y[p]
        x = np.empty_like(r)
        x_G = np.asarray(self.schur.solve(g)).reshape(g.shape) if self.schur is not None else g
        x[self.row[self.assembly.coarse[self.free_coarse]]] = x_G
        for p, part in enumerate(self.parts):
            u_B = np.where((cols[p] >= 0)[:, None], x_G[np.maximum(cols[p], 0)], 0.0)
            x[self.row[part.dofs[part.interior]]] = y[p] - self._part_solve(p, self.K_IB[p] @ u_B)
        return x.reshape(shape)

    def recover(self, U: np.ndarray, n_model: int) -> np.ndarray:
        """Model-DOF vectors (n_model, k) from assembly vectors U (n_asm, k): u_G as given, each part's
        own DOFs u_I = -K_II^-1 K_IB u_B + Phi_p q_p (step 4)."""
        a = self.assembly
        out = np.zeros((n_model, U.shape[1]))
        out[a.coarse] = U[:len(a.coarse)]
        for p, part in enumerate(self.parts):
            q = U[a.offsets[p]:a.offsets[p + 1]]
            out[part.dofs[part.interior]] = self.reductions[p].modes @ q - self._part_solve(p, self.K_IB[p] @ U[a.local[p]])
        return out

    def eigenvalue_count(self, red, sigma: float) -> int | None:
        """Eigenvalues of the whole model below ``sigma`` (held DOFs removed): Sylvester's law of inertia
        with every part's own DOFs eliminated (Wittrick-Williams over the parts) - the negative pivots of
        every part's (K - sigma M)_II plus those of the sum of their exact dynamic Schur complements on G
        (``part_dynamic_schur``: on ``tasks`` when given, a function fn, [args per part] -> [results], else
        here), both by a sparse LDL^T (sidprep.fe.pardiso).  None when a pivot had to be perturbed."""
        a = self.assembly
        args = [(part, sigma) for part in self.parts]
        schurs = self.tasks(part_dynamic_schur, args) if self.tasks is not None \
            else [part_dynamic_schur(*x) for x in args]
        if any(schur is None for schur in schurs):
            return None
        keep = ~np.isin(a.coarse, [] if red.held is None else red.held)
        coarse = coarse_inertia(summed_blocks(a.local, [schur[1] for schur in schurs], len(a.coarse))[keep][:, keep])
        if coarse is None:
            return None
        return int(sum(schur[0] for schur in schurs) + coarse)


def summed_blocks(positions, blocks, n: int) -> sp.csr_matrix:
    """sum_p P_p^T B_p P_p (n, n) csr: the dense blocks B_p (len(pos), len(pos)) added at ``positions``."""
    rows = np.concatenate([np.repeat(pos, len(pos)) for pos in positions])
    cols = np.concatenate([np.tile(pos, len(pos)) for pos in positions])
    return sp.csr_matrix((np.concatenate([B.ravel() for B in blocks]), (rows, cols)), shape=(n, n))


def coarse_inertia(S: sp.csr_matrix) -> int | None:
    """Negative eigenvalues of the symmetric sparse coarse matrix S by LDL^T, or None (a perturbed pivot)."""
    if S.shape[0] == 0:
        return 0
    inertia = ldlt_inertia(0.5 * (S + S.T))
    return None if inertia.n_perturbed else inertia.n_negative


def part_dynamic_schur(part: PartModel, sigma: float):
    """(#{eigenvalues of the part's (K, M)_II below sigma}, the part's exact dynamic Schur complement
    (K - sigma M)_BB - (K - sigma M)_BI (K - sigma M)_II^-1 (K - sigma M)_IB (nb_p, nb_p) on its coarse
    DOFs), both from one sparse LDL^T of the part's K - sigma M; None when a pivot was perturbed.  A task."""

    with single_threaded_blas():                          # one BLAS thread per task (a worker per core)
        inertia = ldlt_inertia((part.K - sigma * part.M).tocsr(), part.boundary)
    return None if inertia.n_perturbed else (inertia.n_negative, inertia.schur)


def second_level(assembly: Assembly, boundary, n_modes=None, fmax=None):
    """Step 3: Craig-Bampton of the assembled parts on the monolithic boundary b (in b's order)."""

    b = np.searchsorted(assembly.coarse, np.asarray(boundary, dtype=np.int64))
    return craig_bampton(assembly.K, assembly.M, b, n_modes=n_modes, fmax=fmax)


def parts_reduced_model(K_model, M_model, boundary, parts, reductions, assembly, level2, tasks=None):
    """Step 4: the ReducedModel of the whole model in model DOFs, as ``craig_bampton`` returns it
    (basis with the boundary columns first, K, M projected from the model matrices), with the
    substructured K_ii solver as its factor (``tasks``: where it runs per-part work, see there)."""

    n = K_model.shape[0]
    solver = SubstructuredSolver(parts, reductions, assembly, boundary, n, tasks)
    basis = solver.recover(level2.basis, n)
    nb = len(boundary)
    interior = np.ones(n, bool)
    interior[boundary] = False
    f, basis[interior, nb:] = refined_modes(K_model, M_model, interior, solver, basis[interior, nb:])
    return ReducedModel(basis, project(K_model, basis), project(M_model, basis),
                        np.asarray(boundary, dtype=np.int64), f, solver)


def refined_modes(K, M, interior, solver, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Step 5: the lowest len(X.T) eigenpairs of K_ii, M_ii in span[X, K_ii^-1 M_ii X] (Rayleigh-Ritz
    after one block inverse iteration); (frequencies Hz (nm,), modes (ni, nm) M_ii-normalised)."""


    nm = X.shape[1]
    if nm == 0:
        return np.zeros(0), X
    m_ii, k_ii = interior_operator(M, interior).matmat, interior_operator(K, interior).matmat
    Y = solver.solve(m_ii(X))
    V = np.hstack([X, Y / np.sqrt(np.einsum("ij,ij->j", Y, m_ii(Y)))])    # columns of unit M_ii norm
    gram = V.T @ m_ii(V)
    s, W = np.linalg.eigh(0.5 * (gram + gram.T))
    keep = s > RANK_TOL * s.max()                        # X and K^-1 M X are nearly parallel
    V = V @ (W[:, keep] / np.sqrt(s[keep]))              # M_ii-orthonormal
    lam, Z = sla.eigh(V.T @ k_ii(V), subset_by_index=(0, nm - 1))
    return np.sqrt(np.abs(lam)) / (2 * np.pi), V @ Z
