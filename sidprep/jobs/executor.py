"""Where tasks run: a local process pool or a Dask cluster, behind one small interface (``run``,
``wait``, ``close``, ``workers``) - the executor of ``sidprep batch`` (sidprep.jobs.batch) and of
reductions in parts (sidprep.jobs.parts)."""

from __future__ import annotations

import os

from sidprep.errors import InputError

#: seconds to wait for a Dask scheduler before giving up
DASK_CONNECT_S = 10


class _LocalPool:
    """A process pool of ``workers`` processes (forkserver: clean workers, reused across jobs)."""

    def __init__(self, workers: int):
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        self.pool = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("forkserver"))
        self.workers = workers

    def run(self, fn, *args):
        """Any task (a top-level function and its picklable arguments) on the pool."""
        return self.pool.submit(fn, *args)

    def wait(self, futures):
        from concurrent.futures import FIRST_COMPLETED, wait
        return wait(futures, return_when=FIRST_COMPLETED).done

    def close(self):
        self.pool.shutdown(wait=True, cancel_futures=True)


class _DaskPool:
    """The same interface on a dask.distributed cluster (``address`` of its scheduler)."""

    def __init__(self, address, workers: int | None):
        try:
            from distributed import Client
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

    def wait(self, futures):
        from distributed import wait
        return wait(list(futures), return_when="FIRST_COMPLETED").done

    def close(self):
        if self.own:
            self.client.close()


def task_pool(scheduler=None, workers: int | None = None, client=None):
    """The executor of batches and of reductions in parts: a Dask cluster (``client`` or the
    ``scheduler`` address) or, without either, a local process pool of ``workers`` (default: cores)."""
    if client or scheduler:
        return _DaskPool(client or scheduler, workers)
    return _LocalPool(workers or os.cpu_count() or 1)
