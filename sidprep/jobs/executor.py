"""Where tasks run: a local process pool or a Dask cluster behind one contract (``Executor``) - the
executor of ``sidprep batch`` (sidprep.jobs.batch) and of reductions in parts (sidprep.jobs.parts).

A task is a top-level function and its picklable arguments.  ``submit`` runs it on any worker,
``run_on`` on one worker (a slot: what a task leaves in that worker's process is found by the next
task sent there; sidprep.jobs.parts keeps parts so), ``wait`` returns the futures done, ``renew``
starts a slot whose worker died afresh, ``stop`` stops the running tasks now (^C, SIGTERM), ``clear``
drops what tasks left on workers that outlive ``close``.  A worker that dies (killed, out of memory)
fails its task's future with an error of its own; the other workers go on.
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Callable, Iterable
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Any, Protocol

from sidprep.errors import InputError
from sidprep.jobs.guard import STOP_GRACE_S, guarded, stop_workers, worker_setup

#: seconds to wait for a Dask scheduler before giving up
DASK_CONNECT_S = 10
#: an array argument of a pinned Dask task above this many bytes is scattered to its worker first
SCATTER_BYTES = 2**20


#: every thread pool of a worker process at one thread, set before numpy, MKL or OpenBLAS load (a
#: limit set after the import does not reach OpenMP): with N jobs on N cores more threads only
#: contend (1.58x -> 1.77x over one by one on 2 cores)
SINGLE_THREAD_ENV = {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
                     "VECLIB_MAXIMUM_THREADS": "1"}


class Executor(Protocol):
    """The contract of the local pool (``LocalPool``) and of a Dask cluster (``DaskPool``).

    workers : how many tasks run at once; slots : the workers a task can be sent to (``run_on``).  A
    task's future is a concurrent.futures.Future, or Dask's, which has the same ``result``.
    """

    workers: int

    @property
    def slots(self) -> list: ...

    def submit(self, fn: Callable, *args: Any) -> Future:
        """``fn(*args)`` on any worker."""

    def run_on(self, slot, fn: Callable, *args: Any) -> Future:
        """``fn(*args)`` on the worker ``slot``."""

    def wait(self, futures: Iterable[Future], timeout: float | None = None) -> set:
        """The futures done: at least one, or none after ``timeout`` seconds."""

    def renew(self, slot) -> bool:
        """Whether ``slot``'s worker had died (a fresh one takes its place)."""

    def worker_memory_limits(self) -> list[float] | None:
        """Each worker's memory limit in bytes (0: none set), or None when the workers share this
        machine's memory with the driver (a local pool)."""

    def clear(self, fn: Callable, *args: Any) -> None:
        """``fn(*args)`` on every worker that outlives ``close`` (to drop what the tasks left there)."""

    def stop(self, futures: Iterable[Future]) -> None:
        """Stop the running ``futures`` now (the local pool ends its workers: SIGTERM, then SIGKILL)."""

    def close(self) -> None:
        """Release the workers."""


def wait_first(futures, timeout=None) -> set:
    """The concurrent futures done: at least one, or none after ``timeout`` seconds."""
    return wait(futures, timeout=timeout, return_when=FIRST_COMPLETED).done


def worker_start(parent_pid: int) -> None:
    """Initializer of every local worker, run before the task's modules are imported (this module
    imports no numerical library): the thread limits, then the batch's hold on the worker
    (sidprep.jobs.guard.worker_setup: ^C is the parent's, SIGTERM unwinds, no worker outlives it)."""
    os.environ.update(SINGLE_THREAD_ENV)
    worker_setup(parent_pid)


def died(future: Future) -> bool:
    """Whether ``future`` failed because its worker process died."""
    return future.done() and not future.cancelled() and isinstance(future.exception(), BrokenProcessPool)


class WorkerSlot:
    """One worker process of the local pool: a single-process ProcessPoolExecutor, spawned as a child
    of this process (with forkserver a SIGKILL of the batch left the server and workers blocked on
    pipes whose write ends leaked into their siblings, sidprep.jobs.guard).  Its first task reports the
    worker's process id (``process``); it has died when a task of it failed with BrokenProcessPool
    (``dead``)."""

    def __init__(self):
        self.executor = ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn"),
                                            initializer=worker_start, initargs=(os.getpid(),))
        self.pid = self.executor.submit(os.getpid)
        self.futures: list[Future] = []
        self.lost = False

    def submit(self, fn, *args) -> Future:
        """``fn(*args)`` in this worker (guarded: SIGTERM unwinds it, sidprep.jobs.guard.guarded)."""
        self.futures = [f for f in self.futures if not f.done() or died(f)]
        try:
            future = self.executor.submit(guarded, fn, *args)
        except BrokenProcessPool:
            self.lost = True
            raise
        self.futures.append(future)
        return future

    @property
    def busy(self) -> int:
        """Tasks sent here and not done."""
        return sum(not f.done() for f in self.futures)

    @property
    def dead(self) -> bool:
        """Whether the worker process died: a task of it failed with BrokenProcessPool, or its process,
        once started, is gone (its executor refuses tasks from then on)."""
        self.lost = self.lost or any(died(f) for f in [self.pid, *self.futures]) or \
            (self.pid.done() and self.process() is None)
        return self.lost

    def process(self, timeout: float = 0.0):
        """The worker's multiprocessing.Process while it runs (None once it has ended), its process id
        awaited up to ``timeout`` seconds."""
        wait([self.pid], timeout=timeout)
        if not self.pid.done() or self.pid.cancelled() or self.pid.exception() is not None:
            return None
        return next((p for p in multiprocessing.active_children() if p.pid == self.pid.result()), None)

    def close(self) -> None:
        """Shut the executor down; after the worker's death without waiting (the executor's internals
        can hang on the dead pipes, seen in CPython 3.11's terminate_broken)."""
        if self.dead:
            self.executor.shutdown(wait=False, cancel_futures=True)
        else:
            self.executor.shutdown(wait=True, cancel_futures=True)


