"""One FE model reduced in parts: component mode synthesis by two Craig-Bampton levels.

The cells are split into N connected parts (sidprep.reduction.partition).  In model DOFs (after the
RBE2/RBE3 interfaces) part p owns the DOFs its cells touch; the *coarse* DOFs G are those owned by
two or more parts plus the boundary b of the monolithic reduction (the interface masters).  With I_p
the other DOFs of part p, the model is

    K = sum_p T_p^T K_p T_p,     K_p = [[K_II, K_IB], [K_BI, K_BB]]  (B_p = part p's DOFs in G)

The steps, in the order of the driver sidprep.jobs.parts.reduce_in_parts (each part's work is a task
where the part is held, sidprep.reduction.part_tasks):

1. each part's exact static Schur complement S_p = K_BB - K_BI K_II^-1 K_IB on B_p (one sparse partial
   LDL^T); their sum S on G \\ b is the whole model's exact Schur complement, summed as the parts'
   blocks arrive into dense blocks between the cuts (sidprep.reduction.coarse_space.static_schur,
   sidprep.reduction.block_ldlt.CutBlocks); with a frequency limit, the whole model's count of
   fixed-interface modes below it comes first (Wittrick-Williams over the parts,
   sidprep.reduction.coarse_space.count_below);
2. the coarse space: b kept; every cut (the coarse DOFs shared by one set of parts) reduced to its
   lowest interface modes, eigenvectors of S and M on the cut (characteristic constraint modes;
   Castanier, Tan & Pierre 2001): u_G = R c (sidprep.reduction.coarse_space.coarse_space);
3. each part's Craig-Bampton on its coarse coordinates c_p (``reduce_part``, a task):
   u_I = Psi_p R_p c_p + Phi_p q_p, Psi_p = -K_II^-1 K_IB, one constraint mode per coordinate (not per
   coarse DOF), Phi_p its fixed-interface modes up to a cut-off; meanwhile S is factored (a block
   LDL^T, in core or out of core: sidprep.reduction.coarse_space.schur_factor);
4. the reduced parts assembled on [c, q_1 .. q_N] (``assemble_parts``) and a second Craig-Bampton of
   that assembly on b (``second_level``); parts whose modes stop below PART_CUTOFF x its highest
   fixed-interface frequency are reduced again (``reduce_parts_to_cutoff``);
5. every model DOF recovered from the parts with the whole model's EXACT constraint modes
   -K_ii^-1 K_ib, by substructuring (sidprep.reduction.substructured: part tasks around the solve
   with the factor of S; each part's K_II factor made once where it is held), which gives the same
   ReducedModel as ``craig_bampton`` (basis, K, M, boundary b) with an exact K_ii^-1 and a certified
   eigenvalue count over the parts, so the checks of sidprep.reduction.fe_checks hold against the full
   model unchanged;
6. the fixed-interface modes refined by one block inverse iteration with that exact K_ii^-1:
   Rayleigh-Ritz on span[X, K_ii^-1 M_ii X] (sidprep.reduction.substructured.refined_modes).

Craig & Bampton 1968; Hurty 1965 (component modes); Wittrick & Williams 1971 (eigenvalue count);
Bathe & Wilson 1972 (subspace iteration); Castanier, Tan & Pierre 2001 (characteristic constraint modes).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from sidprep.errors import InputError
from sidprep.fe.linalg import single_threaded_blas
from sidprep.progress import peak_memory_mb
from sidprep.reduction.coarse_space import CoarseSpace
from sidprep.reduction.craig_bampton import ReducedModel, craig_bampton
from sidprep.reduction.part_tasks import HeldPart, PartTaskRunner
from sidprep.reduction.partition import PartModel

#: the parts' fixed-interface modes reach this multiple of the highest fixed-interface frequency of
#: the second level (the component cut-off ratio that governs CMS accuracy): 1e-4 agreement with the
#: monolithic reduction on the piston rod (4 parts) and a bar (8 parts), tests/test_parts.py
PART_CUTOFF = 2.0
#: fewest fixed-interface modes of a part in the first round, which asks PART_FIRST_ROUND x
#: PART_CUTOFF^2 x (second-level modes / parts): a part of 1/N of the body has about 1/N of its modes
#: below a frequency, and about PART_CUTOFF^2 times as many below PART_CUTOFF x it (measured 2.4-4.4
#: on the piston rod and the bar); parts short of PART_CUTOFF x the top frequency run again (a second
#: round costs a whole part reduction, the margin less)
PART_MIN_MODES = 12
PART_FIRST_ROUND = 1.25
#: interface modes kept on every cut: INTERFACE_PER_MODE x the second level's fixed-interface modes
#: (n_modes, or the whole model's count below fmax), at least INTERFACE_MIN_MODES (tests/test_parts.py:
#: 1e-4 agreement with the monolithic reduction on the piston rod and the bar)
INTERFACE_PER_MODE = 2.0
INTERFACE_MIN_MODES = 24


def interface_count(wanted: int | None) -> int:
    """Interface modes kept on every cut for ``wanted`` second-level fixed-interface modes."""
    return max(INTERFACE_MIN_MODES, int(np.ceil(INTERFACE_PER_MODE * (wanted or 0))))



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
    """Step 3: Craig-Bampton of one part on its coarse coordinates (``with_coarse_coordinates``): n_modes
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


