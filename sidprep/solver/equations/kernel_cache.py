"""Where the compiled kernels live on disk: one cache of every way in (tests, the CLI, the API,
batch and Dask workers), keyed by the solver's source text, and seeded from the kernels that the
install compiled (docs/performance.md, "First run").

numba's own cache is keyed by each source file's absolute folder and checked against that file
alone: a checkout, a worktree and an install of the same code compile three times, and a kernel
whose callee changed in another file is loaded stale.  Here every solver kernel is cached under
one *namespace*, the hash of all the solver's kernel files: the same code shares one set of
compiled kernels wherever it lies, and any edit of a kernel file compiles every kernel afresh.

The install (``pip install .``, setup.py) compiles the kernels once into the package
(``sidprep/solver/_kernels/<namespace>``), with the entry kernels compiled ahead of time
(``aot/``, aot.py); the first import of an installed solver copies them into the user's cache,
so the first run loads instead of compiling.  numba itself is imported only when a kernel is
JIT-compiled or loaded (kernel_locator, install_kernel_cache).
"""

from __future__ import annotations

import hashlib
import os
import shutil
from importlib import metadata
from pathlib import Path


#: the solver's source folder (sidprep/solver/ in a checkout, sidprep/solver when installed)
SOLVER_ROOT = Path(__file__).resolve().parents[1]
#: the user's kernel cache: NUMBA_CACHE_DIR when set, else the user's cache folder
KERNEL_CACHE = Path(os.environ.get("NUMBA_CACHE_DIR") or Path(
    os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "sidprep" / "numba")
#: the folder, inside the installed package, of the kernels compiled by the install
SHIPPED = "sidprep/solver/_kernels"
#: written into a namespace folder once it has been seeded: the install folder it was seeded from
SEEDED_MARK = ".seeded"
#: the folder of the ahead-of-time entry kernels inside a namespace folder (aot.py)
AOT_FOLDER = "aot"


def source_namespace(root: Path = SOLVER_ROOT) -> str:
    """'kernels-<sha256 of every solver file that declares kernels (``@jit``), path and text>'
    (16 hex digits).  A compiled kernel holds the code of the kernels it calls and the constants
    it reads, so kernel constants live in kernel files."""
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        text = path.read_bytes()
        if b"@jit" not in text or "_kernels" in path.parts:
            continue
        digest.update(path.relative_to(root).as_posix().encode())
        digest.update(text)
    return "kernels-" + digest.hexdigest()[:16]


NAMESPACE = source_namespace()


def kernel_locator() -> type:
    """numba's cache locator of the solver's kernels: KERNEL_CACHE / NAMESPACE / <module folder>
    (a class made when numba is first needed: a run served by the ahead-of-time kernels never
    imports numba, aot.py)."""
    from numba.core import caching  # deferred: import numba 0.17 CPU s, only when a kernel is JIT-compiled

    base = caching.UserProvidedCacheLocator if hasattr(caching, "UserProvidedCacheLocator") \
        else caching._UserProvidedCacheLocator

    class KernelLocator(base):
        def __init__(self, py_func, py_file):
            super().__init__(py_func, py_file)
            folder = Path(py_file).resolve().parent.relative_to(SOLVER_ROOT)
            self._cache_path = str(KERNEL_CACHE / NAMESPACE / ("solver." + ".".join(folder.parts)).rstrip("."))

        @classmethod
        def from_function(cls, py_func, py_file):
            if not Path(py_file).resolve().is_relative_to(SOLVER_ROOT):
                return None
            return super().from_function(py_func, py_file)

    return KernelLocator


def shipped_kernels() -> Path | None:
    """The installed distribution's compiled kernels of this NAMESPACE, if it has them.  Every
    distribution named sidprep is asked: a checkout that was installed from (``pip install .``, as
    CI does) keeps a ``sidprep.egg-info`` of its own, found first from the checkout's folder."""
    for dist in metadata.distributions(name="sidprep"):
        folder = Path(dist.locate_file(SHIPPED)) / NAMESPACE
        if folder.is_dir():
            return folder
    return None


def seed_label(source: Path | None) -> str:
    """What a namespace's SEEDED_MARK holds: the install folder it was seeded from ('' for none)."""
    return "" if source is None else str(source)


def mark_seeded(target: Path, source: Path | None) -> None:
    """Write ``target``'s SEEDED_MARK: seeded from ``source`` (None: nothing was installed)."""
    (target / SEEDED_MARK).write_text(seed_label(source))


def seed_cache() -> None:
    """Copy the install's compiled kernels into KERNEL_CACHE / NAMESPACE once per install folder.

    The mark names the folder it was seeded from, so a cache first used from a checkout (nothing
    to seed) is seeded when the same code is installed later.  JIT files the cache already has
    are kept (the user's own compilations); the ahead-of-time folder is the install's build and
    replaces the cache's.  One stat and one metadata lookup (~0.2 ms) once seeded.
    """
    target = KERNEL_CACHE / NAMESPACE
    source = shipped_kernels()
    try:
        if (target / SEEDED_MARK).read_text() == seed_label(source):
            return
    except OSError:
        pass
    try:
        target.mkdir(parents=True, exist_ok=True)
        if source is not None:
            for path in source.rglob("*"):
                relative = path.relative_to(source)
                dest = target / relative
                if path.is_file() and (relative.parts[0] == AOT_FOLDER or not dest.exists()):
                    dest.parent.mkdir(parents=True, exist_ok=True)
                    part = dest.with_name(dest.name + f".{os.getpid()}.part")
                    shutil.copyfile(path, part)
                    os.replace(part, dest)
        mark_seeded(target, source)
    except OSError:  # a read-only cache: numba compiles in memory, as without a cache
        pass


def install_kernel_cache() -> None:
    """Point numba's cache of the solver kernels at KERNEL_CACHE / NAMESPACE (once per process,
    before the first kernel's numba dispatcher is made); seed_cache() has run at import."""
    from numba.core import caching, config  # deferred: import numba 0.17 CPU s, only when a kernel is JIT-compiled

    impl = caching.CacheImpl if hasattr(caching, "CacheImpl") else caching._CacheImpl
    if not any(getattr(locator, "solver_kernels", False) for locator in impl._locator_classes):
        locator = kernel_locator()
        locator.solver_kernels = True
        impl._locator_classes.insert(0, locator)
    if not config.CACHE_DIR:  # read by the locator's base class
        config.CACHE_DIR = str(KERNEL_CACHE)
