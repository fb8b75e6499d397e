"""A reduction in parts as tasks (``sidprep reduce MESH --parts N [--scheduler ADDRESS]``).

``reduce_in_parts`` is the driver: the flow of a run, top-down, in the steps of component mode
synthesis (sidprep.reduction.component_modes).  The mesh is partitioned and each part described
(sidprep.reduction.partition); every part's work runs as tasks on the executor of ``sidprep batch``
(sidprep.jobs.executor: a local process pool, or a Dask cluster) through ``PartTasks``, the
sidprep.reduction.part_tasks.PartTaskRunner of this package; the driver sums the coarse problem,
assembles, reduces the coarse DOFs and recovers the model.

* Memory: before any part starts, each part's largest task (its reduction, or its Schur task with the
  dense blocks on its coarse DOFs) is estimated (sidprep.reduction.part_tasks.part_peak_bytes) against
  one worker's memory; a part that does not fit is refused with the ``parts`` that would fit.
* Parts held where they are reduced: each part is pinned to one worker, which holds its matrices
  (sent once) and its K_II factor (made once) for the whole run (sidprep.jobs.held_parts); later
  tasks send right-hand sides only.
* Faults: a task whose worker is lost (killed, out of memory) is run again - its part sent and
  factored again - on the restarted slot (local pool) or another worker (Dask), up to PART_RETRIES
  times; then the run stops with one line naming the part.  A task that raises an error of its own
  on a living worker is not run again: the run stops with that error, naming the part (PartFailed).
  No result is assembled from a part that did not finish.
"""

from __future__ import annotations

import uuid
import weakref
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from typing import Any

import numpy as np

from sidprep.errors import InputError
from sidprep.fe.linalg import MEMORY_HEADROOM, available_memory_bytes
from sidprep.jobs.executor import Executor, task_pool
from sidprep.jobs.held_parts import NotHeld, PartFailed, held_task, release_run
from sidprep.reduction.coarse_space import coarse_space, coordinates_per_part, count_below, schur_factor, static_schur
from sidprep.reduction.component_modes import interface_count, reduce_parts_to_cutoff
from sidprep.reduction.craig_bampton import ReducedModel
from sidprep.reduction.part_tasks import PartArgs, PartTask, by_part, part_peak_bytes, task_peak_bytes
from sidprep.reduction.partition import PartModel, part_models, partition_cells
from sidprep.reduction.substructured import SubstructuredSolver, parts_reduced_model


#: times a part is run again after its worker was lost
PART_RETRIES = 2
#: seconds between checks, while part tasks run, for tasks pinned to a worker that is gone
SLOT_CHECK_S = 5.0
#: most parts suggested when a part does not fit a worker
MAX_SUGGESTED_PARTS = 4096
#: the share of the available memory a local pool leaves to its driver, beyond the model it holds
#: already: the coarse blocks (up to COARSE_IN_MEMORY_FRACTION of it; more goes out of core) and the
#: basis and solve vectors (at 1.02M DOF in 16 parts the driver grew ~6 GB past the model's ~3 GB)
LOCAL_DRIVER_SHARE = 0.35


class PartLost(RuntimeError):
    """A part's task failed PART_RETRIES + 1 times because its worker was lost."""


@dataclass(frozen=True)
class PartsSettings:
    """How a model is reduced in parts: ``n_parts`` parts, on the Dask cluster ``scheduler`` (its
    address or a dask.distributed Client) or a local pool of ``workers`` processes (default: cores)."""

    n_parts: int
    scheduler: object = None
    workers: int | None = None


def worker_memory_bytes(pool: Executor) -> float:
    """Memory one worker of ``pool`` may use: the smallest Dask worker
    memory limit times the fraction at which a Dask worker pauses (``dask_pause_fraction``), or the
    available memory (sidprep.fe.linalg.available_memory_bytes, SIDPREP_MEMORY_LIMIT) less
    LOCAL_DRIVER_SHARE of it, shared by the local workers."""

    limits = pool.worker_memory_limits()
    if limits is None:
        return (1.0 - LOCAL_DRIVER_SHARE) * available_memory_bytes() / max(pool.workers, 1)
    if limits and min(limits) > 0:
        return min(limits) * dask_pause_fraction()
    return available_memory_bytes()


