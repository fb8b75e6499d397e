"""The parts a worker process holds through a reduction in parts (the worker's side of
sidprep.jobs.parts.PartTasks).

A part is sent to its worker once, with its first task; the worker keeps it - its matrices and the
factor of its K_II, sidprep.reduction.part_tasks.HeldPart - in a ``HeldParts`` store, so later tasks
carry right-hand sides only.  The store keeps the worker's resident memory within the budget the
driver gives with each task, releasing other parts' matrices and factors (made again when next
needed, without the part sent again).  ``held_task`` is what the driver sends: a part task run
with the part this worker process holds (``WORKER_PARTS``).
"""

from __future__ import annotations

import threading
from collections import OrderedDict

from sidprep.errors import InputError
from sidprep.progress import resident_memory_bytes, return_freed_memory
from sidprep.reduction.part_tasks import HeldPart, PartTask
from sidprep.reduction.partition import PartModel


class PartFailed(RuntimeError):
    """A part's task raised an error of its own (its worker lives): not run again."""


class NotHeld(LookupError):
    """A part task reached a worker that does not hold the part (a new one): send it again."""


class HeldParts:
    """(run id, part index) -> HeldPart, least recently used first, behind a lock (a Dask worker runs
    tasks in threads): the parts one worker process holds."""

    def __init__(self):
        self.parts: OrderedDict[tuple, HeldPart] = OrderedDict()
        self.lock = threading.Lock()

    def task(self, key: tuple, part: PartModel | None, budget: float, fn: PartTask, *args):
        """``fn(HeldPart, *args)`` with the part ``key`` (``held``).  An error of the task's own (the
        part's assembly included) is PartFailed, naming the part: it is not retried."""
        held = None
        try:
            held = self.held(key, part, budget)
            return fn(held, *args)
        except (InputError, MemoryError, NotHeld):             # the user's error; out of memory: the worker's
            raise
        except Exception as exc:                               # the task's own error: the same again on a retry
            name = (held.description if held is not None else part).name
            raise PartFailed(f"{name}: {fn.__name__} failed: {type(exc).__name__}: {exc}") from None
        finally:                                               # the task's temporaries, not kept as heap; the
            self.release_others(key, budget)                   # worker idles within its budget, as it starts

    def held(self, key: tuple, part: PartModel | None, budget: float) -> HeldPart:
        """The HeldPart ``key``; ``part`` (None when it should be held already: NotHeld otherwise) is held
        from now on.  While the worker's resident memory (``resident_memory_bytes``, its freed heap
        returned first) exceeds ``budget`` - what it may hold when a task starts, the task's own peak
        left beside it (sidprep.jobs.parts.check_parts_fit) - the most recently used other part whose
        matrices or factor are held is released (``HeldPart.release``): measured, not estimated, since a
        worker also holds its interpreter and what its transfers left (a 2.4M-DOF run's 5 GB workers
        sat at 3.4 GB between tasks with 2 GB of parts estimated held, and a count task on top of that
        stopped them).  The tasks of a round visit a worker's parts in the same order every round, so
        the part just used is the one needed last (least recently used first would release each part
        just before its next task).  Its task assembles the part, outside the lock, so a worker's
        threads assemble parts side by side."""
        with self.lock:
            held = self.parts.get(key)
            if held is None:
                if part is None:
                    raise NotHeld(key)
                held = self.parts[key] = HeldPart(part)
            self.parts.move_to_end(key)
        self.release_others(key, budget)
        return held

    def release_others(self, key: tuple, budget: float) -> None:
        """Give the freed heap back, then release the most recently used held part other than ``key``
        while the worker's resident memory exceeds ``budget`` (``held``)."""
        with self.lock:
            others = [h for k, h in self.parts.items() if k != key and h.holds]
            return_freed_memory()
            while others and resident_memory_bytes() > budget:
                others.pop().release()
                return_freed_memory()

    def release_run(self, run: str) -> None:
        """Drop every part of the run ``run``."""
        with self.lock:
            for key in [k for k in self.parts if k[0] == run]:
                del self.parts[key]


#: the parts this worker process holds (every process has its own; the driver's holds none)
WORKER_PARTS = HeldParts()


def held_task(key: tuple, part: PartModel | None, budget: float, fn: PartTask, *args):
    """A part task as the driver sends it: ``fn(HeldPart, *args)`` with the part ``key`` this worker
    holds (``HeldParts.task``)."""
    return WORKER_PARTS.task(key, part, budget, fn, *args)


def release_run(run: str) -> None:
    """Drop every part of the run ``run`` this worker holds (sent to every worker as a run ends)."""
    WORKER_PARTS.release_run(run)
