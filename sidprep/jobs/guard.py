"""A batch's hold on its output folder and on its worker processes.

* ``folder_lock(outdir)``: one batch writes a folder at a time.  The lock is the file
  ``outdir/.sidprep-batch.lock`` (JSON: pid, host, start time), created exclusively; a second batch
  stops with an InputError naming the first.  A lock whose process no longer runs (same host) is
  stale and taken over.  On release the lock goes, and so does every ``.part`` file left in the
  folder (the folder was this batch's alone: a worker stopped mid-write leaves its temporary file).
* ``worker_setup(parent_pid)``: the initializer of every worker process (spawned: a child of the
  batch process): ^C is the parent's to handle (no KeyboardInterrupt traceback per worker),
  SIGTERM unwinds (temporary files removed; also when it lands in a weakref callback or
  ``__del__``, ``sidprep.errors.keep_stops_raisable``), and the worker ends when the batch process is gone
  (SIGKILL of the parent leaves no worker running): PR_SET_PDEATHSIG on Linux, and a watchdog
  thread polling the parent elsewhere and as a second guard.
* ``stop_workers(processes)``: SIGTERM to each, then SIGKILL after STOP_GRACE_S.
* ``require_main_guard(call)``: the local workers are spawned, and a spawned worker first imports
  the user's script: a script that calls ``run_batch`` at its top level gets a one-line error
  saying to put the call under ``if __name__ == "__main__":``, not a lost worker.
"""

from __future__ import annotations

import ast
import contextlib
import ctypes
import json
import multiprocessing
import os
import signal
import socket
import sys
import threading
import time
from pathlib import Path

from sidprep.errors import InputError, Terminated, keep_stops_raisable

LOCK_NAME = ".sidprep-batch.lock"
#: prctl option: signal to receive when the parent process dies (linux/prctl.h)
PR_SET_PDEATHSIG = 1
#: seconds between a worker's checks that the batch process still runs
PARENT_POLL_S = 0.5
#: seconds a stopped worker gets to remove its temporary files before it is killed
STOP_GRACE_S = 5.0


def _running(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:        # another user's process
        return True
    return True


def _owner(lock: Path) -> dict | None:
    """The lock's content, or None when it is gone or unreadable (being written: retried)."""
    try:
        return json.loads(lock.read_text())
    except (OSError, ValueError):
        return None


@contextlib.contextmanager
def folder_lock(outdir: Path):
    """Hold ``outdir`` for one batch (module doc); InputError when another batch holds it."""
    lock = Path(outdir) / LOCK_NAME
    me = {"pid": os.getpid(), "host": socket.gethostname(), "started_unix_s": time.time()}
    for _ in range(3):
        try:
            fd = os.open(lock, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
        except FileExistsError:
            owner = _owner(lock)
            if owner is None:
                time.sleep(0.1)
                continue
            if owner.get("host") != me["host"] or _running(int(owner.get("pid", -1))):
                started = time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(owner.get("started_unix_s", 0)))
                raise InputError(f"{outdir}: another sidprep batch writes this folder (pid {owner.get('pid')} on "
                                 f"{owner.get('host')}, started {started}); wait for it or choose another "
                                 f"outdir (a stale lock: remove {lock})") from None
            with contextlib.suppress(FileNotFoundError):    # stale: its batch is gone
                lock.unlink()
            continue
        except OSError as exc:
            raise InputError(f"{outdir}: cannot create the lock file ({exc.strerror}); choose a writable folder") \
                from None
        with os.fdopen(fd, "w") as f:
            json.dump(me, f)
        break
    else:
        raise InputError(f"{outdir}: the lock file {lock} cannot be taken; remove it if no batch runs")
    try:
        yield lock
    finally:
        for part in list(Path(outdir).rglob("*.part")):
            with contextlib.suppress(OSError):
                part.unlink()
        with contextlib.suppress(OSError):
            lock.unlink()


def _top_level_calls(tree: ast.Module, call: str):
    """Line numbers of the calls of ``call`` (name or attribute) that run when the module is
    imported: outside functions, classes and ``if __name__ ...`` blocks."""
    for stmt in tree.body:
        if isinstance(stmt, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            continue
        if isinstance(stmt, ast.If) and any(isinstance(n, ast.Name) and n.id == "__name__"
                                            for n in ast.walk(stmt.test)):
            continue
        for node in ast.walk(stmt):
            if isinstance(node, ast.Call) and call in (getattr(node.func, "id", None), getattr(node.func, "attr", None)):
                yield node.lineno


def require_main_guard(call: str) -> None:
    """InputError when ``call`` runs at the top level of the user's script (module doc): in the
    script's own process, found in its source; in a spawned worker importing the script, found by
    being there."""
    main = sys.modules.get("__main__")
    fix = f'put the {call}(...) call under `if __name__ == "__main__":` (its worker processes import the script)'
    if multiprocessing.parent_process() is not None and getattr(main, "__name__", "") == "__mp_main__":
        raise InputError(f"{getattr(main, '__file__', 'the script')}: {call} started while a worker imported the "
                         f"script; {fix}")
    script = getattr(main, "__file__", None)
    if not script or getattr(main, "__spec__", None) is not None:   # interactive, -c, or python -m (a module)
        return
    try:
        tree = ast.parse(Path(script).read_bytes())
    except (OSError, SyntaxError, ValueError):
        return
    for line in _top_level_calls(tree, call):
        raise InputError(f"{script}:{line}: {call} runs at the top level of the script; {fix}")


#: a worker runs a job (``guarded``): SIGTERM unwinds it; an idle worker just ends
_busy = False


def worker_setup(parent_pid: int) -> None:
    """Initializer of a batch's worker process (module doc)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, _on_sigterm)
    keep_stops_raisable()
    if sys.platform.startswith("linux"):
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
        if os.getppid() != parent_pid:                       # the parent died before prctl
            os._exit(143)
    threading.Thread(target=_watch_parent, args=(parent_pid,), daemon=True, name="sidprep-parent-watch").start()


def _on_sigterm(signum, frame):
    if _busy:
        raise Terminated()
    os._exit(143)


def guarded(job, *args):
    """``job(*args)`` in a worker; stopped by SIGTERM, the job unwinds (its temporary files are
    removed) and the worker ends."""
    global _busy
    _busy = True
    try:
        return job(*args)
    except Terminated:
        os._exit(143)
    finally:
        _busy = False


def _watch_parent(parent_pid: int) -> None:
    while _running(parent_pid):
        time.sleep(PARENT_POLL_S)
    os.kill(os.getpid(), signal.SIGTERM)       # unwind the job: its temporary files are removed
    time.sleep(STOP_GRACE_S)
    os._exit(143)


def stop_workers(processes) -> None:
    """SIGTERM to each worker process (multiprocessing.Process), SIGKILL to those still running
    after STOP_GRACE_S."""
    processes = [p for p in processes if p.is_alive()]
    for p in processes:
        with contextlib.suppress(OSError):
            p.terminate()
    deadline = time.monotonic() + STOP_GRACE_S
    for p in processes:
        p.join(max(deadline - time.monotonic(), 0.0))
        if p.is_alive():
            p.kill()
            p.join(1.0)