def dask_pause_fraction() -> float:
    """The fraction of its memory limit at which a Dask worker stops starting tasks
    (``distributed.worker.memory.pause``, 0.8 by default; else ``terminate``, 0.95; else 1): the parts a
    worker holds must stay below it, or the worker pauses with them held and the run waits for ever."""
    import dask.config  # deferred: 1.5 s import, Dask only (loaded with the client already)

    for key in ("distributed.worker.memory.pause", "distributed.worker.memory.terminate"):
        fraction = dask.config.get(key, default=False)
        if fraction:
            return float(fraction)
    return 1.0


def check_parts_fit(parts, n_dof: int, memory: float, components: bool = False, coordinates=None) -> float:
    """InputError before any part starts when a part's estimated peak (``part_peak_bytes``, with its
    ``coordinates``, ``coordinates_per_part``, if known) exceeds ``memory`` (bytes, one worker), naming
    the ``parts`` that would fit (``components``: an assembly's, whose split is the user's).  Returns
    the resident bytes a worker may have when a task starts, the largest task's peak left beside it:
    the bound of the parts it holds (their matrices and K_II factors, sidprep.jobs.held_parts)."""

    coordinates = np.zeros(len(parts), dtype=np.int64) if coordinates is None else coordinates
    need = [part_peak_bytes(p, c) for p, c in zip(parts, coordinates)]
    worst = int(np.argmax(need))
    if need[worst] <= MEMORY_HEADROOM * memory:
        return MEMORY_HEADROOM * memory - need[worst]
    n = len(parts)
    size, n_coarse = len(parts[worst].dofs), len(parts[worst].boundary)
    fits = next((m for m in range(n + 1, MAX_SUGGESTED_PARTS + 1)            # a part's cuts shrink as a surface
                 if task_peak_bytes(size * n // m, int(n_coarse * (n / m) ** (2 / 3)),
                                    parts[worst].extent * (n / m) ** (1 / 3), coordinates[worst])
                 <= MEMORY_HEADROOM * memory), None)
    advice = f"use --parts {fits} or more (or workers with more memory)" if fits else "use workers with more memory"
    if components:
        advice = "split it into smaller components (or use workers with more memory)"
    gb = 1024.0 ** 3
    raise InputError(f"{'components' if components else 'parts'} = {n}: {parts[worst].name} ({size} of {n_dof} DOF) "
                     f"needs ~{need[worst] / gb:.2f} GB, a worker has {memory / gb:.2f} GB; {advice}")


def homes(parts, slots: list) -> list:
    """Each part's worker: the largest parts first, each to the slot holding the fewest DOFs."""
    load = dict.fromkeys(slots, 0)
    home = [None] * len(parts)
    for p in sorted(range(len(parts)), key=lambda p: -len(parts[p].dofs)):
        home[p] = min(slots, key=lambda s: load[s])
        load[home[p]] += len(parts[p].dofs)
    return home