class LocalPool:
    """The ``Executor`` on this machine: ``workers`` spawned worker processes, one per slot
    (``WorkerSlot``); ``submit`` sends a task to the slot with the fewest running (a dead one started
    afresh first)."""

    def __init__(self, workers: int):
        self.pool = [WorkerSlot() for _ in range(workers)]
        self.workers = workers

    @property
    def slots(self) -> list:
        return list(range(self.workers))

    def submit(self, fn, *args) -> Future:
        slot = min(self.slots, key=lambda s: self.pool[s].busy)
        self.renew(slot)
        return self.run_on(slot, fn, *args)

    def run_on(self, slot, fn, *args) -> Future:
        return self.pool[slot].submit(fn, *args)

    def wait(self, futures, timeout=None) -> set:
        return wait_first(futures, timeout)

    def renew(self, slot) -> bool:
        if not self.pool[slot].dead:
            return False
        self.pool[slot].close()
        self.pool[slot] = WorkerSlot()
        return True

    def worker_memory_limits(self) -> None:
        return None

    def clear(self, fn, *args) -> None:
        """Nothing: what a task left in a worker's process ends with it (``close``)."""

    def stop(self, futures) -> None:
        """SIGTERM to every worker, SIGKILL after STOP_GRACE_S (sidprep.jobs.guard.stop_workers)."""
        processes = [slot.process(timeout=STOP_GRACE_S) for slot in self.pool]
        stop_workers([p for p in processes if p is not None])

    def close(self) -> None:
        while self.pool:
            self.pool.pop().close()


class DaskPool:
    """The ``Executor`` on a dask.distributed cluster (``address`` of its scheduler, or a Client)."""

    def __init__(self, address, workers: int | None):
        try:
            from distributed import Client  # deferred: 1.5 s import, Dask only
        except ImportError:
            raise InputError("scheduler: dask.distributed is not installed; pip install distributed") from None
        try:
            self.client = address if hasattr(address, "submit") else Client(address, timeout=DASK_CONNECT_S)
        except (OSError, TimeoutError) as exc:
            raise InputError(f"scheduler {address}: cannot connect ({exc}); check the address and that the "
                             "scheduler runs") from None
        self.own = not hasattr(address, "submit")
        info = self.client.scheduler_info()["workers"].values()
        self.workers = workers or max(sum(w.get("nthreads", 1) for w in info), 1)

    @property
    def slots(self) -> list:
        """The workers' addresses (those alive now)."""
        return sorted(self.client.scheduler_info()["workers"])

    def submit(self, fn, *args):
        return self.client.submit(fn, *args, pure=False)

    def run_on(self, slot, fn, *args):
        """A task on the worker ``slot`` (its address) while it lives; on another when it is gone.  Its
        array arguments above SCATTER_BYTES are scattered to that worker first, so that the scheduler
        holds no copy of them in the task (at 2.4M DOF in parts, 3.8 GB in the scheduler's process)."""
        args = [self.client.scatter(a, workers=[slot], hash=False) if getattr(a, "nbytes", 0) > SCATTER_BYTES else a
                for a in args]
        return self.client.submit(fn, *args, pure=False, workers=[slot], allow_other_workers=True)

    def wait(self, futures, timeout=None) -> set:
        from distributed import wait as wait_dask  # deferred: 1.5 s import, Dask only
        try:
            return wait_dask(list(futures), timeout=timeout, return_when="FIRST_COMPLETED").done
        except TimeoutError:
            return set()

    def renew(self, slot) -> bool:
        """Dask replaces lost workers itself: whether ``slot`` is gone."""
        return slot not in self.slots

    def worker_memory_limits(self) -> list[float]:
        return [float(w.get("memory_limit") or 0) for w in self.client.scheduler_info()["workers"].values()]

    def clear(self, fn, *args) -> None:
        self.client.run(fn, *args, on_error="ignore")     # a worker that died holds nothing

    def stop(self, futures) -> None:
        self.client.cancel(list(futures))

    def close(self) -> None:
        if self.own:
            self.client.close()


def task_pool(scheduler=None, workers: int | None = None, client=None) -> Executor:
    """The executor of batches and of reductions in parts: a Dask cluster (``client`` or the
    ``scheduler`` address) or, without either, a local pool of ``workers`` processes (default: cores)."""
    if client or scheduler:
        return DaskPool(client or scheduler, workers)
    return LocalPool(workers or os.cpu_count() or 1)
