"""What runs where a part is held: the part tasks of component mode synthesis and how they are run.

A part task is a function fn(held, *args) of a ``HeldPart`` - the part's description, its matrices
assembled where it is held and the factor of its K_II (its own DOFs), made once there - and of
right-hand sides, so that only those travel after the part's first task.  ``PartTaskRunner`` is the
one contract of whatever runs them: ``InProcess`` here, or sidprep.jobs.parts.PartTasks on the
workers of a local pool or a Dask cluster.  The tasks: the part's exact dynamic Schur complement
with its inertia (``part_dynamic_schur``), its share of the coarse right-hand side of a substructured
solve (``part_coarse_load``), its own DOFs given its coarse ones (``part_interior_solve``), and its
Craig-Bampton reduction (sidprep.reduction.component_modes.reduce_part); ``part_peak_bytes`` bounds
the largest one's memory before any starts.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any, Protocol

import numpy as np

from sidprep.fe.linalg import estimate_peak_memory, factorize, single_threaded_blas
from sidprep.fe.pardiso import Inertia, ldlt_inertia
from sidprep.reduction.craig_bampton import reduction_peak_bytes
from sidprep.reduction.partition import PartModel, assembled

#: dense (nb_p, nb_p) arrays alive at the peak of a part's Schur task (``part_dynamic_schur``): PARDISO's
#: Schur block, the x it is returned in, and its workspace - measured 2.6 (peak RSS over the same
#: LDL^T without the Schur rows: +423 MiB for nb_p = 4581 on a 94k-DOF part of the 2.4M bar in 24)
SCHUR_DENSE_COPIES = 3
#: (n_p, n_coordinates) arrays alive at the peak of a part's reduction beyond ``reduction_peak_bytes``
#: (the basis's constraint modes, the coupling of K and M to the coordinates): measured 1.6 between two
#: parts of the 475k bar in 8 (186 and 360 coordinates, ~60k DOF each: 708 and 839 MiB peak RSS)
COORDINATE_COPIES = 2

#: a part task: fn(HeldPart, *args) -> its result
PartTask = Callable[..., Any]
#: the arguments of a round of part tasks: one tuple per part (every part, in order), or
#: {part index: tuple} (those parts; their results in its order)
PartArgs = Sequence[tuple] | Mapping[int, tuple]


class PartTaskRunner(Protocol):
    """Runs a round of part tasks: fn(HeldPart of part p, *args[p]) for the parts of ``args``, each part
    where it is held (its matrices and K_II factor kept across rounds).  Without ``consume`` it returns
    the results in the order of ``args``; with it, consume(p, result) as each part's result arrives
    (none kept) and None.  ``meanwhile()``: the driver's own work, run once while the tasks run."""

    def __call__(self, fn: PartTask, args: PartArgs, consume: Callable[[int, Any], None] | None = None,
                 meanwhile: Callable[[], None] | None = None) -> list | None: ...


def by_part(args: PartArgs) -> dict[int, tuple]:
    """{part index: its task's arguments} of a round's ``args`` (``PartTaskRunner``)."""
    return dict(args) if isinstance(args, Mapping) else dict(enumerate(args))


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

class InProcess:
    """The ``PartTaskRunner`` without an executor: the tasks run here, one after the other, each part's
    HeldPart kept across rounds (its K_II factored once); ``meanwhile()`` runs first."""

    def __init__(self, parts: Sequence[PartModel]):
        self.held = [HeldPart(part) for part in parts]

    def __call__(self, fn: PartTask, args: PartArgs, consume: Callable[[int, Any], None] | None = None,
                 meanwhile: Callable[[], None] | None = None) -> list | None:
        if meanwhile is not None:
            meanwhile()
        results = []
        for p, a in by_part(args).items():
            result = fn(self.held[p], *a)
            if consume is None:
                results.append(result)
            else:
                consume(p, result)
        return None if consume is not None else results


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