class PartTasks:
    """The PartTaskRunner (sidprep.reduction.part_tasks) on an executor: each part pinned to one worker
    of one pool kept from the parts' reductions to the checks (the substructured solves and the
    certified count, sidprep.reduction.substructured.SubstructuredSolver, run after the driver
    returned).  A part's matrices are sent once, with its first task; its worker holds it and its
    K_II factor (``held_task``; its resident memory at a task's start bounded by ``budget`` bytes) so
    later tasks send right-hand sides only.  A part whose worker was lost (killed, out of memory) is
    sent again with its task, to the fresh process of its slot (or another Dask worker), up to
    PART_RETRIES times; then PartLost.  The pool is closed with ``close`` or when this object is garbage-collected."""

    def __init__(self, settings: PartsSettings, parts: list[PartModel]):
        self.settings, self.parts = settings, parts
        self.pool = task_pool(settings.scheduler, settings.workers)
        weakref.finalize(self, self.pool.close)
        self.run = uuid.uuid4().hex
        self.home = homes(parts, self.pool.slots)
        self.sent: set = set()
        self.sent_mb = 0.0
        self.budget = float("inf")

    def __call__(self, fn: PartTask, args: PartArgs, consume: Callable[[int, Any], None] | None = None,
                 meanwhile: Callable[[], None] | None = None) -> list | None:
        """The round (``PartTaskRunner``); ``meanwhile()`` runs once the tasks are handed out."""
        args = by_part(args)
        results: dict = {}
        lost = dict.fromkeys(args, 0)
        todo = list(args)
        while todo:
            running = {}
            pending, todo = todo, []
            for p in pending:
                try:
                    running[self.submit(p, fn, args[p])] = p
                except Exception as exc:                    # its slot broke while the tasks were handed out
                    self.lose(p, exc, lost)
                    todo.append(p)
            if meanwhile is not None:
                meanwhile()
                meanwhile = None
            while running:
                done = self.pool.wait(list(running), timeout=SLOT_CHECK_S)
                if not done:                                # Dask keeps a task pinned to a gone worker
                    self.resend_orphans(running, lost, todo)  # unrunnable when all workers died at once
                for fut in done:
                    p = running.pop(fut)
                    try:
                        result = fut.result()
                    except (InputError, PartLost, PartFailed):
                        raise
                    except NotHeld:                         # a fresh holder (a new worker): send the part again
                        self.sent.discard(p)
                        self.rehome(self.home[p])
                        todo.append(p)
                        continue
                    except Exception as exc:                # the worker died (killed, out of memory: no
                        self.lose(p, exc, lost)             # task error reaches here, ``held_task``)
                        todo.append(p)
                        continue
                    self.sent.add(p)
                    if consume is None:
                        results[p] = result
                    else:
                        consume(p, result)
        return None if consume is not None else [results[p] for p in args]

    def submit(self, p: int, fn: PartTask, args: tuple):
        """Part p's task on its worker, with the part's matrices unless the worker holds them."""
        part = None if p in self.sent else self.parts[p]
        if part is not None:
            self.sent_mb += sent_mb([part])
        return self.pool.run_on(self.home[p], held_task, (self.run, p), part, self.budget, fn, *args)

    def lose(self, p: int, exc: Exception, lost: dict) -> None:
        """Part p's worker was lost: its slot's parts are sent again (PartLost after PART_RETRIES)."""
        lost[p] += 1
        if lost[p] > PART_RETRIES:
            raise PartLost(f"{self.parts[p].name}: its worker was lost {lost[p]} times ({type(exc).__name__}); no SID "
                           "written - check the workers' memory and logs, or use more parts") from None
        slot = self.home[p]
        self.pool.renew(slot)
        for q, home in enumerate(self.home):
            if home == slot:
                self.sent.discard(q)
        self.rehome(slot)

    def rehome(self, slot) -> None:
        """The parts at ``slot`` to the workers alive, if it is gone (a Dask worker's restart gives
        it a new address)."""
        alive = self.pool.slots
        if slot not in alive and alive:
            for q, home in enumerate(self.home):
                if home == slot:
                    self.home[q] = alive[q % len(alive)]

    def resend_orphans(self, running: dict, lost: dict, todo: list) -> None:
        """Tasks of ``running`` (future -> part) pinned to a worker that is gone are cancelled and
        their parts lost (``lose``: re-homed, sent again with ``todo``)."""
        alive = set(self.pool.slots)
        orphans = [(fut, p) for fut, p in running.items() if self.home[p] not in alive]
        for fut, p in orphans:
            del running[fut]
            self.pool.stop([fut])
            self.lose(p, ConnectionError(f"worker {self.home[p]} gone"), lost)
            todo.append(p)

    def close(self) -> None:
        """Close the pool (its workers drop the parts they hold)."""
        try:
            self.pool.clear(release_run, self.run)
        finally:
            self.pool.close()


def sent_mb(items) -> float:
    """MiB of the arrays of PartModels (to the workers, their PartFE and materials included) or
    PartReductions (back), once each."""
    return sum(array_bytes(x) for x in items) / 2.0**20


def array_bytes(x) -> int:
    """Bytes of the numpy arrays in ``x``: an array, a sparse matrix, or an object holding them."""
    if isinstance(x, np.ndarray):
        return x.nbytes
    if hasattr(x, "indptr"):
        return x.data.nbytes + x.indices.nbytes + x.indptr.nbytes
    return sum(array_bytes(v) for v in vars(x).values()) if hasattr(x, "__dict__") else 0


