"""The one executor contract of batches and reductions in parts (sidprep.jobs.executor).

Independent references: the operating system's process ids and signals (a worker killed with
SIGKILL, a worker's process gone after ``stop``), the ``Executor`` protocol's own member list, and
the source text of the jobs package (no private attribute of another library).
"""

import ast
import os
import signal
import time
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

import psutil
import pytest

from sidprep.jobs.executor import DaskPool, Executor, LocalPool

ROOT = Path(__file__).resolve().parents[1]
#: seconds a worker may take to start (spawned: a fresh interpreter) and answer
START_S = 60
#: private names of the standard library that its documentation makes public (os._exit)
DOCUMENTED_PRIVATE = {"_exit"}


def test_the_local_pool_and_dask_implement_every_member_of_the_contract():
    members = {name for name in vars(Executor) if not name.startswith("_")} | set(Executor.__annotations__)
    assert {"submit", "run_on", "wait", "renew", "stop", "close", "workers", "slots"} <= members
    for pool in (LocalPool, DaskPool):
        missing = [name for name in members - {"workers"} if not callable(getattr(pool, name, None))
                   and not isinstance(getattr(pool, name, None), property)]
        assert not missing, f"{pool.__name__} lacks {missing}"


def test_a_killed_local_worker_fails_its_own_task_and_its_slot_alone_starts_afresh():
    pool = LocalPool(2)
    try:
        pids = [pool.run_on(slot, os.getpid).result(timeout=START_S) for slot in pool.slots]
        assert len(set(pids)) == 2 and not any(pool.renew(slot) for slot in pool.slots)   # alive: kept
        sleeping = pool.run_on(0, time.sleep, 30)
        os.kill(pids[0], signal.SIGKILL)
        with pytest.raises(BrokenProcessPool):
            sleeping.result(timeout=START_S)
        assert pool.run_on(1, os.getpid).result(timeout=START_S) == pids[1]     # the other worker goes on
        assert pool.renew(0) and not pool.renew(1)
        fresh = pool.run_on(0, os.getpid).result(timeout=START_S)
        assert fresh not in pids and psutil.Process(fresh).ppid() == os.getpid()
        # ``submit`` sends a task to a worker with nothing running
        busy = pool.submit(time.sleep, 10)
        t0 = time.monotonic()
        assert pool.submit(os.getpid).result(timeout=START_S) in (fresh, pids[1])
        assert time.monotonic() - t0 < 10 and not busy.done()
    finally:
        pool.close()


def test_stop_ends_the_local_workers_and_their_running_tasks():
    pool = LocalPool(1)
    try:
        pid = pool.run_on(0, os.getpid).result(timeout=START_S)
        running = pool.submit(time.sleep, 60)
        time.sleep(0.5)
        t0 = time.monotonic()
        pool.stop([running])
        with pytest.raises(BrokenProcessPool):
            running.result(timeout=START_S)
        assert time.monotonic() - t0 < 30 and not psutil.pid_exists(pid)
    finally:
        pool.close()


def private_attributes(source: str) -> list[int]:
    """Lines of ``source`` that reach ``x._name`` where x is not the object itself (self, cls)."""
    return [node.lineno for node in ast.walk(ast.parse(source))
            if isinstance(node, ast.Attribute) and node.attr.startswith("_") and not node.attr.startswith("__")
            and node.attr not in DOCUMENTED_PRIVATE
            and not (isinstance(node.value, ast.Name) and node.value.id in ("self", "cls"))]


def test_the_jobs_reach_no_private_attribute_of_another_object():
    assert private_attributes("pool._broken") == [1]                       # the check can fail
    assert not private_attributes("os._exit(0)\nself._part = None")
    offenders = [f"{path.name}:{line}" for path in sorted((ROOT / "sidprep" / "jobs").glob("*.py"))
                 for line in private_attributes(path.read_text())]
    assert not offenders, offenders
