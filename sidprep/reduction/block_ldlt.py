"""A block LDL^T of a symmetric matrix held as dense blocks between groups of positions, in memory or
out of core: the coarse problem of component mode synthesis (the exact Schur complement of the whole
model on the cuts between parts, sidprep.reduction.coarse_space).

``CutBlocks`` sums the parts' dense Schur complements as they arrive, block (i, j) between two groups
(cuts) that a part joins, and eliminates group after group, fewest neighbours first (Bunch-Kaufman
pivots of each diagonal block, scipy.linalg.ldl; level-3 updates of its neighbours): the negative
pivots count the matrix's negative eigenvalues (Sylvester's law; Haynsworth's inertia additivity over
the groups), and the steps kept make a solver (``CutFactor``).  Blocks larger than
COARSE_IN_MEMORY_FRACTION of the available memory live in memory-mapped temporary files with their
disk blocks reserved first (``disk_zeros``, ``posix_fallocate``): a full disk is an InputError before
anything is written, not a SIGBUS.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from sidprep.errors import InputError
from sidprep.fe.linalg import available_memory_bytes, single_threaded_blas

#: the coarse blocks and their factor stay in memory up to this fraction of the memory available as
#: their round starts; larger ones go to memory-mapped files (``disk_zeros``): the
#: driver's basis and solve vectors come later (at 2.4M DOF in 16 parts, ~4.4 GB of blocks stayed in
#: memory at 0.25, beside the model's ~5 GB and 0.58 GB per 30 columns of model-size vectors)
COARSE_IN_MEMORY_FRACTION = 0.1


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


