"""What the port's comparison tests share: a probe .pyx (Python entries to the core's pointer
kernels) compiled into a module, and the comparison of a result with the numba kernel's."""

import importlib.util
from pathlib import Path

import numpy as np
from Cython.Build import cythonize
from setuptools import Distribution, Extension

ROOT = Path(__file__).resolve().parents[2]
#: kernel against kernel, the same arithmetic in the same order: relative to the largest entry
KERNEL_RTOL = 1e-12


def compile_probe(source: Path, build: Path):
    """The module of the probe ``source`` (.pyx beside its test, cimporting the core), compiled in
    ``build`` with index checks on."""
    name = source.stem
    extension = cythonize([Extension(name, [str(source)])], include_path=[str(ROOT)], build_dir=str(build),
                          quiet=True, compiler_directives={"language_level": 3, "boundscheck": True})
    command = Distribution({"ext_modules": extension}).get_command_obj("build_ext")
    command.build_lib = command.build_temp = str(build)
    command.ensure_finalized()
    command.run()
    spec = importlib.util.spec_from_file_location(name, command.get_ext_fullpath(name))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def close(x, ref, rtol=KERNEL_RTOL) -> bool:
    """Whether x equals ref to rtol of ref's largest entry (equal where ref is zero)."""
    x, ref = np.asarray(x, float), np.asarray(ref, float)
    return x.shape == ref.shape and np.max(np.abs(x - ref), initial=0.0) <= rtol * np.max(np.abs(ref), initial=0.0)
