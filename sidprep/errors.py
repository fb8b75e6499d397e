"""User-facing errors: one line naming the file, the problem and the fix."""

import os
import signal
import sys
import threading
import time


class InputError(Exception):
    """Bad input (file, option, model).  The CLI prints ``sidprep: error: <message>`` and exits 2.

    The message must be one line that names the file or option, the problem and the fix,
    e.g. ``"rod.msh: 3 elements have negative volume (worst: element 1207); re-mesh or fix the node order"``.
    """

    exit_code = 2


def printable(text: str) -> str:
    """``text`` with control characters (newline, tab, ANSI escape, ...) written as escapes
    (``\\n``, ``\\x1b``): user text echoed in a message stays one line and cannot drive the terminal."""
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in str(text))


#: how a library note that is a warning starts (e.g. sidprep.jobs.reduce's rotation check)
WARNING_PREFIX = "WARNING: "


def note_line(note: str) -> str:
    """The line a command prints on stderr for a library note: ``note: ...``, or for a note that is a
    warning the warning line of every command, ``sidprep: warning: ...``."""
    if note.startswith(WARNING_PREFIX):
        return f"sidprep: warning: {printable(note[len(WARNING_PREFIX):])}"
    return f"note: {note}"


def ascii_line(text: str) -> str:
    """``text`` as one line of ASCII for a comment in an ASCII file (OBJ, SID_FEM): whitespace runs
    as one blank, other characters outside printable ASCII as Python escapes (``b\\xe4r.msh``)."""
    flat = " ".join(str(text).split())
    return flat.encode("ascii", "backslashreplace").decode("ascii")


class SimulationFailed(InputError):
    """A simulation stopped before t_end (Newton failure, divergence, max_steps); ``result``
    holds everything computed up to the last accepted step (``result.stats.failed`` says
    why), so that it can be written and inspected."""

    def __init__(self, message: str, result=None):
        super().__init__(message)
        self.result = result


class Terminated(BaseException):
    """SIGTERM received (``terminate_on_sigterm``): unwinds like KeyboardInterrupt, so that
    temporary files are removed; the CLI exits 143 (128 + SIGTERM, ``sidprep.cli.main.SIGNAL_EXITS``)."""


def _raise_terminated(signum, frame):
    raise Terminated()


#: seconds after which a dropped stop's signal is sent again (the hook has long returned)
STOP_RESEND_S = 0.01
#: the signal that raises each stop exception again when Python had to drop it
_STOP_SIGNALS = ((Terminated, signal.SIGTERM), (KeyboardInterrupt, signal.SIGINT))


def _signal_dropped_stop_again(unraisable) -> None:
    """``sys.unraisablehook``: a stop (Terminated, KeyboardInterrupt) raised by a signal handler
    while a weakref callback, ``__del__`` or the garbage collector ran cannot propagate, and Python
    would print it and go on; a thread sends the process the signal again once this hook has
    returned (sent from here, the handler would raise in the hook), and the handler raises the stop
    at the main thread's next ordinary instruction.  Anything else goes to Python's default hook."""
    for stop, signum in _STOP_SIGNALS:
        if isinstance(unraisable.exc_value, stop):
            threading.Thread(target=_signal_later, args=(signum,), daemon=True).start()
            return
    sys.__unraisablehook__(unraisable)


def _signal_later(signum: int) -> None:
    time.sleep(STOP_RESEND_S)
    os.kill(os.getpid(), signum)


def keep_stops_raisable() -> None:
    """Install ``_signal_dropped_stop_again`` as ``sys.unraisablehook`` (the CLI and batch workers)."""
    sys.unraisablehook = _signal_dropped_stop_again


def terminate_on_sigterm() -> None:
    """Turn SIGTERM into a ``Terminated`` exception in the main thread (the CLI installs it); a stop
    that lands where Python cannot raise it is raised again (``keep_stops_raisable``)."""

    signal.signal(signal.SIGTERM, _raise_terminated)
    keep_stops_raisable()
