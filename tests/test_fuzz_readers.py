"""Property-based fuzzing of the readers (hypothesis).

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


# ------------------------------------------------------------------------------------------------
# matrix files of other FE codes: every reader returns finite K, M (and eigenvalues) or InputError
# ------------------------------------------------------------------------------------------------

#: numbers a damaged matrix file holds (text), and their binary twins (.eig)
WILD_MATRIX_NUMBERS = ["1.0e999", "-1.0D+999", "1e308", "NaN", "inf", "1e-320", "0", "-0.0"]
WILD_DOUBLES = [np.nan, np.inf, -np.inf, 1e308, -1e308, 0.0, 1e-320]
#: a spring k = 1e3 N/m in x between nodes 1 and 2 and 0.5 kg per node, in each text format
SPRING_FILES = {
    "mtx": {"j_STIF1.mtx": "** stiffness\n1,1, 1,1, 1.0e3\n1,1, 2,1, -1.0e3\n2,1, 2,1, 1.0e3\n",
            "j_MASS1.mtx": "1,1, 1,1, 0.5\n2,1, 2,1, 0.5\n"},
    "pch": {"s.pch": "DMIG,KAAX,0,6,2,0,,,2\nDMIG,KAAX,1,1,,1,1,1.0+3\nDMIG,KAAX,2,1,,1,1,-1.0+3\n"
                     "DMIG,KAAX,2,1,,2,1,1.0D+3\nDMIG,MAAX,0,6,2,0,,,2\nDMIG,MAAX,1,1,,1,1,0.5\n"
                     "DMIG,MAAX,2,1,,2,1,0.5\n"},
    "sti": {"c.sti": "1 1 1.0e3\n1 2 -1.0e3\n2 2 1.0e3\n", "c.mas": "1 1 0.5\n2 2 0.5\n", "c.dof": "1.1\n2.1\n"},
}
#: one C3D4 element: the deck beside a CalculiX .eig file (its matrix structure)
TET_DECK = ("*NODE, NSET=NALL\n1, 0, 0, 0\n2, 1, 0, 0\n3, 0, 1, 0\n4, 0, 0, 1\n*ELEMENT, TYPE=C3D4, ELSET=EALL\n"
            "1, 1, 2, 3, 4\n")


def finite_matrices_or_input_error(path) -> None:
    from sidprep.fe.matrices import read_matrices

    try:
        with contextlib.redirect_stdout(io.StringIO()):
            fe = read_matrices(path)
    except InputError as exc:
        assert "\n" not in str(exc) and str(path.parent) in str(exc), str(exc)
        return
    for A in (fe.K, fe.M):
        assert np.isfinite(A.data).all()
    assert fe.eigenvalues is None or np.isfinite(fe.eigenvalues).all()


@given(data=st.data())
def test_text_matrix_files_with_wild_numbers(tmp_path_factory, data):
    fmt = data.draw(st.sampled_from(sorted(SPRING_FILES)))
    folder = tmp_path_factory.mktemp("matrices")
    files = dict(SPRING_FILES[fmt])
    for _ in range(data.draw(st.integers(1, 2))):
        name = data.draw(st.sampled_from(sorted(n for n in files if not n.endswith(".dof"))))
        tokens = files[name].replace("\n", " \n ").split(" ")
        numbers = [k for k, t in enumerate(tokens) if any(c.isdigit() for c in t) and "." in t]
        k = data.draw(st.sampled_from(numbers))
        tokens[k] = data.draw(st.sampled_from(WILD_MATRIX_NUMBERS))
        files[name] = " ".join(tokens).replace(" \n ", "\n")
    for name, text in files.items():
        (folder / name).write_text(text)
    finite_matrices_or_input_error(folder / next(iter(files)))


def eig_file(folder: Path, rng) -> Path:
    """A CalculiX STORAGE=YES .eig file of the one-tet deck (layout: sidprep.fe.matrices.calculix):
    2 eigenvalues, K and M (diagonal + strict lower triangle), 2 eigenvectors."""
    from sidprep.fe.matrices.calculix import lower_structure

    (folder / "tet.inp").write_text(TET_DECK)
    cols, _ = lower_structure([np.array([[1, 2, 3, 4]])], np.array([1, 2, 3, 4]))
    neq, nzs, nev = 12, len(cols), 2
    body = np.concatenate([[1.0, 4.0], rng.uniform(1, 2, neq), rng.uniform(-0.1, 0.1, nzs),
                           rng.uniform(1, 2, neq), rng.uniform(-0.1, 0.1, nzs), rng.uniform(-1, 1, nev * neq)])
    path = folder / "tet.eig"
    path.write_bytes(np.array([0, 1, 0, nev], np.int32).tobytes() + body.tobytes())
    return path


@given(data=st.data())
def test_calculix_eig_files_with_wild_doubles(tmp_path_factory, data):
    path = eig_file(tmp_path_factory.mktemp("eig"), np.random.default_rng(data.draw(st.integers(0, 2**16))))
    raw = bytearray(path.read_bytes())
    for _ in range(data.draw(st.integers(1, 3))):
        k = data.draw(st.integers(0, (len(raw) - 16) // 8 - 1))
        raw[16 + 8 * k:24 + 8 * k] = np.float64(data.draw(st.sampled_from(WILD_DOUBLES))).tobytes()
    path.write_bytes(bytes(raw))
    finite_matrices_or_input_error(path)


def test_the_undamaged_matrix_files_read(tmp_path):
    """The sources of the two properties above are valid files: their damage is what is refused."""
    from sidprep.fe.matrices import read_matrices

    for fmt, files in SPRING_FILES.items():
        for name, text in files.items():
            (tmp_path / name).write_text(text)
        assert read_matrices(tmp_path / next(iter(files))).K.nnz == 4, fmt
    fe = read_matrices(eig_file(tmp_path, np.random.default_rng(0)))
    assert fe.K.shape == (12, 12) and list(fe.eigenvalues) == [1.0, 4.0]


@pytest.mark.parametrize("value", ["nan", "inf"])
def test_a_non_finite_eig_entry_is_named_before_any_eigensolver(tmp_path, value):
    path = eig_file(tmp_path, np.random.default_rng(1))
    raw = bytearray(path.read_bytes())
    raw[16 + 8 * 2:16 + 8 * 3] = np.float64(value).tobytes()           # K's first diagonal entry
    path.write_bytes(bytes(raw))
    from sidprep.fe.matrices import read_matrices

    with pytest.raises(InputError, match=rf"tet\.eig: the stiffness matrix holds 1 non-finite entries \(first: "
                                         rf"{value} at node 1 DOF 1, node 1 DOF 1\)"):
        read_matrices(path)


# ------------------------------------------------------------------------------------------------
# the /stress group of a SID HDF5 file
# ------------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def stress_h5(beam, tmp_path_factory):
    assert beam[0].stress is not None
    path = tmp_path_factory.mktemp("stress") / "beam.sid.h5"
    write_sid_hdf5(beam[0], path)
    return path


@given(data=st.data())
def test_sid_stress_group_with_wild_members(stress_h5, tmp_path_factory, data):
    """Whatever /stress holds, reading the SID for a stress recovery gives consistent, finite modal
    stresses or one InputError (never a silent wrong shape or NaN)."""
    from sidprep.sid.checks import stress_problem

    path = tmp_path_factory.mktemp("h5") / "damaged.sid.h5"
    shutil.copy(stress_h5, path)
    with h5py.File(path, "r+") as f:
        g = f["stress"]
        for _ in range(data.draw(st.integers(1, 3))):
            name = data.draw(st.sampled_from(["node_ids", "points", "modes"]))
            old = g[name][()]
            action = data.draw(st.sampled_from(["shorter", "value", "wild"]))
            del g[name]
            if action == "shorter" and np.ndim(old) >= 1 and len(old) > 1:
                g[name] = old[:-1]
            elif action == "value" and np.ndim(old) >= 1 and old.dtype.kind == "f":
                old.flat[data.draw(st.integers(0, old.size - 1))] = data.draw(wild_float)
                g[name] = old
            else:
                g[name] = _wild_array(data)
    try:
        with np.errstate(all="raise", under="ignore"):
            sid = read_sid(path, "error")
    except InputError as exc:
        assert "\n" not in str(exc)
        return
    s = sid.stress
    assert stress_problem(s, sid.nq) is None
    assert np.isfinite(s.points).all() and np.isfinite(s.modes).all()


# ------------------------------------------------------------------------------------------------
# TOML nesting: every TOML reader (scene, job, study) bounds the depth before parsing
# ------------------------------------------------------------------------------------------------

def _nested_toml(kind: str, depth: int) -> str:
    if kind == "array":
        return "x = " + "[" * depth + "1" + "]" * depth + "\n"
    if kind == "inline":
        return "x = " + "{a = " * depth + "1" + "}" * depth + "\n"
    if kind == "dotted":
        return ".".join(["a"] * depth) + " = 1\n"
    if kind == "spaced":
        return " . ".join(["a"] * depth) + " = 1\n"
    return "[" + ".".join(["a"] * depth) + "]\nb = 1\n"


@settings(deadline=None)
@given(kind=st.sampled_from(["array", "inline", "dotted", "spaced", "header"]),
       depth=st.one_of(st.integers(1, 100), st.sampled_from([1000, 20_000, 200_000])),
       reader=st.sampled_from(["scene", "job", "study"]))
def test_toml_nested_at_any_depth_is_read_or_refused_in_one_line(tmp_path_factory, kind, depth, reader):
    import time

    from sidprep.jobs.batch import read_study
    from sidprep.tables import MAX_TOML_DEPTH, parse_toml

    path = tmp_path_factory.mktemp("toml") / "deep.toml"
    path.write_text(_nested_toml(kind, depth))
    read = {"scene": load_scene, "job": read_job, "study": read_study}[reader]
    t0 = time.perf_counter()
    with pytest.raises(InputError) as info:
        read(path)
    assert time.perf_counter() - t0 < TOML_REFUSAL_S and "\n" not in str(info.value)
    nested = "nested" in str(info.value) or "dotted key" in str(info.value)
    assert nested == (depth > MAX_TOML_DEPTH), str(info.value)       # deep: refused for the depth
    if depth <= MAX_TOML_DEPTH:
        parse_toml(path.read_text(), path)                            # shallow: valid TOML, read


#: a TOML file nested 200k levels deep is refused within this (the parser alone took minutes)
TOML_REFUSAL_S = 5.0