@dataclass(frozen=True)
class Assembly:
    """The reduced parts on [c, q_1, ..., q_N]: K, M (n_asm, n_asm) csr; space : the CoarseSpace of c;
    offsets : (N + 1,) start of each q_p."""

    K: sp.csr_matrix
    M: sp.csr_matrix
    space: CoarseSpace
    offsets: np.ndarray


def assemble_parts(reductions: list[PartReduction], space: CoarseSpace) -> Assembly:
    """Step 4: every part's reduced K, M summed into the coarse coordinates and its own modal ones."""
    offsets = space.R.shape[1] + np.cumsum([0] + [r.modes.shape[1] for r in reductions])
    index = [np.r_[space.columns(p), np.arange(offsets[p], offsets[p + 1])] for p in range(len(reductions))]
    n = int(offsets[-1])
    return Assembly(summed_blocks(index, [r.K for r in reductions], n), summed_blocks(index, [r.M for r in reductions], n),
                    space, offsets)


def second_level(assembly: Assembly, n_modes=None, fmax=None) -> ReducedModel:
    """Step 4: Craig-Bampton of the assembled parts on the monolithic boundary b (c's first coordinates)."""
    return craig_bampton(assembly.K, assembly.M, np.arange(assembly.space.n_boundary), n_modes=n_modes, fmax=fmax)


def reduce_parts_to_cutoff(parts: list[PartModel], space: CoarseSpace, tasks: PartTaskRunner,
                           memory: float | None = None, n_modes: int | None = None, fmax: float | None = None,
                           meanwhile=None) -> tuple[list[PartReduction], Assembly, ReducedModel]:
    """Steps 3 and 4: rounds of the parts' reductions (``reduce_part`` on ``tasks``, each within
    ``memory`` bytes) until every part's fixed-interface modes reach PART_CUTOFF x the second level's
    highest fixed-interface frequency (n_modes of them, or all below fmax Hz): the first round asks
    PART_CUTOFF x fmax, or a share of n_modes (PART_FIRST_ROUND, PART_MIN_MODES), and runs
    ``meanwhile()`` while its tasks run; the parts short of the cut-off run again.  Returns (the
    reductions in part order, their Assembly, the second level's ReducedModel)."""

    reductions: dict = {}

    def run_round(requests: dict, meanwhile=None) -> None:
        order = sorted(requests)
        done = tasks(reduce_part, {p: (space.part_map(p), *requests[p], memory) for p in order}, meanwhile=meanwhile)
        reductions.update(zip(order, done))

    if fmax is not None:
        first = {p: (None, PART_CUTOFF * fmax) for p in range(len(parts))}
    else:
        count = max(PART_MIN_MODES, int(np.ceil(PART_FIRST_ROUND * PART_CUTOFF ** 2 * n_modes / len(parts))))
        first = dict.fromkeys(range(len(parts)), (count, None))
    run_round(first, meanwhile)
    asked = {p: f for p, (_, f) in first.items() if f is not None}
    while True:
        ordered = [reductions[p] for p in range(len(parts))]
        assembly = assemble_parts(ordered, space)
        level2 = second_level(assembly, n_modes=n_modes, fmax=fmax)
        needed = PART_CUTOFF * float(level2.fixed_interface_hz.max(initial=0.0))
        short = [p for p in short_parts(ordered, parts, needed) if asked.get(p, 0.0) < needed]
        if not short:
            return ordered, assembly, level2
        asked.update(dict.fromkeys(short, needed))
        run_round(dict.fromkeys(short, (None, needed)))
