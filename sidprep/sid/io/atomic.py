"""Write files atomically: to a temporary name in the target folder, renamed when complete.

Every output of sidprep goes through :func:`atomic_path` (text, OBJ, HTML, CSV) or
:func:`atomic_hdf5` (.sid.h5, results .h5): a full disk or another I/O error becomes one
InputError naming the file, the temporary file is removed on every exit path (exceptions,
KeyboardInterrupt, and SIGTERM once ``sidprep.errors.terminate_on_sigterm`` is installed), and
no final-named file is ever partial.  The files written inside :func:`output_set` form one set
(a reduction's .sid.h5, .SID_FEM and .obj): all appear, or none.
"""

from __future__ import annotations

import contextlib
import contextvars
import os
import signal
import tempfile
from pathlib import Path

import h5py

from sidprep.errors import InputError

#: the open output set: (temporary, final) paths renamed together when the set completes
_OPEN_SET: contextvars.ContextVar[list | None] = contextvars.ContextVar("sidprep_output_set", default=None)
#: the signals held back while a set is renamed (their handlers run once it is complete)
_HELD_SIGNALS = {signal.SIGINT, signal.SIGTERM}


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike):
    """Yield a temporary path next to ``path``; rename it to ``path`` only if the block succeeds.

    A failure (exception, interrupt) removes the temporary file, so no half-written output
    is ever left under the final name; an OSError in the block (disk full, quota, I/O error)
    becomes an InputError naming ``path``.
    """
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
    except OSError as exc:
        raise InputError(f"{path}: cannot write here ({exc.strerror}); choose a writable folder") from None
    os.close(fd)
    try:
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp creates 0600; give the file the usual permissions
        yield Path(tmp)
        pending = _OPEN_SET.get()
        if pending is None:
            os.replace(tmp, path)
        else:
            pending.append((tmp, path))
    except OSError as exc:
        _remove(tmp)
        raise InputError(f"{path}: could not be written ({exc.strerror or exc}); free disk space or "
                         "choose another folder") from None
    except BaseException:
        _remove(tmp)
        raise


@contextlib.contextmanager
def output_set():
    """The files that :func:`atomic_path` writes in the block form one set: each stays under its
    temporary name until the block succeeds, then all are renamed with SIGINT and SIGTERM held
    back (a signal takes effect after the last rename); any failure or signal before removes
    every temporary file: the set of outputs is complete or absent."""
    pending: list = []
    token = _OPEN_SET.set(pending)
    try:
        yield
        _OPEN_SET.reset(token)
        token = None
        held = signal.pthread_sigmask(signal.SIG_BLOCK, _HELD_SIGNALS)
        try:
            while pending:
                tmp, path = pending[0]
                try:
                    os.replace(tmp, path)
                except OSError as exc:
                    raise InputError(f"{path}: could not be written ({exc.strerror or exc}); free disk space or "
                                     "choose another folder") from None
                pending.pop(0)
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, held)
    finally:
        if token is not None:
            _OPEN_SET.reset(token)
        for tmp, _ in pending:
            _remove(tmp)


@contextlib.contextmanager
def atomic_hdf5(path: str | os.PathLike):
    """Yield a new, empty ``h5py.File`` held in memory; written to ``path`` atomically when the
    block succeeds (through :func:`atomic_path`).

    HDF5 itself never writes to the disk.  Why: when HDF5 (2.0, h5py 3.16) fails to write
    (ENOSPC, EFBIG, EIO) while closing a file whose groups or datasets are still open, the
    failed flush leaves the file half closed: h5py's remaining object ids fail to decrement
    ("Can't decrement id ref count", printed as "Exception ignored" tracebacks) and the final
    ``H5Fclose`` touches the freed file structure: a segmentation fault.  Building the file in
    memory (core driver, no backing store) and writing its image with an ordinary Python write
    turns any I/O error into an OSError, hence one InputError.
    """
    with atomic_path(path) as tmp:
        with h5py.File(f"{tmp}.in-memory", "w", driver="core", backing_store=False) as f:
            yield f
            f.flush()
            image = f.id.get_file_image()
        with open(tmp, "wb") as out:
            out.write(image)


def _remove(tmp) -> None:
    with contextlib.suppress(FileNotFoundError):
        os.unlink(tmp)


def _umask() -> int:
    """The process umask (reading it requires setting it; restored at once)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask
