"""The entry kernels compiled ahead of time (sidprep/solver/equations/aot.py): a Python-level kernel call
runs the export recorded for exactly its argument types, anything else numba's dispatcher, and
both give the same results.

The dispatch rules are tested on an extension compiled here from three small kernels (seconds);
the whole-run comparisons use the extension the install compiled (the installed package's, which
the first import seeds into the kernel cache, as CI installs and then tests from the clone).
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import sysconfig
import time
from pathlib import Path

import numba
import numpy as np
import pytest

from sidprep.solver.equations import aot, kernel_cache
from sidprep.solver.equations.rotations import cross, exp_so3, matmul

ROOT = Path(__file__).resolve().parents[1]
#: AOT and JIT code of one kernel are compiled by the same LLVM for the same CPU from the same
#: typed IR: equal to rounding; the bound a reordering by another inlining decision could reach
AOT_RELATIVE = 1e-12
#: the scenes run both ways (examples the install's prebuild covers)
SCENES = ["examples/flexible_pendulum/scene.toml", "examples/beam_slider_crank/scene.toml"]


def _key(*args):
    return aot.arguments_key(args)


def _can_build_extensions() -> bool:
    """A C compiler and Python's headers: what numba.pycc needs (as the install's prebuild)."""
    headers = Path(sysconfig.get_paths()["include"]) / "Python.h"
    return headers.exists() and any(shutil.which(cc) for cc in ("cc", "gcc", "clang"))


@pytest.fixture(scope="module")
def small_extension(tmp_path_factory) -> Path:
    """exp_so3 (C vector), cross (two C vectors) and matmul (two C matrices) compiled with pycc."""
    if not _can_build_extensions():
        pytest.skip("no C compiler or no Python headers (python3-dev): numba.pycc cannot build here")
    vector, matrix = np.array([0.1, 0.2, 0.3]), np.eye(3)
    calls = {(kernel, _key(*args)): tuple(kernel.typeof_pyval(a) for a in args)
             for kernel, args in [(exp_so3, (vector,)), (cross, (vector, vector)), (matmul, (matrix, matrix))]}
    for (kernel, _), numba_types in calls.items():
        kernel.compile(numba_types)  # the JIT overload (its return type), even where an export serves calls
    folder = tmp_path_factory.mktemp("aot")
    entries = aot.compile_entries(calls, folder)
    assert [entry["export"] for entry in entries] == ["k0", "k1", "k2"]
    return folder


@pytest.fixture
def with_exports(small_extension, monkeypatch):
    """The three kernels dispatching to the small extension."""
    table = aot.read_table(small_extension)
    for kernel in (exp_so3, cross, matmul):
        monkeypatch.setattr(kernel, "exports", table[aot.kernel_name(kernel.py_func)])
    return table


def test_argument_key_separates_what_numba_types_apart():
    c = np.zeros((3, 4))
    fortran, strided = np.asfortranarray(c), c[:, ::2]
    readonly = c.copy()
    readonly.flags.writeable = False
    keys = [_key(a) for a in (c, fortran, strided, readonly, c.astype(np.float32), np.zeros(3))]
    assert len(set(keys)) == len(keys)
    assert [k[0][3] for k in keys[:3]] == ["C", "F", "A"]
    assert _key(1.0) != _key(np.float64(1.0)) != _key(1) != _key(True)
    assert _key(lambda: 0) is None and _key([1.0]) is None and _key(2 ** 64) is None
    assert _key((1.0, c)) == (("t", ("f",), *keys[0]),)


def test_equal_keys_mean_equal_numba_types():
    values = [np.zeros(3), np.ones(3), np.zeros((2, 2)), np.zeros((2, 2), order="F"), np.zeros((4, 4))[:, 1],
              1.0, 2.5, 3, 7, True, np.float64(2.0), np.int32(1), None, (1.0, np.zeros(2)), (0.0, np.ones(2))]
    by_key = {}
    for value in values:
        by_key.setdefault(aot.argument_key(value), set()).add(exp_so3.typeof_pyval(value))
    assert all(len(types) == 1 for types in by_key.values())


def test_an_exact_match_runs_the_export(with_exports):
    vector = np.array([0.3, -0.2, 0.5])
    result = exp_so3(vector)
    assert _key(vector) in exp_so3.exports.functions  # resolved: the export ran
    np.testing.assert_allclose(result, exp_so3.py_func(vector), rtol=AOT_RELATIVE, atol=0)
    a, b = np.arange(6.0).reshape(2, 3), np.arange(12.0).reshape(3, 4)
    np.testing.assert_allclose(matmul(a, b), a @ b, rtol=AOT_RELATIVE)


def test_another_layout_never_reaches_the_export(with_exports):
    vector = np.array([0.3, 9.0, -0.2, 9.0, 0.5, 9.0])[::2]  # layout A
    expected = exp_so3.py_func(vector.copy())
    np.testing.assert_allclose(exp_so3(vector), expected, rtol=AOT_RELATIVE)
    assert _key(vector) not in exp_so3.exports.functions
    # why: pycc's unboxing takes the strided vector as C order and reads the wrong elements
    export = exp_so3.exports.get(_key(vector.copy()))
    assert not np.allclose(export(vector), expected)
    a, b = np.asfortranarray(np.arange(6.0).reshape(2, 3)), np.arange(12.0).reshape(3, 4)
    np.testing.assert_allclose(matmul(a, b), a @ b, rtol=AOT_RELATIVE)
    assert _key(a, b) not in matmul.exports.functions


def test_other_types_and_keywords_go_to_numba(with_exports):
    readonly = np.array([0.3, -0.2, 0.5])
    readonly.flags.writeable = False
    np.testing.assert_allclose(exp_so3(readonly), exp_so3.py_func(readonly), rtol=AOT_RELATIVE)
    np.testing.assert_allclose(cross(a=np.ones(3), b=np.arange(3.0)), np.cross(np.ones(3), np.arange(3.0)))
    assert set(exp_so3.exports.functions) <= {_key(np.zeros(3))} and not cross.exports.functions


def test_a_table_of_another_machine_is_ignored(small_extension, tmp_path):
    other = tmp_path / "other"
    shutil.copytree(small_extension, other)
    table = json.loads((other / aot.TABLE).read_text())
    table["target"]["cpu"] = "another-cpu"
    if table["cpu_fingerprint"] is not None:  # Linux: the fingerprint decides, without llvmlite
        assert len(aot.read_table(small_extension)) == 3
        table["cpu_fingerprint"] = "0" * 64
    (other / aot.TABLE).write_text(json.dumps(table))
    assert aot.read_table(other) == {}
    table["cpu_fingerprint"] = None  # no fingerprint: LLVM's host target decides
    (other / aot.TABLE).write_text(json.dumps(table))
    assert aot.read_table(other) == {}
    assert len(aot.read_table(small_extension)) == 3


def _aot_kernels_in_a_process(cache: Path, switch: str) -> int:
    code = "from sidprep.solver.equations import aot; print(len(aot.AOT_TABLE))"
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache), "PYTHONPATH": str(ROOT), aot.SWITCH: switch}
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    return int(done.stdout)


def test_the_switch_turns_the_exports_off(small_extension, tmp_path):
    namespace = tmp_path / kernel_cache.NAMESPACE
    shutil.copytree(small_extension, namespace / aot.AOT_FOLDER)
    kernel_cache.mark_seeded(namespace, kernel_cache.shipped_kernels())
    assert _aot_kernels_in_a_process(tmp_path, "1") == 3
    assert _aot_kernels_in_a_process(tmp_path, "0") == 0


def test_the_prebuild_records_calls_from_python(with_exports, monkeypatch):
    monkeypatch.setattr(aot, "RECORDED", {})
    vector = np.array([0.1, 0.2, 0.3])
    exp_so3(vector)
    matmul(np.eye(3), np.eye(3)[:, :2])  # an A-layout argument: recorded as such
    assert aot.RECORDED[(exp_so3, _key(vector))] == (exp_so3.typeof_pyval(vector),)
    assert (matmul, _key(np.eye(3), np.eye(3)[:, :2])) in aot.RECORDED
    # recorded calls run numba's overloads (the return types of the exports), not the exports
    assert not exp_so3.exports.functions and exp_so3.overloads.get((exp_so3.typeof_pyval(vector),))


#: a child process: run a scene, print how many exports ran, save every output array
RUN_SCENE = """
import sys
import numpy as np
from sidprep.solver.equations import aot
from sidprep.solver.scene import load_scene, simulate
result = simulate(load_scene(sys.argv[1]))
arrays = {}
def walk(value, path):
    if isinstance(value, np.ndarray) and value.dtype.kind in "fiub":
        arrays[path] = value
    elif isinstance(value, dict):
        for k, v in value.items():
            walk(v, f"{path}/{k}")
    elif hasattr(value, "__dict__"):
        for k, v in vars(value).items():
            walk(v, f"{path}/{k}")
