"""The install compiles the solver's kernels into the package, as a compiled core ships with its
library (docs/performance.md, "First run"): the JIT kernels of numba's cache, and the kernels
called from Python ahead of time into one extension module (solver/equations/aot.py; it needs a C
compiler and Python's headers, else the JIT kernels serve alone).  The first ``sidprep simulate``
then loads them.

Everything else about the package is in pyproject.toml.  ``SIDPREP_PREBUILD=0`` skips the
compilation (the kernels then compile on first use), ``SIDPREP_AOT=0`` only the extension;
editable installs always skip it.
"""

import glob
import os
import shutil
import subprocess
import sys
from pathlib import Path

from setuptools import Distribution, setup
from setuptools.command.build_py import build_py


def prebuild_enabled() -> bool:
    """Whether the install compiles the kernels (SIDPREP_PREBUILD=0 skips it)."""
    return os.environ.get("SIDPREP_PREBUILD", "1") != "0"


class BuildWithKernels(build_py):
    """build_py, then a few steps of every bundled example scene with every method, compiled
    into build_lib/sidprep/solver/_kernels (sidprep.solver.prebuild): numba's cache and the
    entry-kernel extension, both under the kernel source's namespace."""

    def run(self):
        super().run()
        if getattr(self, "editable_mode", False) or not prebuild_enabled():
            return
        lib = Path(self.build_lib).resolve()
        kernels = lib / "sidprep" / "solver" / "_kernels"
        shutil.rmtree(kernels, ignore_errors=True)  # an earlier build's kernels, of other sources
        scenes = sorted(glob.glob("examples/*/scene*.toml"))
        # the built package first, then this process's path: pip's isolated build environment
        # (numpy, numba, scipy, h5py of [build-system] requires) reaches the child through it
        path = os.pathsep.join([str(lib), *filter(None, [os.environ.get("PYTHONPATH")]), *sys.path])
        env = {**os.environ, "PYTHONPATH": path, "NUMBA_CACHE_DIR": str(kernels)}
        print(f"compiling the solver kernels on {len(scenes)} example scenes (SIDPREP_PREBUILD=0 skips) ...",
              flush=True)
        done = subprocess.run([sys.executable, "-m", "sidprep.solver.prebuild", *scenes], env=env)
        if done.returncode:
            print("warning: the solver kernels were not compiled at install; they compile on first use",
                  file=sys.stderr)


class KernelDistribution(Distribution):
    """A wheel with compiled kernels holds machine code for this interpreter and platform: it is
    tagged as such (e.g. cp311-cp311-linux_x86_64), not as a pure-Python py3-none-any wheel."""

    def has_ext_modules(self):
        return prebuild_enabled()


setup(cmdclass={"build_py": BuildWithKernels}, distclass=KernelDistribution)
