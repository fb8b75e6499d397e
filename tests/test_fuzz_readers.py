"""Issue 26 item 9: property-based fuzzing of the readers (hypothesis).

Property of every reader: for any input it returns a value or raises InputError (one line
naming the file); never another exception, a hang or a native crash.  The inputs are valid
files with one to a few damages: a SID_FEM line replaced, deleted or given a wild number; an
HDF5 SID member deleted or replaced by an array of another shape, type or value; scene and job
TOML keys given wild values; tetrahedral meshes with wild coordinates and connectivity.

Profiles (``SIDPREP_FUZZ`` environment variable): ``ci`` (default: FUZZ_CI_EXAMPLES examples
per reader, a few seconds each) and ``long`` (FUZZ_LONG_EXAMPLES per reader, on demand):

    SIDPREP_FUZZ=long python -m pytest -q tests/test_fuzz_readers.py
"""

from __future__ import annotations

import contextlib
import io
import os
import shutil
from pathlib import Path

import h5py
import meshio
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sidprep.errors import InputError
from sidprep.fe.mesh import read_mesh
from sidprep.jobs.jobfile import read_job
from sidprep.reduction.beam import beam_options_from_table, beam_sid
from sidprep.sid.checks import physical_problems, sid_checks
from sidprep.sid.io import read_sid
from sidprep.sid.io.sid_fem import format_sid_fem, parse_sid_fem
from sidprep.sid.io.sid_hdf5 import write_sid_hdf5
from sidprep.solver.scene import load_scene

ROOT = Path(__file__).resolve().parents[1]
#: examples per reader in CI and on demand
FUZZ_CI_EXAMPLES = 25
FUZZ_LONG_EXAMPLES = 1000
settings.register_profile("ci", max_examples=FUZZ_CI_EXAMPLES, deadline=None, derandomize=True,
                          suppress_health_check=list(HealthCheck))
settings.register_profile("long", max_examples=FUZZ_LONG_EXAMPLES, deadline=None,
                          suppress_health_check=list(HealthCheck))
settings.load_profile(os.environ.get("SIDPREP_FUZZ", "ci"))

#: numbers a hostile file writes
WILD_NUMBERS = ["NaN", "nan", "inf", "-inf", "1.0D+999", "-1.0D+999", "1e-320", "0", "-0", "1e308", "-1",
                "12345678901234567890", "0x10", "", "1.0D+", "D", "1,5"]
wild_float = st.one_of(st.sampled_from([np.nan, np.inf, -np.inf, 0.0, -1.0, 1e308, -1e308, 1e-320]),
                       st.floats(allow_nan=True, allow_infinity=True))


@pytest.fixture(scope="module")
def beam():
    """A small analytical Beam SID (2 bending forms) and its SID_FEM text."""
    sid = beam_sid(beam_options_from_table({"length": 1.0, "section": "circle:0.02", "material": "steel",
                                            "modes": "xz:1-2"}, "fuzz"))
    return sid, format_sid_fem(sid)


def reads_or_input_error(read, *args):
    """``read(*args)``, its result checked too (physical_problems, sid_checks); True if it read."""
    try:
        with contextlib.redirect_stdout(io.StringIO()), np.errstate(all="raise", under="ignore"):
            out = read(*args)
    except InputError as exc:
        assert "\n" not in str(exc), str(exc)
        return False
    if hasattr(out, "Me"):               # a SID: its checks must not fail on it either
        with np.errstate(all="raise", under="ignore"):
            physical_problems(out)
            sid_checks(out)
    return True


# ------------------------------------------------------------------------------------------------
# SID_FEM (text)
# ------------------------------------------------------------------------------------------------

@given(data=st.data())
def test_sid_fem_with_damaged_lines(beam, data):
    lines = beam[1].splitlines()
    for _ in range(data.draw(st.integers(1, 3))):
        k = data.draw(st.integers(0, len(lines) - 1))
        action = data.draw(st.sampled_from(["delete", "number", "text", "truncate"]))
        if action == "delete":
            del lines[k]
        elif action == "number" and "=" in lines[k]:
            lines[k] = lines[k].split("=")[0] + "= " + data.draw(st.sampled_from(WILD_NUMBERS))
        elif action == "text":
            lines[k] = data.draw(st.text(max_size=40))
        else:
            lines = lines[:k]
        if not lines:
            break
    reads_or_input_error(parse_sid_fem, "\n".join(lines), "fuzz.SID_FEM")


# ------------------------------------------------------------------------------------------------
# SID HDF5
# ------------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def beam_h5(beam, tmp_path_factory):
    path = tmp_path_factory.mktemp("fuzz") / "beam.sid.h5"
    write_sid_hdf5(beam[0], path)
    with h5py.File(path, "r") as f:
        members = []
        f.visit(members.append)
        attrs = [(name, a) for name in ["/", *members] for a in f[name].attrs]
    return path, members, attrs


def _wild_array(data):
    kind = data.draw(st.sampled_from(["float", "int", "str", "empty", "scalar"]))
    shape = tuple(data.draw(st.lists(st.integers(0, 4), min_size=0, max_size=3)))
    if kind == "str":
        return np.array(["x"] * int(np.prod(shape)), dtype=h5py.string_dtype()).reshape(shape)
    if kind == "empty":
        return np.zeros((0,))
    if kind == "scalar":
        return np.float64(data.draw(wild_float))
    values = [data.draw(wild_float) for _ in range(min(int(np.prod(shape)), 8))]
    a = np.resize(np.array(values or [0.0]), shape)
    return a.astype(int) if kind == "int" and np.isfinite(a).all() and (np.abs(a) < 2**62).all() else a


@given(data=st.data())
def test_sid_hdf5_with_damaged_members(beam_h5, tmp_path_factory, data):
    source, members, attrs = beam_h5
    path = tmp_path_factory.mktemp("h5") / "damaged.sid.h5"
    shutil.copy(source, path)
    with h5py.File(path, "r+") as f:
        for _ in range(data.draw(st.integers(1, 3))):
            if data.draw(st.booleans()):
                name = data.draw(st.sampled_from(members))
                if name in f:
                    del f[name]
                    if data.draw(st.booleans()):
                        f[name] = _wild_array(data)
            else:
                name, attr = data.draw(st.sampled_from(attrs))
                if name in f:
                    f[name].attrs[attr] = _wild_array(data)
    reads_or_input_error(read_sid, path, "off")


# ------------------------------------------------------------------------------------------------
# scene and job TOML
# ------------------------------------------------------------------------------------------------

def _toml_value(data) -> str:
    return data.draw(st.sampled_from(["nan", "inf", "-inf", "1e300", "-1e300", "1e-300", "0", "-5", "true", '""',
                                      '"x"', "[]", "[1, 2]", "[nan, 0, 0]", "{}", "1979-05-27", '"\\u001b[31m"',
                                      "99999999999"]))


def _damaged_toml(text: str, data) -> str:
    """``text`` with 1-3 ``key = value`` lines given wild values."""
    lines = text.splitlines()
    keyed = [k for k, line in enumerate(lines) if "=" in line and not line.lstrip().startswith("#")]
    for _ in range(data.draw(st.integers(1, 3))):
        k = data.draw(st.sampled_from(keyed))
        lines[k] = lines[k].split("=")[0] + "= " + _toml_value(data)
    return "\n".join(lines) + "\n"


SCENES = ["moving_force", "flexible_pendulum", "two_link_manipulator", "slider_crank"]


@given(data=st.data())
def test_scene_toml_with_wild_values(tmp_path_factory, data):
    example = ROOT / "examples" / data.draw(st.sampled_from(SCENES))
    folder = tmp_path_factory.mktemp("scene")
    for f in example.iterdir():
        if f.suffix in (".h5", ".SID_FEM", ".obj"):
            (folder / f.name).symlink_to(f)
    scene = folder / "scene.toml"
    scene.write_text(_damaged_toml((example / "scene.toml").read_text(), data))
    reads_or_input_error(load_scene, scene)


@given(data=st.data())
def test_job_toml_with_wild_values(tmp_path_factory, data):
    folder = tmp_path_factory.mktemp("job")
    text = (ROOT / "examples" / "reduce_job" / "job.toml").read_text()
    job = folder / "job.toml"
    job.write_text(_damaged_toml(text.replace('mesh = "', f'mesh = "{ROOT}/examples/reduce_job/'), data))
    reads_or_input_error(read_job, job)


# ------------------------------------------------------------------------------------------------
# meshes
# ------------------------------------------------------------------------------------------------

@given(data=st.data())
def test_meshes_with_wild_points_and_cells(tmp_path_factory, data):
    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], float)
    cells = np.array([[0, 1, 2, 3], [1, 2, 3, 4]])
    for _ in range(data.draw(st.integers(1, 3))):
        if data.draw(st.booleans()):
            points[data.draw(st.integers(0, 4)), data.draw(st.integers(0, 2))] = data.draw(wild_float)
        else:
            cells[data.draw(st.integers(0, 1)), data.draw(st.integers(0, 3))] = data.draw(st.integers(-3, 8))
    fmt = data.draw(st.sampled_from(["vtu", "msh"]))
    path = tmp_path_factory.mktemp("mesh") / f"fuzz.{fmt}"
    try:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            meshio.write_points_cells(path, points, [("tetra", cells)],
                                      **({"file_format": "gmsh22", "binary": False} if fmt == "msh" else {}))
    except Exception:                    # noqa: BLE001  meshio refuses to write it: nothing to read
        return
    reads_or_input_error(read_mesh, path)