walk(result, "")
np.savez(sys.argv[2], **arrays)
print(sum(len(exports.functions) for exports in aot.AOT_TABLE.values()))
"""


def _run_scene(scene: str, out: Path, switch: str) -> int:
    env = {**os.environ, "PYTHONPATH": str(ROOT), aot.SWITCH: switch}
    done = subprocess.run([sys.executable, "-c", RUN_SCENE, scene, str(out)], env=env, cwd=ROOT,
                          capture_output=True, text=True, timeout=1800)
    assert done.returncode == 0, done.stderr[-2000:]
    return int(done.stdout.split()[-1])


@pytest.mark.skipif(not aot.AOT_TABLE, reason="no ahead-of-time extension in this environment "
                    "(an editable install or a checkout: `pip install .` compiles it)")
@pytest.mark.parametrize("scene", SCENES)
def test_ahead_of_time_and_jit_runs_agree(scene, tmp_path):
    exports_run = _run_scene(scene, tmp_path / "aot.npz", "1")
    assert exports_run > 0  # the entry kernels of the run were the extension's
    assert _run_scene(scene, tmp_path / "jit.npz", "0") == 0
    with np.load(tmp_path / "aot.npz") as ahead, np.load(tmp_path / "jit.npz") as jit:
        assert sorted(ahead.files) == sorted(jit.files) and len(ahead.files) > 10
        for name in ahead.files:
            scale = max(np.max(np.abs(jit[name]), initial=0.0), 1e-300)
            np.testing.assert_allclose(ahead[name], jit[name], rtol=0, atol=AOT_RELATIVE * scale, err_msg=name)


def test_an_installed_extension_is_the_one_tested():
    """CI installs the package (which compiles the extension) and tests from the clone: the
    clone's solver then has the install's namespace, and the first import seeded the extension."""
    shipped = kernel_cache.shipped_kernels()
    if shipped is None or os.environ.get(aot.SWITCH) == "0":
        pytest.skip("no installed package compiled from this source (or SIDPREP_AOT=0)")
    assert (shipped / aot.AOT_FOLDER / aot.TABLE).exists(), (
        "the install compiled no ahead-of-time kernels: a C compiler and Python's headers (python3-dev)?")
    assert aot.AOT_TABLE, (f"the installed extension is not reached by the tests: tables looked for in "
                           f"{aot.table_folders()}, the cache's seed mark "
                           f"{(kernel_cache.KERNEL_CACHE / kernel_cache.NAMESPACE / kernel_cache.SEEDED_MARK)}")


def test_kernels_stay_numba_dispatchers_to_their_callers():
    """numba types a kernel global as a Dispatcher and compiles calls to it into the caller."""
    assert isinstance(numba.typeof(cross), numba.types.Dispatcher)  # through Kernel._numba_type_
    caller = numba.njit(lambda a, b: cross(a, b)[2] + exp_so3(a)[0, 0])
    a, b = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
    assert caller(a, b) == pytest.approx(1.0 + exp_so3.py_func(a)[0, 0], rel=AOT_RELATIVE)


#: a child process: the solver imported without numba; a kernel's first JIT call inside a watched
#: block imports numba and reports its compilation to the listener
FIRST_JIT = """
import sys
import sidprep.solver.scene
from sidprep.solver.equations import aot
before = "numba" in sys.modules
class Listener:
    starts = 0
    def on_start(self, ev):
        self.starts += 1
    def on_end(self, ev):
        pass
