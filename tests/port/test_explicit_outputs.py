"""The compiled core's explicit integrators, sample outputs and out-of-plane reactions
(sidprep/solver/core/explicit.pyx, outputs.pyx, planar.pyx) against the numba kernels they replace
(sidprep/solver/integrators/explicit.py, outputs.py, planar.py): the same results to round-off."""

import numpy as np
import pytest

from sidprep.solver.core import planar as core_planar
from sidprep.solver.integrators import planar as numba_planar

#: kernel against kernel, the same arithmetic in the same order: relative to the largest entry
KERNEL_RTOL = 1e-12


def rank_deficient(rng, no, nd, rank, dependent_on):
    """(no, nd) of the given rank: rows >= rank are combinations of the rows dependent_on."""
    u, _ = np.linalg.qr(rng.standard_normal((nd, rank)))
    head = rng.uniform(0.4, 2.0, (rank, 1)) * u.T
    tail = rng.standard_normal((no - rank, len(dependent_on))) @ head[dependent_on] / len(dependent_on)
    return np.ascontiguousarray(np.vstack([head, tail]))


def core_independent_equations(a):
    rows = np.zeros(min(a.shape), np.int64)
    return rows[:core_planar.independent_equations(np.ascontiguousarray(a), rows)]


def core_minimum_norm_solution(a, load, rows):
    no, nd = a.shape
    x = np.zeros(nd)
    core_planar.minimum_norm_solution(np.ascontiguousarray(a), load, rows, np.zeros((no, no)), np.zeros(no), x)
    return x


def close(x, ref, rtol=KERNEL_RTOL):
    return np.max(np.abs(x - ref), initial=0.0) <= rtol * max(np.max(np.abs(ref), initial=0.0), 1e-300)


@pytest.mark.parametrize("no, nd, rank", [(9, 9, 9), (9, 12, 9), (9, 12, 6), (12, 9, 9), (12, 9, 5), (3, 2, 1)])
def test_out_of_plane_solution_matches_numba(no, nd, rank):
    """independent_equations picks the same rows; minimum_norm_solution gives the same reactions
    on later matrices of the pattern, and where the rank fell or grew (its lstsq fallback)."""
    rng = np.random.default_rng(no * 100 + nd * 10 + rank)
    deps = list(range(min(rank, 3)))
    first = rank_deficient(rng, no, nd, rank, deps)
    rows = core_independent_equations(first)
    np.testing.assert_array_equal(rows, numba_planar.independent_equations(first))
    others = [rank_deficient(rng, no, nd, rank, deps) for _ in range(3)]
    if rank > 1:
        others.append(rank_deficient(rng, no, nd, rank - 1, deps[:1]))
    if rank < min(no, nd):
        others.append(rank_deficient(rng, no, nd, rank + 1, deps[:1]))
    for a in others:
        load = a @ rng.standard_normal(nd)
        ref = numba_planar.minimum_norm_solution(a, load, rows)
        assert close(core_minimum_norm_solution(a, load, rows), ref)
        x = np.zeros(nd)
        core_planar.lstsq(a, load, x)
        assert close(x, numba_planar.lstsq(a, load))
        assert core_planar.solves(a, ref, load) == numba_planar.solves(a, ref, load)
