"""A reduction in parts as tasks (``sidprep reduce MESH --parts N [--scheduler ADDRESS]``).

The mesh is partitioned, every part's Craig-Bampton reduction runs as a task on the executor of
``sidprep batch`` (sidprep.jobs.executor.task_pool: a local process pool, or a Dask cluster), and the
driver assembles, reduces the coarse DOFs and recovers the model (sidprep.reduction.parts).

* Memory: before any part starts, each part's largest task (its reduction, or its Schur task with the
  dense blocks on its coarse DOFs) is estimated (sidprep.reduction.parts.part_peak_bytes) against one
  worker's memory; a part that does not fit is refused with the ``parts`` that would fit.
* Parts held where they are reduced (``PartTasks``): each part is pinned to one worker, which holds
  its matrices (sent once) and its K_II factor (made once) for the whole run; later tasks send
  right-hand sides only.
* Faults: a task whose worker is lost (killed, out of memory) is run again - its part sent and
  factored again - on the restarted slot (local pool) or another worker (Dask), up to PART_RETRIES
  times; then the run stops with one line naming the part.  A task that raises an error of its own
  on a living worker is not run again: the run stops with that error, naming the part (PartFailed).
  No result is assembled from a part that did not finish.
"""

from __future__ import annotations

import threading
import uuid
import weakref
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np

from sidprep.errors import InputError
from sidprep.fe.linalg import MEMORY_HEADROOM, available_memory_bytes
from sidprep.jobs.executor import task_pool
from sidprep.progress import resident_memory_bytes, return_freed_memory
from sidprep.reduction.parts import (PART_CUTOFF, HeldPart, assemble_parts, coarse_space, coordinates_per_part,
    count_below, part_models, part_peak_bytes, partition_cells, parts_reduced_model, reduce_part,
    schur_factor, second_level, short_parts, static_schur, task_peak_bytes)


#: times a part is run again after its worker was lost
PART_RETRIES = 2
#: seconds between checks, while part tasks run, for tasks pinned to a worker that is gone
SLOT_CHECK_S = 5.0
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
#: most parts suggested when a part does not fit a worker
MAX_SUGGESTED_PARTS = 4096
#: the share of the available memory a local pool leaves to its driver, beyond the model it holds
#: already: the coarse blocks (up to COARSE_IN_MEMORY_FRACTION of it; more goes out of core) and the
#: basis and solve vectors (at 1.02M DOF in 16 parts the driver grew ~6 GB past the model's ~3 GB)
LOCAL_DRIVER_SHARE = 0.35


class PartLost(RuntimeError):
    """A part's task failed PART_RETRIES + 1 times because its worker was lost."""


class PartFailed(RuntimeError):
    """A part's task raised an error of its own (its worker lives): not run again."""


@dataclass(frozen=True)
class PartsSettings:
    """How a model is reduced in parts: ``n_parts`` parts, on the Dask cluster ``scheduler`` (its
    address or a dask.distributed Client) or a local pool of ``workers`` processes (default: cores)."""

    n_parts: int
    scheduler: object = None
    workers: int | None = None


