"""The solver's entry kernels compiled ahead of time, and ``jit``, the decorator of every kernel
(docs/performance.md, "First run: kernel compilation").

The install's prebuild (sidprep/solver/prebuild.py) runs the example scenes and records every kernel call
made from Python: the kernel and its arguments' types.  numba.pycc compiles each recorded
(kernel, argument types) into one extension module, ``entry_kernels``, beside the shipped JIT
kernels (``<kernel cache>/<NAMESPACE>/aot``), with a table: export name <-> kernel <-> argument
key.  A kernel called from Python then runs its ahead-of-time export when the call's argument key
equals a recorded one exactly, else numba's dispatcher as before (it compiles or loads from the
JIT cache): a scene no example covers, a function argument, ``SIDPREP_AOT=0``,
``NUMBA_DISABLE_JIT=1``, a checkout without an install.

Each kernel is a ``Kernel``: its Python-level call looks the table up first, then calls its numba
dispatcher, which is made (numba imported, the kernel cache installed) only when first needed, so
a run whose entry calls the table covers never imports numba.  Calls between kernels never pass
through here: numba types a kernel global through ``Kernel._numba_type_`` (its dispatcher's
type) and compiles the callee into the caller, as for any numba dispatcher.

The argument key is a finer classification than numba's own ``typeof`` of an argument (an array:
dtype, ndim, C/F/A layout, read-only; a scalar: its Python or numpy type; tuples and namedtuples
member by member, with the namedtuple's class), so equal keys mean equal numba types, and an
array of another layout never reaches an export compiled for C order (pycc's unboxing does not
check the layout).  The prebuild checks that the key determines the numba types on every call it
records.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.machinery
import importlib.util
import json
import os
import signal
import threading
import warnings
from contextlib import contextmanager
from functools import update_wrapper
from collections.abc import Callable, Iterable
from pathlib import Path

import numpy as np

from sidprep.solver.equations.kernel_cache import (AOT_FOLDER, KERNEL_CACHE, NAMESPACE, install_kernel_cache, seed_cache,
                                                   shipped_kernels)

#: the extension module of the entry kernels, and its file's suffix (this interpreter's ABI)
MODULE = "entry_kernels"
EXTENSION_SUFFIX = importlib.machinery.EXTENSION_SUFFIXES[0]
#: the table of the exports: export name <-> kernel <-> argument key
TABLE = "table.json"
#: the environment variable that turns the ahead-of-time kernels off ("0") for comparisons
SWITCH = "SIDPREP_AOT"
#: the /proc/cpuinfo fields that name the CPU and its features (x86: vendor, family, model,
#: stepping, flags; ARM: implementer, architecture, variant, part, Features)
CPU_FIELDS = {"vendor_id", "cpu family", "model", "model name", "stepping", "flags", "CPU implementer",
              "CPU architecture", "CPU variant", "CPU part", "Features"}
#: Python ints numba types as int64 (larger ones go to numba's dispatcher)
INT64_RANGE = (-(2 ** 63), 2 ** 63)


def array_layout(flags) -> str:
    """numba's layout letter of an array: 'C' if C-contiguous, else 'F' if Fortran-contiguous,
    else 'A' (numba.np.numpy_support.map_layout)."""
    return "C" if flags.c_contiguous else "F" if flags.f_contiguous else "A"


def argument_key(value) -> tuple | None:
    """The exact type of one argument, as a hashable tuple of str / int / bool, or None when it
    is not one an ahead-of-time export can take (a function, a list, an object, a huge int).

    ndarray -> ("a", dtype.str, ndim, layout, read-only); bool, int, float, complex, None ->
    ("b",), ("i",), ("f",), ("c",), ("n",); a numpy scalar -> ("s", dtype.str); a tuple ->
    ("t", keys...); a namedtuple -> ("nt", "module.qualname", keys...)."""
    kind = type(value)
    if kind is np.ndarray:
        flags = value.flags
        return ("a", value.dtype.str, value.ndim, array_layout(flags), not flags.writeable)
    if kind is float:
        return ("f",)
    if kind is bool:
        return ("b",)
    if kind is int:
        return ("i",) if INT64_RANGE[0] <= value < INT64_RANGE[1] else None
    if value is None:
        return ("n",)
    if isinstance(value, tuple):
        keys = arguments_key(value)
        if keys is None:
            return None
        if kind is tuple:
            return ("t", *keys)
        if hasattr(kind, "_fields"):
            return ("nt", f"{kind.__module__}.{kind.__qualname__}", *keys)
        return None
    if kind is complex:
        return ("c",)
    if isinstance(value, np.generic) and value.dtype.kind in "biufc":
        return ("s", value.dtype.str)
    return None


def arguments_key(args: Iterable) -> tuple | None:
    """The keys of a call's positional arguments, or None if any has none."""
    keys = []
    for arg in args:
        key = argument_key(arg)
        if key is None:
            return None
        keys.append(key)
    return tuple(keys)


