"""Where tasks run: a local process pool or a Dask cluster, behind one small interface (``run``,
``wait``, ``close``, ``workers``) - the executor of ``sidprep batch`` (sidprep.jobs.batch) and of
reductions in parts (sidprep.jobs.parts)."""

from __future__ import annotations

import multiprocessing
import os
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

from sidprep.errors import InputError
from sidprep.jobs.guard import guarded, stop_workers, worker_setup

#: seconds to wait for a Dask scheduler before giving up
DASK_CONNECT_S = 10
#: an array argument of a pinned Dask task above this many bytes is scattered to its worker first
SCATTER_BYTES = 2**20


#: every thread pool of a worker process at one thread, set before numpy, MKL, OpenBLAS or numba
#: load (a limit set after the import does not reach OpenMP / numba): with N jobs on N cores more
#: threads only contend (issue 27: 1.58x -> 1.77x over one by one on 2 cores)
SINGLE_THREAD_ENV = {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
                     "NUMBA_NUM_THREADS": "1", "VECLIB_MAXIMUM_THREADS": "1"}


def _worker_start(parent_pid: int) -> None:
    """Initializer of every local worker, run before the task's modules are imported (this module
    imports no numerical library): the thread limits, then the batch's hold on the worker
    (sidprep.jobs.guard.worker_setup: ^C is the parent's, SIGTERM unwinds, no worker outlives it)."""
    os.environ.update(SINGLE_THREAD_ENV)
    worker_setup(parent_pid)


class _LocalPool:
    """A process pool of ``workers`` processes, reused across tasks. Spawned, children of this
    process: with forkserver a SIGKILL of the batch left the server and workers blocked on pipes
    whose write ends leaked into their siblings (sidprep.jobs.guard)."""

    def __init__(self, workers: int):
        self.pool = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"),
                                        initializer=_worker_start, initargs=(os.getpid(),))
        self.workers = workers

    def run(self, fn, *args):
        """Any task (a top-level function and its picklable arguments) on the pool."""
        return self.pool.submit(guarded, fn, *args)

    def wait(self, futures, timeout=None):
        """The futures done: at least one, or none after ``timeout`` seconds."""
        return wait(futures, timeout=timeout, return_when=FIRST_COMPLETED).done

    def stop(self, futures):
        """Stop the running tasks now (^C, SIGTERM): sidprep.jobs.guard.stop_workers."""
        stop_workers(list(getattr(self.pool, "_processes", {}).values()))

    def close(self):
        if getattr(self.pool, "_broken", False):
            # a worker died: waiting for the pool's internals can hang on its dead pipes (seen in
            # CPython 3.11's terminate_broken), so the remaining workers are killed and not waited for
            for process in list((getattr(self.pool, "_processes", None) or {}).values()):
                process.kill()
            self.pool.shutdown(wait=False, cancel_futures=True)
        else:
            self.pool.shutdown(wait=True, cancel_futures=True)


class _PinnedLocalPool:
    """``workers`` single-process pools, one per slot: a task given a slot (``run_on``) runs in that
    slot's process, so what a task leaves there (sidprep.jobs.parts: a part and its factor) is found
    by the next task sent to the same slot.  A slot whose process died is started afresh (``renew``)."""

    def __init__(self, workers: int):
        self.pools = [_LocalPool(1) for _ in range(workers)]
        self.workers = workers

    @property
    def slots(self) -> list:
        return list(range(self.workers))

    def run_on(self, slot, fn, *args):
        """A task on the process of ``slot``."""
        return self.pools[slot].run(fn, *args)

    def wait(self, futures, timeout=None):
        """The futures done: at least one, or none after ``timeout`` seconds."""
        return wait(futures, timeout=timeout, return_when=FIRST_COMPLETED).done

    def renew(self, slot) -> bool:
        """Start ``slot``'s process afresh if it died; whether it had."""
        if not getattr(self.pools[slot].pool, "_broken", False):
            return False
        self.pools[slot].close()
        self.pools[slot] = _LocalPool(1)
        return True

    def stop(self, futures):
        for pool in self.pools:
            pool.stop(futures)

    def clear(self, fn, *args) -> None:
        """Nothing: what a task left in a slot's process ends with it (``close``)."""

    def close(self):
        while self.pools:
            self.pools.pop().close()


class _DaskPool:
    """The same interface on a dask.distributed cluster (``address`` of its scheduler)."""

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
        self.memory_mb = sum(w.get("memory_limit", 0) or 0 for w in info) / 2**20 or None

    def run(self, fn, *args):
        """Any task (a top-level function and its picklable arguments) on the cluster."""
        return self.client.submit(fn, *args, pure=False)

    @property
    def slots(self) -> list:
        """The workers' addresses (those alive now)."""
        return sorted(self.client.scheduler_info()["workers"])

    def run_on(self, slot, fn, *args):
        """A task on the worker ``slot`` (its address) while it lives; on another when it is gone.  Its
        array arguments above SCATTER_BYTES are scattered to that worker first, so that the scheduler
        holds no copy of them in the task (at 2.4M DOF in parts, 3.8 GB in the scheduler's process)."""
        args = [self.client.scatter(a, workers=[slot], hash=False) if getattr(a, "nbytes", 0) > SCATTER_BYTES else a
                for a in args]
        return self.client.submit(fn, *args, pure=False, workers=[slot], allow_other_workers=True)

    def renew(self, slot) -> bool:
        """Dask replaces lost workers itself: whether ``slot`` is gone."""
        return slot not in self.slots

    def clear(self, fn, *args) -> None:
        """``fn(*args)`` on every worker (they outlive ``close``: clear what the tasks left there)."""
        self.client.run(fn, *args, on_error="ignore")     # a worker that died holds nothing

    def wait(self, futures, timeout=None):
        """The futures done: at least one, or none after ``timeout`` seconds."""
        from distributed import wait  # deferred: 1.5 s import, Dask only
        try:
            return wait(list(futures), timeout=timeout, return_when="FIRST_COMPLETED").done
        except TimeoutError:
            return set()

    def stop(self, futures):
        self.client.cancel(list(futures))

    def close(self):
        if self.own:
            self.client.close()


def task_pool(scheduler=None, workers: int | None = None, client=None, pinned: bool = False):
    """The executor of batches and of reductions in parts: a Dask cluster (``client`` or the
    ``scheduler`` address) or, without either, a local process pool of ``workers`` (default: cores);
    ``pinned``: a task can be sent to one worker (``slots``, ``run_on``, ``renew``)."""
    if client or scheduler:
        return _DaskPool(client or scheduler, workers)
    n = workers or os.cpu_count() or 1
    return _PinnedLocalPool(n) if pinned else _LocalPool(n)