def worker_memory_bytes(pool) -> float:
    """Memory one worker may use: the smallest Dask worker memory limit times the fraction at which a
    Dask worker pauses (``dask_pause_fraction``), or the available memory
    (sidprep.fe.linalg.available_memory_bytes, SIDPREP_MEMORY_LIMIT) less LOCAL_DRIVER_SHARE of it,
    shared by the local workers."""

    client = getattr(pool, "client", None)
    if client is not None:
        limits = [w.get("memory_limit") or 0 for w in client.scheduler_info()["workers"].values()]
        if limits and min(limits) > 0:
            return float(min(limits)) * dask_pause_fraction()
        return available_memory_bytes()
    return (1.0 - LOCAL_DRIVER_SHARE) * available_memory_bytes() / max(pool.workers, 1)


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
    the bound of the parts it holds (their matrices and K_II factors, ``held_part``)."""

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


class NotHeld(LookupError):
    """A part task reached a worker that does not hold the part (a new one): send it again."""


#: per worker process: (run id, part index) -> HeldPart, least recently used first; its lock (a Dask
#: worker runs tasks in threads)
_HELD: OrderedDict = OrderedDict()
_HELD_LOCK = threading.Lock()


def held_task(key: tuple, part, budget: float, fn, *args):
    """``fn(HeldPart, *args)`` in a worker with the part ``key`` it holds (``held_part``).  An error of
    the task's own (the part's assembly included) is PartFailed, naming the part: it is not retried."""
    held = None
    try:
        held = held_part(key, part, budget)
        return fn(held, *args)
    except (InputError, MemoryError, NotHeld):             # the user's error; out of memory: the worker's
        raise
    except Exception as exc:                               # the task's own error: the same again on a retry
        name = (held.description if held is not None else part).name
        raise PartFailed(f"{name}: {fn.__name__} failed: {type(exc).__name__}: {exc}") from None
    finally:                                               # the task's temporaries, not kept as heap; the
        release_others(key, budget)                        # worker idles within its budget, as it starts


def held_part(key: tuple, part, budget: float) -> HeldPart:
    """The HeldPart ``key`` this worker holds; ``part`` (a PartModel, or None when the worker should
    hold it already: NotHeld otherwise) is held from now on.  While the worker's resident memory
    (``resident_memory_bytes``, its freed heap returned first) exceeds ``budget`` - what it may hold
    when a task starts, the task's own peak left beside it (``check_parts_fit``) - the most recently
    used other part whose matrices or factor are held is released (``HeldPart.release``): measured,
    not estimated, since a worker also holds its interpreter and what its transfers left (a 2.4M-DOF
    run's 5 GB workers sat at 3.4 GB between tasks with 2 GB of parts estimated held, and a count
    task on top of that stopped them).  The tasks of a round visit a worker's parts in the same order
    every round, so the part just used is the one needed last (least recently used first would
    release each part just before its next task).  Its task assembles the part, outside the lock, so
    a worker's threads assemble parts side by side."""
    with _HELD_LOCK:
        held = _HELD.get(key)
        if held is None:
            if part is None:
                raise NotHeld(key)
            held = _HELD[key] = HeldPart(part)
        _HELD.move_to_end(key)
    release_others(key, budget)
    return held


def release_others(key: tuple, budget: float) -> None:
    """Give the freed heap back, then release the most recently used held part other than ``key``
    while the worker's resident memory exceeds ``budget`` (``held_part``)."""
    with _HELD_LOCK:
        others = [h for k, h in _HELD.items() if k != key and h.holds]
        return_freed_memory()
        while others and resident_memory_bytes() > budget:
            others.pop().release()
            return_freed_memory()


def release_run(run: str) -> None:
    """Drop every part of the run ``run`` this worker holds."""
    with _HELD_LOCK:
        for key in [k for k in _HELD if k[0] == run]:
            del _HELD[key]


def homes(parts, slots: list) -> list:
    """Each part's worker: the largest parts first, each to the slot holding the fewest DOFs."""
    load = dict.fromkeys(slots, 0)
    home = [None] * len(parts)
    for p in sorted(range(len(parts)), key=lambda p: -len(parts[p].dofs)):
        home[p] = min(slots, key=lambda s: load[s])
        load[home[p]] += len(parts[p].dofs)
    return home


class PartTasks:
    """fn, [args per part] -> [fn(HeldPart of part p, *args[p]) per part] as tasks, each part pinned to
    one worker of one pool kept from the parts' reductions to the checks (the substructured solves
    and the certified count, sidprep.reduction.parts.SubstructuredSolver, run after the reducer
    returned).  A part's matrices are sent once, with its first task; its worker holds it and its
    K_II factor (``held_task``; its resident memory at a task's start bounded by ``budget`` bytes) so
    later tasks send right-hand sides only.  A part whose worker was lost (killed, out of memory) is
    sent again with its task, to the fresh process of its slot (or another Dask worker), up to
    PART_RETRIES times; then PartLost.  The pool is closed with ``close`` or when this object is garbage-collected."""

    def __init__(self, settings: PartsSettings, parts):
        self.settings, self.parts = settings, parts
        self.pool = task_pool(settings.scheduler, settings.workers, pinned=True)
        weakref.finalize(self, self.pool.close)
        self.run = uuid.uuid4().hex
        self.home = homes(parts, self.pool.slots)
        self.sent: set = set()
        self.sent_mb = 0.0
        self.budget = float("inf")

    def __call__(self, fn, args, consume=None, meanwhile=None) -> list | None:
        """``args``: a list (every part) or {part index: args} (those parts; results in its order).  With
        ``consume``: consume(p, result) as each part's result arrives (none kept), and None.
        ``meanwhile()``: the driver's own work, run once the tasks are handed out (while they run)."""
        args = args if isinstance(args, dict) else dict(enumerate(args))
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

    def submit(self, p: int, fn, args: tuple):
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