def as_key(data) -> tuple:
    """A key read back from the JSON table (lists -> tuples)."""
    return tuple(as_key(item) if isinstance(item, list) else item for item in data)


def kernel_name(fn: Callable) -> str:
    """'module:qualname' of a kernel's Python function: its name in the table."""
    return f"{fn.__module__}:{fn.__qualname__}"


def host_target() -> dict:
    """The machine the exports are compiled for: LLVM's process triple, host CPU and features,
    and the interpreter's extension-module suffix (its version and ABI)."""
    from llvmlite import binding as llvm  # deferred: 0.025-0.04 CPU s; cpu_fingerprint() serves on Linux

    return {"triple": llvm.get_process_triple(), "cpu": llvm.get_host_cpu_name(),
            "features": llvm.get_host_cpu_features().flatten(), "suffix": EXTENSION_SUFFIX}


def cpu_fingerprint() -> str | None:
    """sha256 of the machine's architecture, the interpreter's extension suffix and the CPU model
    and feature flags of /proc/cpuinfo's first processor (CPU_FIELDS); None without /proc/cpuinfo.
    The same CPU model and flags mean the same LLVM host CPU and features (both read cpuid)."""
    try:
        with open("/proc/cpuinfo") as cpuinfo:
            lines = []
            for line in cpuinfo:
                if not line.strip():
                    break
                lines.append(line)
    except OSError:
        return None
    fields = sorted(f"{key.strip()}:{value.strip()}" for key, _, value in (line.partition(":") for line in lines)
                    if key.strip() in CPU_FIELDS)
    text = "\n".join([os.uname().machine, EXTENSION_SUFFIX, *fields])
    return hashlib.sha256(text.encode()).hexdigest() if fields else None


def same_machine(table: dict) -> bool:
    """Whether ``table`` was compiled for this machine and interpreter: by the CPU fingerprint
    where both have one (no llvmlite import), else by LLVM's host target."""
    fingerprint = cpu_fingerprint()
    if fingerprint is not None and table.get("cpu_fingerprint") is not None:
        return table["cpu_fingerprint"] == fingerprint
    return table.get("target") == host_target()


class EntryKernels:
    """The extension module of one table, imported on the first call that matches an export."""

    def __init__(self, folder: Path):
        self.folder = folder
        self.module = None
        self.broken = False

    def export(self, name: str) -> Callable | None:
        """The compiled function ``name`` of the extension (imported on first use), or None if
        the extension does not import (then every call goes to numba's dispatchers)."""
        if self.module is None and not self.broken:
            try:
                path = self.folder / (MODULE + EXTENSION_SUFFIX)
                spec = importlib.util.spec_from_file_location(MODULE, path)
                module = importlib.util.module_from_spec(spec)
                spec.loader.exec_module(module)
                self.module = module
            except (ImportError, OSError):
                self.broken = True
        return None if self.broken else getattr(self.module, name)


class Exports:
    """A kernel's exports: argument key -> export name, resolved to the function on first use."""

    def __init__(self, extension: EntryKernels):
        self.extension = extension
        self.names: dict[tuple, str] = {}
        self.functions: dict[tuple, Callable] = {}

    def get(self, key: tuple) -> Callable | None:
        """The export compiled for exactly ``key``, or None."""
        function = self.functions.get(key)
        if function is None and key in self.names:
            function = self.extension.export(self.names[key])
            if function is not None:
                self.functions[key] = function
        return function


def table_folders() -> list[Path]:
    """Where a table may lie: the user's kernel cache (seeded from the install), then the
    installed package's own folder (a cache that could not be written)."""
    shipped = shipped_kernels()
    return [KERNEL_CACHE / NAMESPACE / AOT_FOLDER] + ([] if shipped is None else [shipped / AOT_FOLDER])


def read_table(folder: Path) -> dict[str, Exports]:
    """kernel name -> its Exports, from ``folder``/TABLE; empty if there is no table or it was
    compiled for another machine."""
    try:
        table = json.loads((folder / TABLE).read_text())
    except (OSError, ValueError):
        return {}
    if not same_machine(table):
        return {}
    extension = EntryKernels(folder)
    kernels: dict[str, Exports] = {}
    for entry in table["entries"]:
        kernels.setdefault(entry["kernel"], Exports(extension)).names[as_key(entry["key"])] = entry["export"]
    return kernels


def jit_disabled() -> bool:
    """NUMBA_DISABLE_JIT=1: the kernels run as plain Python (read as numba's config reads it)."""
    return int(os.environ.get("NUMBA_DISABLE_JIT") or 0) != 0


