"""The solver's entry kernels compiled ahead of time, and ``jit``, the decorator of every kernel
(docs/performance.md, "Fourth pass: entry kernels ahead of time").

The install's prebuild (solver/prebuild.py) runs the example scenes and records every kernel call
made from Python: the kernel and its arguments' types.  numba.pycc compiles each recorded
(kernel, argument types) into one extension module, ``entry_kernels``, beside the shipped JIT
kernels (``<kernel cache>/<NAMESPACE>/aot``), with a table: export name <-> kernel <-> argument
key.  A kernel called from Python then runs its ahead-of-time export when the call's argument key
equals a recorded one exactly, else numba's dispatcher as before (it compiles or loads from the
JIT cache): a scene no example covers, a function argument, ``SIDPREP_AOT=0``,
``NUMBA_DISABLE_JIT=1``, a checkout without an install.

Calls between kernels never pass through here: each kernel is a numba dispatcher (a subclass
whose Python-level ``__call__`` looks the table up first), so numba types kernel-to-kernel calls
as before and compiles them into the caller.

The argument key is a finer classification than numba's own ``typeof`` of an argument (an array:
dtype, ndim, C/F/A layout, read-only; a scalar: its Python or numpy type; tuples and namedtuples
member by member, with the namedtuple's class), so equal keys mean equal numba types, and an
array of another layout never reaches an export compiled for C order (pycc's unboxing does not
check the layout).  The prebuild checks that the key determines the numba types on every call it
records.
"""

from __future__ import annotations

import importlib.machinery
import importlib.util
import json
import os
import warnings
from collections.abc import Callable, Iterable
from pathlib import Path

import numpy as np
from llvmlite import binding as llvm
from numba.core import config, registry

from sidprep.solver.equations.kernel_cache import KERNEL_CACHE, NAMESPACE, SOLVER_ROOT, install_kernel_cache

#: the extension module of the entry kernels, and its file's suffix (this interpreter's ABI)
MODULE = "entry_kernels"
EXTENSION_SUFFIX = importlib.machinery.EXTENSION_SUFFIXES[0]
#: the folder of the extension and its table inside a namespace folder
AOT_FOLDER = "aot"
#: the table of the exports: export name <-> kernel <-> argument key
TABLE = "table.json"
#: the environment variable that turns the ahead-of-time kernels off ("0") for comparisons
SWITCH = "SIDPREP_AOT"
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
    return {"triple": llvm.get_process_triple(), "cpu": llvm.get_host_cpu_name(),
            "features": llvm.get_host_cpu_features().flatten(), "suffix": EXTENSION_SUFFIX}


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
    package's own folder (an installed package whose cache could not be written)."""
    return [KERNEL_CACHE / NAMESPACE / AOT_FOLDER, SOLVER_ROOT / "_kernels" / NAMESPACE / AOT_FOLDER]


def read_table(folder: Path) -> dict[str, Exports]:
    """kernel name -> its Exports, from ``folder``/TABLE; empty if there is no table or it was
    compiled for another machine."""
    try:
        table = json.loads((folder / TABLE).read_text())
    except (OSError, ValueError):
        return {}
    if table.get("target") != host_target():
        return {}
    extension = EntryKernels(folder)
    kernels: dict[str, Exports] = {}
    for entry in table["entries"]:
        kernels.setdefault(entry["kernel"], Exports(extension)).names[as_key(entry["key"])] = entry["export"]
    return kernels


def load_table() -> dict[str, Exports]:
    """The ahead-of-time exports of this process's kernels (none with SIDPREP_AOT=0)."""
    if os.environ.get(SWITCH, "1") == "0" or config.DISABLE_JIT:
        return {}
    for folder in table_folders():
        kernels = read_table(folder)
        if kernels:
            return kernels
    return {}


install_kernel_cache()  # numba's cache of the kernels set up (and seeded) before any is declared
#: kernel name -> Exports of this process
AOT_TABLE = load_table()
#: (dispatcher, argument key) -> numba argument types of every Python-level call, while the
#: prebuild records (record_calls); None otherwise
RECORDED: dict | None = None