def reduce_parts(tasks: PartTasks, parts, coarse, boundary, M_model, memory, n_modes=None, fmax=None,
                 components: bool = False):
    """The coarse space from the parts' exact static Schur complements (one round of tasks), then rounds
    of part reductions until every part's modes reach PART_CUTOFF x the second level's highest
    fixed-interface frequency; returns (reductions in part order, Assembly, second-level ReducedModel,
    the factor of the exact coarse Schur complement).  With ``fmax``, the parts' reductions are checked
    against ``memory`` (``check_parts_fit``, ``components``) once the count gives their coordinates."""

    wanted = n_modes
    if fmax is not None:                                # the whole model's fixed-interface modes below fmax
        wanted = count_below(parts, coarse, boundary, (2 * np.pi * fmax) ** 2, tasks)
        tasks.budget = check_parts_fit(parts, M_model.shape[0], memory, components,
                                       coordinates_per_part(parts, coarse, boundary, interface_count(wanted)))
    schur = [static_schur(parts, coarse, boundary, tasks)]
    space = coarse_space(parts, coarse, boundary, schur[0], M_model, interface_count(wanted))
    factor: list = []

    def factor_schur() -> None:
        """The coarse Schur complement factored (and dropped) while the first reductions run."""
        factor.append(schur_factor(schur.pop()))

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
    run_round(first, factor_schur)
    asked = {p: f for p, (_, f) in first.items() if f is not None}
    while True:
        ordered = [reductions[p] for p in range(len(parts))]
        assembly = assemble_parts(ordered, space)
        level2 = second_level(assembly, n_modes=n_modes, fmax=fmax)
        needed = PART_CUTOFF * float(level2.fixed_interface_hz.max(initial=0.0))
        short = [p for p in short_parts(ordered, parts, needed) if asked.get(p, 0.0) < needed]
        if not short:
            break
        asked.update(dict.fromkeys(short, needed))
        run_round(dict.fromkeys(short, (None, needed)))
    return ordered, assembly, level2, factor[0]


def interface_count(wanted: int | None) -> int:
    """Interface modes kept on every cut for ``wanted`` second-level fixed-interface modes."""
    return max(INTERFACE_MIN_MODES, int(np.ceil(INTERFACE_PER_MODE * (wanted or 0))))


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


def parts_reducer(mesh, material, settings: PartsSettings, notes: list | None = None, components=None):
    """The Craig-Bampton step of sidprep.jobs.reduce.reduce_body done in parts: a function
    (im, K_model, M_model, boundary, n_modes=, fmax=) -> ReducedModel; ``notes`` gets one line on
    the parts (sizes, modes, peak memory of the workers).  ``components`` : (labels (ne,), names) of
    an assembly's components (sidprep.jobs.assembly) as the parts, ``material`` then one per
    component; default a METIS partition into ``settings.n_parts``."""

    labels, names = components if components is not None else (partition_cells(mesh.cells, settings.n_parts), None)

    def reducer(im, K_model, M_model, boundary, n_modes=None, fmax=None):

        parts, coarse = part_models(mesh, material, labels, im, boundary, names)
        tasks = PartTasks(settings, parts)
        try:
            memory = worker_memory_bytes(tasks.pool)
            coordinates = None if n_modes is None else coordinates_per_part(parts, coarse, boundary,
                                                                               interface_count(n_modes))
            tasks.budget = check_parts_fit(parts, mesh.n_dof, memory, names is not None, coordinates)
            ordered, assembly, level2, coarse_factor = reduce_parts(tasks, parts, coarse, boundary, M_model, memory,
                                                                    n_modes, fmax, names is not None)
        except BaseException:
            tasks.close()
            raise
        if notes is not None:
            notes.append(f"reduced in {len(parts)} {'components' if names else 'parts'} of "
                         f"{min(len(p.dofs) for p in parts)}-"
                         f"{max(len(p.dofs) for p in parts)} DOF, {len(coarse)} coarse DOF in {assembly.space.R.shape[1]} "
                         f"coordinates, "
                         f"{sum(len(r.frequencies_hz) for r in ordered)} part modes up to "
                         f"{min(r.top_hz for r in ordered):.4g}-{max(r.top_hz for r in ordered):.4g} Hz; "
                         f"worker peak {max(r.peak_memory_mb for r in ordered):.0f} MiB; "
                         f"{tasks.sent_mb:.0f} MiB of parts sent to the workers, {sent_mb(ordered):.0f} MiB back")
        return parts_reduced_model(K_model, M_model, boundary, parts, ordered, assembly, level2, coarse_factor,
                                   tasks)                 # empties ``ordered``: the parts' modes are freed

    return reducer