def load_table() -> dict[str, Exports]:
    """The ahead-of-time exports of this process's kernels (none with SIDPREP_AOT=0)."""
    if os.environ.get(SWITCH, "1") == "0" or jit_disabled():
        return {}
    for folder in table_folders():
        kernels = read_table(folder)
        if kernels:
            return kernels
    return {}


seed_cache()  # the install's kernels (the extension with them) copied into the user's cache once
#: kernel name -> Exports of this process
AOT_TABLE = load_table()
#: (kernel, argument key) -> numba argument types of every Python-level call, while the
#: prebuild records (record_calls); None otherwise
RECORDED: dict | None = None
#: the listeners of numba's compile events (run.CompileNotice) while they watch (compile_events)
WATCHING: list = []
#: numba imported and the kernel cache installed (by the first numba_dispatcher call)
NUMBA_SET_UP = False


def numba_dispatcher(fn: Callable, cache: bool):
    """numba's CPU dispatcher of ``fn`` (nopython; cached on disk if ``cache``); the first call
    imports numba, installs the kernel cache and registers the watching listeners."""
    global NUMBA_SET_UP
    from numba.core import registry  # deferred: import numba 0.17 CPU s, only when a kernel is JIT-compiled

    if not NUMBA_SET_UP:
        install_kernel_cache()
        NUMBA_SET_UP = True
        for listener in WATCHING:
            register_listener(listener)
    dispatcher = registry.CPUDispatcher(py_func=fn, locals={}, targetoptions={"nopython": True})
    if cache:
        dispatcher.enable_caching()
    return dispatcher


def register_listener(listener) -> None:
    """Pass numba's compile events ("numba:compile") to ``listener.on_start`` / ``on_end``."""
    from numba.core import event  # deferred: called once numba is set up (numba_dispatcher)

    class CompileEvents(event.Listener):
        def on_start(self, ev):
            listener.on_start(ev)

        def on_end(self, ev):
            listener.on_end(ev)

    listener.numba_adapter = CompileEvents()
    event.register("numba:compile", listener.numba_adapter)


@contextmanager
def compile_events(listener):
    """``listener.on_start(ev)`` / ``on_end(ev)`` for every kernel numba compiles in the block,
    whether numba is set up already or a kernel's first JIT call sets it up inside the block."""
    listener.numba_adapter = None
    WATCHING.append(listener)
    if NUMBA_SET_UP:
        register_listener(listener)
    try:
        yield listener
    finally:
        WATCHING.remove(listener)
        if listener.numba_adapter is not None:
            from numba.core import event  # deferred: imported already (an adapter exists)

            event.unregister("numba:compile", listener.numba_adapter)


class Kernel:
    """A solver kernel: its calls from Python run its ahead-of-time export when one was compiled
    for exactly these argument types, else its numba dispatcher, made (and numba imported) on
    the first such call; while the prebuild records, every call is recorded and run by numba.

    numba types a kernel that another kernel calls through ``_numba_type_`` (its dispatcher's
    type), so kernel-to-kernel calls compile as numba dispatcher calls; any other attribute
    (``stats``, ``overloads``, ``signatures``, ``compile``, ...) is the dispatcher's."""

    def __init__(self, fn: Callable, cache: bool = True):
        update_wrapper(self, fn)
        self.py_func = fn
        self.cache = cache
        self.exports = AOT_TABLE.get(kernel_name(fn)) if cache else None
        self._dispatcher = None

    @property
    def dispatcher(self):
        """numba's dispatcher of the kernel (made on first use)."""
        if self._dispatcher is None:
            self._dispatcher = numba_dispatcher(self.py_func, self.cache)
        return self._dispatcher

    @property
    def _numba_type_(self):
        return self.dispatcher._numba_type_

    def __getattr__(self, name):
        if name.startswith("__"):
            raise AttributeError(name)
        return getattr(self.dispatcher, name)

    def __reduce__(self):
        return kernel_by_name, (self.py_func.__module__, self.py_func.__qualname__)

    def __repr__(self):
        return f"Kernel({kernel_name(self.py_func)})"

    def __call__(self, *args, **kwargs):
        if RECORDED is not None and not kwargs:
            record(self, args)  # and run by numba: its overload gives the export's return type
        elif self.exports is not None and not kwargs:
            key = arguments_key(args)
            function = None if key is None else self.exports.get(key)
            if function is not None:
                return run_export(function, args)
        return self.dispatcher(*args, **kwargs)


#: signals whose Python handlers wait until an export returns (``run_export``)
HELD_SIGNALS = (signal.SIGINT, signal.SIGTERM)