class KernelDispatcher(registry.CPUDispatcher):
    """numba's CPU dispatcher of a kernel, whose calls from Python run the kernel's ahead-of-time
    export when one was compiled for exactly these argument types (while the prebuild records,
    they are recorded and run by numba, so that a rebuild in a cache with a table is complete)."""

    exports: Exports | None = None

    def __call__(self, *args, **kwargs):
        if RECORDED is not None and not kwargs:
            record(self, args)  # and compiled by numba: its overload gives the export's return type
        elif self.exports is not None and not kwargs:
            key = arguments_key(args)
            function = None if key is None else self.exports.get(key)
            if function is not None:
                return function(*args)
        return super().__call__(*args, **kwargs)


def jit(fn: Callable) -> Callable:
    """numba.njit(cache=True) with the ahead-of-time exports of ``fn`` (kernel_cache.py caches
    the JIT code; with NUMBA_DISABLE_JIT=1 the same code runs as plain Python, for debugging)."""
    if config.DISABLE_JIT:
        return fn
    dispatcher = KernelDispatcher(py_func=fn, locals={}, targetoptions={"nopython": True})
    dispatcher.enable_caching()
    dispatcher.exports = AOT_TABLE.get(kernel_name(fn))
    return dispatcher


def record_calls() -> None:
    """Start recording every Python-level kernel call of this process (the prebuild)."""
    global RECORDED
    RECORDED = {}


def record(dispatcher: KernelDispatcher, args: tuple) -> None:
    """Note the call's argument key and numba types; a key seen with other numba types is an
    error of argument_key (it must be at least as fine as numba's typeof)."""
    key = arguments_key(args)
    if key is None or "<locals>" in dispatcher.py_func.__qualname__:
        return
    numba_types = tuple(dispatcher.typeof_pyval(arg) for arg in args)
    seen = RECORDED.setdefault((dispatcher, key), numba_types)
    if seen != numba_types:
        raise AssertionError(f"argument key {key} of {kernel_name(dispatcher.py_func)} "
                             f"is both {seen} and {numba_types}")


def compile_entries(calls: dict, folder: Path) -> list[dict]:
    """Compile every recorded (kernel, argument types) of ``calls`` into the extension
    ``folder``/MODULE with numba.pycc and write its TABLE -> the table's entries.

    calls : (dispatcher, argument key) -> tuple of numba argument types, as recorded; a call
        whose types the dispatcher has no compiled overload of (a literal specialisation) is left
        to the dispatcher."""
    with warnings.catch_warnings():  # pycc is pending deprecation (docs/performance.md says the route)
        warnings.simplefilter("ignore")
        from numba.pycc import CC  # deferred: 0.17 CPU s (setuptools), and only the install compiles
    cc = CC(MODULE)
    cc.output_dir = str(folder)
    cc.target_cpu = "host"  # the JIT's target: built at install on the machine that runs it
    cc.verbose = False
    entries = []
    for (dispatcher, key), numba_types in calls.items():
        overload = dispatcher.overloads.get(numba_types)
        if overload is None:
            continue
        name = f"k{len(entries)}"
        cc.export(name, overload.signature.return_type(*numba_types))(dispatcher.py_func)
        entries.append({"export": name, "kernel": kernel_name(dispatcher.py_func), "key": key,
                        "types": [str(t) for t in numba_types]})
    folder.mkdir(parents=True, exist_ok=True)
    if entries:
        cc.compile()
    table = {"module": MODULE, "target": host_target(), "entries": entries}
    (folder / TABLE).write_text(json.dumps(table, indent=1))
    return entries


def compile_recorded(folder: Path | None = None) -> list[dict]:
    """Compile the calls recorded since record_calls() into ``folder`` (default: the kernel
    cache's namespace folder, where setup.py points it into the package)."""
    folder = folder or KERNEL_CACHE / NAMESPACE / AOT_FOLDER
    return compile_entries(RECORDED or {}, folder)


