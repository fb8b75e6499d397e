"""The coarse problem of component mode synthesis: the exact static Schur complement S of the whole
model on the coarse DOFs G \\ b (the cuts between parts), summed from the parts' own (part tasks,
sidprep.reduction.part_tasks) into dense blocks between the cuts (sidprep.reduction.block_ldlt); its
factor for the substructured solve (``schur_factor``); the coarse space u_G = R c, b kept and every
cut reduced to its lowest interface modes, eigenvectors of S and M on the cut (characteristic
constraint modes; Castanier, Tan & Pierre 2001; ``coarse_space``); and the eigenvalue count of the
whole model over the parts (Wittrick & Williams 1971; ``count_below``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from sidprep.fe.linalg import all_cores_blas
from sidprep.fe.pardiso import Inertia
from sidprep.reduction.block_ldlt import CutBlocks, CutFactor
from sidprep.reduction.part_tasks import InProcess, PartTaskRunner, part_dynamic_schur


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


def schur_factor(S: CutBlocks) -> CutFactor | None:
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


def static_schur(parts, coarse: np.ndarray, boundary, tasks: PartTaskRunner | None = None,
                 out_of_core: bool | None = None) -> CutBlocks:
    """The whole model's exact static Schur complement on G \\ b as dense blocks between its cuts
    (``CutBlocks``, positions in G \\ b; ``out_of_core``: see there): the sum of the parts'
    (``part_dynamic_schur`` at sigma 0 on ``tasks``, default ``InProcess``), each added as it arrives:
    for ``coarse_space`` and ``schur_factor``."""

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


def count_below(parts, coarse: np.ndarray, held, sigma: float, tasks: PartTaskRunner | None = None) -> int | None:
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