def run_export(function: Callable, args: tuple):
    """``function(*args)`` with the Python handlers of HELD_SIGNALS run after it returns.  A pycc
    export boxes a namedtuple result by unpickling its class: Python code inside the compiled call,
    where a pending signal's handler runs; a handler that raises there (Ctrl-C's KeyboardInterrupt,
    the command's SIGTERM) hands the boxing a NULL it does not check: a segmentation fault.  Held
    back, the signal is noted there and its handler runs on return (main thread only: Python runs
    handlers nowhere else)."""
    if threading.current_thread() is not threading.main_thread():
        return function(*args)
    noted, handlers = [], {}
    for number in HELD_SIGNALS:
        handler = signal.getsignal(number)
        if callable(handler):
            handlers[number] = handler
            signal.signal(number, lambda signum, frame: noted.append((signum, frame)))
    try:
        return function(*args)
    finally:
        for number, handler in handlers.items():
            signal.signal(number, handler)
        for signum, frame in noted:
            handlers[signum](signum, frame)


def kernel_by_name(module: str, qualname: str) -> Kernel:
    """The kernel ``module``.``qualname`` (unpickling)."""
    value = importlib.import_module(module)
    for part in qualname.split("."):
        value = getattr(value, part)
    return value


class NumbaValue:
    """A numba object a kernel reads as a global (e.g. a LAPACK binding), made by ``make()`` when
    numba first types a kernel that reads it: numba types it through ``_numba_type_``."""

    def __init__(self, make: Callable):
        self.make = make
        self.value = None

    @property
    def _numba_type_(self):
        if self.value is None:
            self.value = self.make()
        return self.value


def jit(fn: Callable) -> Callable:
    """A solver kernel: numba.njit(cache=True) with the ahead-of-time exports of ``fn``
    (kernel_cache.py caches the JIT code; with NUMBA_DISABLE_JIT=1 the same code runs as plain
    Python, for debugging)."""
    return fn if jit_disabled() else Kernel(fn)


def jit_uncached(fn: Callable) -> Callable:
    """numba.njit(cache=False), made on first use: a kernel that takes another as an argument."""
    return fn if jit_disabled() else Kernel(fn, cache=False)


def record_calls() -> None:
    """Start recording every Python-level kernel call of this process (the prebuild)."""
    global RECORDED
    RECORDED = {}


def record(kernel: Kernel, args: tuple) -> None:
    """Note the call's argument key and numba types; a key seen with other numba types is an
    error of argument_key (it must be at least as fine as numba's typeof)."""
    key = arguments_key(args)
    if key is None or "<locals>" in kernel.py_func.__qualname__:
        return
    numba_types = tuple(kernel.dispatcher.typeof_pyval(arg) for arg in args)
    seen = RECORDED.setdefault((kernel, key), numba_types)
    if seen != numba_types:
        raise AssertionError(f"argument key {key} of {kernel_name(kernel.py_func)} "
                             f"is both {seen} and {numba_types}")


def compile_entries(calls: dict, folder: Path) -> list[dict]:
    """Compile every recorded (kernel, argument types) of ``calls`` into the extension
    ``folder``/MODULE with numba.pycc and write its TABLE -> the table's entries.

    calls : (kernel, argument key) -> tuple of numba argument types, as recorded; a call whose
        types the kernel's dispatcher has no compiled overload of (a literal specialisation) is
        left to the dispatcher."""
    with warnings.catch_warnings():  # pycc is pending deprecation (docs/performance.md says the route)
        warnings.simplefilter("ignore")
        from numba.pycc import CC  # deferred: 0.17 CPU s (setuptools), and only the install compiles
    cc = CC(MODULE)
    cc.output_dir = str(folder)
    cc.target_cpu = "host"  # the JIT's target: built at install on the machine that runs it
    cc.verbose = False
    entries = []
    for (kernel, key), numba_types in calls.items():
        overload = kernel.dispatcher.overloads.get(numba_types)
        if overload is None:
            continue
        name = f"k{len(entries)}"
        cc.export(name, overload.signature.return_type(*numba_types))(kernel.py_func)
        entries.append({"export": name, "kernel": kernel_name(kernel.py_func), "key": key,
                        "types": [str(t) for t in numba_types]})
    folder.mkdir(parents=True, exist_ok=True)
    if entries:
        cc.compile()
    table = {"module": MODULE, "target": host_target(), "cpu_fingerprint": cpu_fingerprint(), "entries": entries}
    (folder / TABLE).write_text(json.dumps(table, indent=1))
    return entries


def compile_recorded(folder: Path | None = None) -> list[dict]:
    """Compile the calls recorded since record_calls() into ``folder`` (default: the kernel
    cache's namespace folder, where setup.py points it into the package)."""
    folder = folder or KERNEL_CACHE / NAMESPACE / AOT_FOLDER
    return compile_entries(RECORDED or {}, folder)