listener = Listener()
with aot.compile_events(listener):
    value = aot.jit_uncached(lambda x: x + 1.0)(1.0)
print(before, listener.starts, value)
"""


def test_the_solver_imports_without_numba_and_reports_its_compilations(tmp_path):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path), "PYTHONPATH": str(ROOT)}
    done = subprocess.run([sys.executable, "-c", FIRST_JIT], env=env, capture_output=True, text=True, check=True)
    before, starts, value = done.stdout.split()
    assert before == "False" and int(starts) >= 1 and float(value) == 2.0


def test_a_signal_during_an_export_is_handled_after_it_returns():
    """A pycc export that boxes a namedtuple runs Python code inside the compiled call; a handler
    raising there crashed the process (SIGTERM to `sidprep simulate` ended in a segmentation
    fault).  run_export holds the handlers back: the call finishes, then the handler runs."""
    finished = []

    def export():
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.05)  # the interpreter runs pending handlers here: the noted one, which returns
        finished.append(True)
        return "result"

    inherited = signal.signal(signal.SIGINT, signal.default_int_handler)  # SIG_IGN in a background job
    try:
        with pytest.raises(KeyboardInterrupt):
            aot.run_export(export, ())
        assert finished == [True]
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
        assert aot.run_export(lambda a, b: a + b, (1, 2)) == 3
    finally:
        signal.signal(signal.SIGINT, inherited)