@dataclass(frozen=True)
class PartsRun:
    """What a reduction in parts is given beside the model: the ``mesh``; ``material``, one Material or
    one per part (an assembly's components: a Material or GivenMatrices each); ``labels`` (ne,), the part
    of every cell; ``names``, one per part (an assembly's components, sidprep.jobs.assembly; None: a
    METIS partition's "part k/N"); ``settings``; ``notes``, a list that gets one line on the parts."""

    mesh: object
    material: object
    labels: np.ndarray
    names: list | None
    settings: PartsSettings
    notes: list | None = None


def parts_reducer(mesh, material, settings: PartsSettings, notes: list | None = None,
                  components=None) -> Callable[..., ReducedModel]:
    """The Craig-Bampton step of sidprep.jobs.reduce.reduce_body done in parts (``reduce_in_parts``): a
    function (im, K_model, M_model, boundary, n_modes=, fmax=) -> ReducedModel.  ``components`` :
    (labels (ne,), names) of an assembly's components as the parts, ``material`` then one per
    component; default a METIS partition into ``settings.n_parts``."""
    labels, names = components if components is not None else (partition_cells(mesh.cells, settings.n_parts), None)
    return partial(reduce_in_parts, PartsRun(mesh, material, labels, names, settings, notes))


def reduce_in_parts(run: PartsRun, im, K_model, M_model, boundary, n_modes=None, fmax=None) -> ReducedModel:
    """The driver: K_model, M_model (model DOFs after the interfaces ``im``) reduced on ``boundary`` with
    n_modes fixed-interface modes, or all below fmax Hz, as sidprep.reduction.craig_bampton.craig_bampton
    reduces them in one piece - in the steps of sidprep.reduction.component_modes, every part's work a
    task where the part is held.  The ReducedModel's factor is the substructured solver, whose tasks
    keep their pool (``interior_factor.tasks.close()``, or when it is freed)."""

    components = run.names is not None
    parts, coarse = part_models(run.mesh, run.material, run.labels, im, boundary, run.names)
    tasks = PartTasks(run.settings, parts)
    try:
        memory = worker_memory_bytes(tasks.pool)          # every part's largest task against one worker
        wanted = n_modes
        if fmax is not None:                              # the whole model's fixed-interface modes below fmax
            tasks.budget = check_parts_fit(parts, run.mesh.n_dof, memory, components)
            wanted = count_below(parts, coarse, boundary, (2 * np.pi * fmax) ** 2, tasks)
        tasks.budget = check_parts_fit(parts, run.mesh.n_dof, memory, components,
                                       coordinates_per_part(parts, coarse, boundary, interface_count(wanted)))
        S = static_schur(parts, coarse, boundary, tasks)                                          # step 1
        space = coarse_space(parts, coarse, boundary, S, M_model, interface_count(wanted))        # step 2
        factor = []                                                                               # steps 3, 4:
        reductions, assembly, level2 = reduce_parts_to_cutoff(parts, space, tasks, memory, n_modes, fmax,
                                                               meanwhile=lambda: factor.append(schur_factor(S)))
    except BaseException:
        tasks.close()
        raise
    if run.notes is not None:
        run.notes.append(parts_note(parts, len(coarse), assembly, reductions, tasks.sent_mb, components))
    solver = SubstructuredSolver(parts, reductions, assembly, boundary, K_model.shape[0], factor[0], tasks)
    return parts_reduced_model(K_model, M_model, solver, level2)    # steps 5, 6 (the parts' modes freed)


def parts_note(parts, n_coarse: int, assembly, reductions, sent: float, components: bool) -> str:
    """The line on a reduction in parts: sizes, coarse DOFs and coordinates, modes, the workers' peak
    memory and the MiB sent (``sent``) and returned."""
    return (f"reduced in {len(parts)} {'components' if components else 'parts'} of "
            f"{min(len(p.dofs) for p in parts)}-{max(len(p.dofs) for p in parts)} DOF, {n_coarse} coarse DOF in "
            f"{assembly.space.R.shape[1]} coordinates, {sum(len(r.frequencies_hz) for r in reductions)} part modes up "
            f"to {min(r.top_hz for r in reductions):.4g}-{max(r.top_hz for r in reductions):.4g} Hz; worker peak "
            f"{max(r.peak_memory_mb for r in reductions):.0f} MiB; {sent:.0f} MiB of parts sent to the workers, "
            f"{sent_mb(reductions):.0f} MiB back")
