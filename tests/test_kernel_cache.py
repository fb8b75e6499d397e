"""The kernel cache (sidprep/solver/equations/kernel_cache.py): one namespace per solver source text,
wherever the sources lie; seeded once from the kernels the install compiled."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from importlib import metadata
from pathlib import Path

from sidprep.solver.equations import kernel_cache
from sidprep.solver.equations.kernel_cache import SEEDED_MARK, kernel_locator, source_namespace
from sidprep.solver.equations.rotations import skew

ROOT = Path(__file__).resolve().parents[1]


def test_namespace_follows_the_source_text_not_its_place(tmp_path):
    one, two = tmp_path / "one", tmp_path / "two"
    shutil.copytree(kernel_cache.SOLVER_ROOT, one, ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copytree(kernel_cache.SOLVER_ROOT, two, ignore=shutil.ignore_patterns("__pycache__"))
    assert source_namespace(one) == source_namespace(two) == kernel_cache.NAMESPACE
    (two / "_kernels").mkdir()  # the compiled kernels of an install are not part of the text
    (two / "_kernels" / "x.py").write_text("@jit\n")
    scene = two / "scene.py"  # nor are the descriptions: no kernel reads them
    scene.write_text(scene.read_text() + "\n")
    assert source_namespace(two) == kernel_cache.NAMESPACE
    callee = two / "equations" / "body.py"  # an edit anywhere: every kernel may inline it
    callee.write_text(callee.read_text() + "\n")
    assert source_namespace(two) != kernel_cache.NAMESPACE


def test_solver_kernels_are_located_in_the_namespace():
    kernel_cache.install_kernel_cache()  # what the first JIT compilation does (NUMBA_CACHE_DIR unset)
    KernelLocator = kernel_locator()
    locator = KernelLocator.from_function(skew.py_func, skew.py_func.__code__.co_filename)
    expected = kernel_cache.KERNEL_CACHE / kernel_cache.NAMESPACE / "solver.equations"
    assert Path(locator.get_cache_path()) == expected
    assert KernelLocator.from_function(test_solver_kernels_are_located_in_the_namespace, __file__) is None


def test_seed_copies_the_install_kernels_once_and_keeps_the_users(tmp_path, monkeypatch):
    shipped, cache = tmp_path / "shipped", tmp_path / "cache"
    (shipped / "solver.equations").mkdir(parents=True)
    (shipped / "solver.equations" / "body.f-1.nbi").write_bytes(b"install")
    (shipped / "solver.equations" / "body.g-2.nbi").write_bytes(b"install")
    mine = cache / kernel_cache.NAMESPACE / "solver.equations" / "body.g-2.nbi"
    mine.parent.mkdir(parents=True)
    mine.write_bytes(b"user")
    monkeypatch.setattr(kernel_cache, "KERNEL_CACHE", cache)
    monkeypatch.setattr(kernel_cache, "shipped_kernels", lambda: shipped)
    kernel_cache.seed_cache()
    assert (mine.parent / "body.f-1.nbi").read_bytes() == b"install"
    assert mine.read_bytes() == b"user"
    assert (cache / kernel_cache.NAMESPACE / SEEDED_MARK).exists()
    (mine.parent / "body.f-1.nbi").unlink()
    kernel_cache.seed_cache()  # seeded: not copied again
    assert not (mine.parent / "body.f-1.nbi").exists()
    assert not list(cache.rglob("*.part"))


def test_a_cache_first_used_from_a_checkout_is_seeded_by_a_later_install(tmp_path, monkeypatch):
    """The cache of a namespace run from a checkout is marked with nothing to seed; installing the
    same code later seeds it: the JIT files it lacks, and the install's ahead-of-time folder."""
    shipped, cache = tmp_path / "shipped", tmp_path / "cache"
    (shipped / kernel_cache.AOT_FOLDER).mkdir(parents=True)
    (shipped / kernel_cache.AOT_FOLDER / "table.json").write_text("install")
    (shipped / "solver.equations").mkdir()
    (shipped / "solver.equations" / "body.f-1.nbi").write_bytes(b"install")
    monkeypatch.setattr(kernel_cache, "KERNEL_CACHE", cache)
    monkeypatch.setattr(kernel_cache, "shipped_kernels", lambda: None)
    kernel_cache.seed_cache()  # a checkout's run: nothing installed
    namespace = cache / kernel_cache.NAMESPACE
    (namespace / "solver.equations").mkdir()
    (namespace / "solver.equations" / "body.f-1.nbi").write_bytes(b"user")
    (namespace / kernel_cache.AOT_FOLDER).mkdir()
    (namespace / kernel_cache.AOT_FOLDER / "table.json").write_text("another build")
    monkeypatch.setattr(kernel_cache, "shipped_kernels", lambda: shipped)
    kernel_cache.seed_cache()
    assert (namespace / kernel_cache.AOT_FOLDER / "table.json").read_text() == "install"
    assert (namespace / "solver.equations" / "body.f-1.nbi").read_bytes() == b"user"
    assert (namespace / SEEDED_MARK).read_text() == str(shipped)


def test_a_kernel_compiled_in_one_process_is_loaded_in_the_next(tmp_path):
    code = ("from sidprep.solver.equations.rotations import skew; import numpy as np; skew(np.ones(3)); "
            "print(len(skew.stats.cache_hits))")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path), "PYTHONPATH": str(ROOT)}
    (tmp_path / kernel_cache.NAMESPACE).mkdir()
    # marked as seeded from this process's install: nothing copied (an install may ship skew's)
    kernel_cache.mark_seeded(tmp_path / kernel_cache.NAMESPACE, kernel_cache.shipped_kernels())
    first = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    second = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    assert (first.stdout.strip(), second.stdout.strip()) == ("0", "1")
    assert list((tmp_path / kernel_cache.NAMESPACE / "solver.equations").glob("rotations.skew-*.nbi"))


def test_the_install_kernels_are_found_beside_a_checkouts_own_egg_info(tmp_path, monkeypatch):
    """`pip install .` leaves sidprep.egg-info in the checkout, found first from there (CI's case):
    the installed distribution's kernels are still the ones found."""
    installed = tmp_path / "site-packages"
    (installed / kernel_cache.SHIPPED / kernel_cache.NAMESPACE).mkdir(parents=True)
    checkout = metadata.PathDistribution(tmp_path / "checkout" / "sidprep.egg-info")
    site = metadata.PathDistribution(installed / "sidprep-0.1.0.dist-info")
    monkeypatch.setattr(metadata, "distributions", lambda name=None: iter([checkout, site]))
    assert kernel_cache.shipped_kernels() == installed / kernel_cache.SHIPPED / kernel_cache.NAMESPACE
    monkeypatch.setattr(metadata, "distributions", lambda name=None: iter([checkout]))
    assert kernel_cache.shipped_kernels() is None
