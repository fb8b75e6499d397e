"""Entry point of the ``sidprep`` command: discovers the sub-command modules of this package.

Each module ``sidprep/cli/<name>.py`` that defines ``register(subparsers)`` adds one sub-command; the
parser it adds must set ``func=run`` with ``run(args) -> int``.  Modules import their heavy
dependencies inside ``run`` so that ``sidprep --help`` stays fast.
Errors: ``InputError`` -> one line on stderr, exit 2; anything else -> one line naming the
internal error, exit 3 (``--debug`` shows the traceback); SIGINT -> exit 130, SIGTERM -> exit 143,
both with one line after the temporary files are removed, at any moment of the process (while
the parser is built, while the command runs, and while the process ends).
"""

from __future__ import annotations

import argparse
import atexit
import importlib
import math
import os
import pkgutil
import signal
import sys
import threading
import warnings

from sidprep import cli
from sidprep import __version__
from sidprep.errors import InputError, Terminated, printable, terminate_on_sigterm


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="sidprep",
        description="Tetrahedral FE model -> reduced flexible body (SID), and an FFR multibody solver.",
    )
    parser.add_argument("--version", action="version", version=f"sidprep {__version__}")
    parser.add_argument("--debug", action="store_true", help="show tracebacks of internal errors")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for info in sorted(pkgutil.iter_modules(cli.__path__), key=lambda m: m.name):
        if info.name == "main":
            continue
        module = importlib.import_module(f"sidprep.cli.{info.name}")
        if hasattr(module, "register"):
            module.register(sub)
    return parser


def one_line_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """Warnings as one line on stderr, ``sidprep: warning: ...`` (no source line, no location)."""
    print(f"sidprep: warning: {printable(message)}", file=sys.stderr)


def check_finite_options(args) -> None:
    """Every number option is finite: argparse's float() accepts "nan" and "inf"."""
    for key, value in vars(args).items():
        if isinstance(value, float) and not math.isfinite(value):
            raise InputError(f"--{key.replace('_', '-')} {value}: must be a finite number")


#: the exit code and the one line of each signal that stops a command (128 + signal number; SIGINT 130)
SIGNAL_EXITS = {signal.SIGINT: (130, "sidprep: interrupted"), signal.SIGTERM: (143, "sidprep: terminated")}


def main(argv: list[str] | None = None, *, own_process: bool = False) -> int:
    """Run one sub-command; ``own_process``: the process is the command's own (``command``), so
    the sub-command's ``process_setup(args)`` (if its parser sets one) runs first."""
    terminate_on_sigterm()
    try:
        parser = build_parser()
        args = parser.parse_args(argv)
    except KeyboardInterrupt:
        return stopped_by(signal.SIGINT)
    except Terminated:
        return stopped_by(signal.SIGTERM)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    warnings.showwarning = one_line_warning
    try:
        if own_process and getattr(args, "process_setup", None):
            args.process_setup(args)          # may import the command's modules: a signal meanwhile ends it as above
        check_finite_options(args)
        return int(args.func(args) or 0)
    except InputError as exc:
        print(f"sidprep: error: {printable(exc)}", file=sys.stderr)
        return InputError.exit_code
    except BrokenPipeError:            # stdout closed early (``sidprep info X | head``): not an error
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except KeyboardInterrupt:
        return stopped_by(signal.SIGINT)
    except Terminated:
        return stopped_by(signal.SIGTERM)
    except Exception as exc:  # an internal error, not bad input
        if args.debug:
            raise
        print(f"sidprep: internal error: {type(exc).__name__}: {printable(exc)} (rerun with --debug for the traceback)",
              file=sys.stderr)
        return 3


def stopped_by(signum: int) -> int:
    """Print the one line of a command stopped by ``signum``; its exit code (SIGNAL_EXITS)."""
    code, line = SIGNAL_EXITS[signum]
    print(line, file=sys.stderr)
    return code


class ShutdownSignals:
    """SIGINT / SIGTERM after the command returned, while the process ends: the first is noted
    (the exit handlers still remove temporary folders) and decides the exit code and its one
    line (``exit_code``); a second one, or the first when ``at_once``, ends the process at once."""

    def __init__(self, at_once: bool = False):
        self.received: int | None = None
        self.at_once = at_once
        for signum in SIGNAL_EXITS:
            signal.signal(signum, self.note)

    def note(self, signum, frame) -> None:
        if self.received is not None or self.at_once:
            os._exit(stopped_by(signum))
        self.received = signum

    def exit_code(self, code: int) -> int:
        return code if self.received is None else stopped_by(self.received)


def command() -> None:
    """The ``sidprep`` command: ``main`` as a process of its own, ended without Python's teardown
    of its modules once the atexit handlers have run and stdout and stderr are flushed: that
    teardown (the ~840 modules a simulation loads, numpy, scipy and h5py among them, freed one by
    one) costs 0.14-0.16 CPU-s after a simulation of examples/flexible_pendulum or
    examples/beam_slider_crank (medians of 5 whole processes, 0.75 and 0.92 CPU-s with it skipped).
    While another thread still runs (a pool, a Dask client), the process ends the ordinary way.
    A signal after the command returned ends the process with its own code (ShutdownSignals)."""
    code = main(own_process=True)
    shutdown = ShutdownSignals(at_once=threading.active_count() > 1)
    if shutdown.at_once:
        sys.exit(code)
    atexit._run_exitfuncs()  # what the interpreter runs first at its exit (temporary folders, h5py, logging)
    code = shutdown.exit_code(code)
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (BrokenPipeError, ValueError):  # reader gone, or the stream closed: nothing left to write
            pass
    os._exit(code)


if __name__ == "__main__":
    command()
