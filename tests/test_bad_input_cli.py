"""Bad inputs and faults run as a user meets them: the ``sidprep`` command in a subprocess (a
native crash or a hang must show as such, not kill the test run).

Every case states its class (``CLASS``) and what must happen: exit 2 with one line
``sidprep: error: ...`` naming the problem (or the expected exit code and text); never a
traceback, an internal error, a signal death, a hang (``TIMEOUT_S``) or a ``.part`` file left.
"""

from __future__ import annotations

import contextlib
import os
import re
import resource
import shutil
import signal
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BAR = ROOT / "data" / "meshes" / "bar.msh"
PENDULUM = ROOT / "examples" / "flexible_pendulum"
#: no case may take longer (the hangs ran on for ever; a refusal before the work takes ~2 s, but the
#: first simulation of a fresh install compiles the solver kernels: ~100 CPU-s, more on a loaded machine)
TIMEOUT_S = 300
#: size of the "full disk" (the issue's 200 kB tmpfs) and the room left on it
FULL_DISK_BYTES = 200_000
FREE_BYTES = 10_000

#: the cases by name (filled by @case), each of a class (Case.kind)
CASES: dict[str, "Case"] = {}


@dataclass(frozen=True)
class Case:
    name: str
    kind: str       # crash | hang | internal | sid-check | security | interrupt | silent | smaller
    build: object   # build(tmp: Path) -> (argv, expected exit code, regex the last stderr line matches)
    full_disk: bool = False


def case(kind: str, full_disk: bool = False):
    def register(build):
        CASES[build.__name__] = Case(build.__name__, kind, build, full_disk)
        return build
    return register


def env() -> dict:
    return {**os.environ, "PYTHONPATH": str(ROOT)}


def sidprep(*argv, cwd=None, preexec_fn=None, timeout=TIMEOUT_S) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "sidprep.cli.main", *map(str, argv)], capture_output=True,
                          text=True, cwd=cwd, env=env(), timeout=timeout, preexec_fn=preexec_fn)


@contextlib.contextmanager
def full_disk(folder: Path):
    """A folder with FREE_BYTES left: a 200 kB tmpfs, filled, when root may mount one; else a
    file-size limit of FREE_BYTES on the child (RLIMIT_FSIZE: writes fail with EFBIG)."""
    folder.mkdir()
    mounted = os.geteuid() == 0 and subprocess.run(
        ["mount", "-t", "tmpfs", "-o", f"size={FULL_DISK_BYTES // 1000}k", "tmpfs", str(folder)],
        capture_output=True).returncode == 0

    if mounted:
        (folder / "filler").write_bytes(bytes(FULL_DISK_BYTES - FREE_BYTES))

    def limit():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (FREE_BYTES, FREE_BYTES))

    try:
        yield None if mounted else limit
    finally:
        if mounted:
            subprocess.run(["umount", str(folder)], capture_output=True)


def leftovers(folder: Path) -> list[Path]:
    return [p for p in folder.rglob("*") if p.name.endswith(".part") or ".part." in p.name]


def check_outcome(proc, code: int, pattern: str) -> None:
    assert "Traceback" not in proc.stderr and "internal error" not in proc.stderr, proc.stderr[-3000:]
    assert "RuntimeWarning" not in proc.stderr and "\x1b" not in proc.stderr, proc.stderr[-3000:]
    assert proc.returncode == code, (proc.returncode, proc.stderr[-3000:])
    if code == 2:   # one line: the error, last
        last = proc.stderr.strip().splitlines()[-1] if proc.stderr.strip() else ""
        assert last.startswith("sidprep: error: ") and re.search(pattern, last), proc.stderr[-3000:]
    elif pattern:
        assert re.search(pattern, proc.stderr, re.M), proc.stderr[-3000:]


# ------------------------------------------------------------------------------------------------
# 1. native crashes
# ------------------------------------------------------------------------------------------------

def _corners_and_tet10():
    """One tet4 (nodes 1-4) and one tet10 (corners 2-5, mid-edge nodes 6-11) sharing a face."""
    import numpy as np

    p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], float)
    c = p[1:5]
    mids = np.array([(c[a] + c[b]) / 2 for a, b in ((0, 1), (1, 2), (0, 2), (0, 3), (2, 3), (1, 3))])
    return np.vstack([p, mids])


def mixed_msh22(tmp: Path, binary: bool) -> Path:
    import meshio

    path = tmp / f"mixed{'_bin' if binary else ''}.msh"
    with contextlib.redirect_stdout(None), contextlib.redirect_stderr(None):
        meshio.write_points_cells(path, _corners_and_tet10(), [("tetra", [[0, 1, 2, 3]]),
                                                             ("tetra10", [list(range(1, 11))])],
                                  file_format="gmsh22", binary=binary)
    return path


def mixed_msh41(tmp: Path) -> Path:
    """gmsh 4.1 ASCII: one volume entity holding a tet4 block and a tet10 block."""
    pts = _corners_and_tet10()
    n = len(pts)
    lines = ["$MeshFormat", "4.1 0 8", "$EndMeshFormat", "$Entities", "0 0 0 1", "1 0 0 0 1 1 1 0 0",
             "$EndEntities", "$Nodes", f"1 {n} 1 {n}", f"3 1 0 {n}", *map(str, range(1, n + 1)),
             *(" ".join(map(str, p)) for p in pts), "$EndNodes", "$Elements", "2 2 1 2", "3 1 4 1",
             "1 1 2 3 4", "3 1 11 1", "2 2 3 4 5 6 7 8 9 10 11", "$EndElements"]
    path = tmp / "mixed41.msh"
    path.write_text("\n".join(lines) + "\n")
    return path


@case("crash")
def mixed_tet4_tet10_msh22_modes(tmp):
    return ["modes", mixed_msh22(tmp, binary=False), "--count", 2, "-q"], 2, "mixes element types"


@case("crash")
def mixed_tet4_tet10_msh22_binary_reduce(tmp):
    return (["reduce", mixed_msh22(tmp, binary=True), "-q", "-o", tmp / "m.sid.h5"], 2,
            "mixes element types")


@case("crash")
def mixed_tet4_tet10_msh41_reduce(tmp):
    return ["reduce", mixed_msh41(tmp), "-q", "-o", tmp / "m.sid.h5"], 2, "volume 1 mixes element types"


@case("crash")
def msh22_element_on_undefined_node(tmp):
    """Found by tests/test_fuzz_readers.py: gmsh.merge segfaults on it."""
    path = tmp / "undefined.msh"
    path.write_text("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n5\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n"
                    "5 1 1 1\n$EndNodes\n$Elements\n2\n1 4 2 0 0 1 2 3 4\n2 4 2 0 0 6 3 4 5\n$EndElements\n")
    return ["modes", path, "--count", 2, "-q"], 2, r"refers to node 6, which the file does not define"


@case("crash", full_disk=True)
def full_disk_beam(tmp):
    return (["beam", "--length", 1, "--section", "circle:0.02", "--modes", "xz:1-20,xy:1-20", "-o",
             tmp / "full" / "b.sid.h5"], 2, r"full/b\.sid\.h5: could not be written")


@case("crash", full_disk=True)
def full_disk_simulate(tmp):
    shutil.copytree(PENDULUM, tmp / "pendulum")
    return (["simulate", tmp / "pendulum" / "scene.toml", "--t-end", 0.05, "-q", "-o", tmp / "full" / "p.h5"],
            2, r"full/p\.h5: could not be written")


@case("internal", full_disk=True)
def full_disk_reduce(tmp):
    return (["reduce", BAR, "--modes", 2, "-q", "-o", tmp / "full" / "bar.sid.h5"], 2,
            r"full/bar\.(sid\.h5|SID_FEM|obj): could not be written")


@case("internal", full_disk=True)
def full_disk_batch(tmp):
    """The job fails with the disk-full error as its record (exit 1); the report still fits."""
    return (["batch", BAR, "--modes", 2, "-q", "-o", tmp / "full" / "out"], 1,
            r"^sidprep batch: bar failed: .*full/out/bar\.(sid\.h5|SID_FEM|obj): could not be written")


@case("internal", full_disk=True)
def full_disk_view(tmp):
    return (["view", PENDULUM / "bar.sid.h5", "-o", tmp / "full" / "bar.html"], 2,
            r"full/bar\.html: could not be written")


# ------------------------------------------------------------------------------------------------
# 2. hangs: every size of work is bounded before the work
# ------------------------------------------------------------------------------------------------

def pendulum(tmp: Path, replace: dict | None = None, append: str = "") -> Path:
    """The flexible pendulum example copied to ``tmp``; ``replace`` edits lines of its scene file."""
    folder = tmp / "pendulum"
    if not folder.exists():
        shutil.copytree(PENDULUM, folder)
    text = (PENDULUM / "scene.toml").read_text()
    for old, new in (replace or {}).items():
        assert old in text, old
        text = text.replace(old, new)
    (folder / "scene.toml").write_text(text + append)
    return folder / "scene.toml"


@case("hang")
def path_with_1e8_samples(tmp):
    return (["reduce", BAR, "--modes", 2, "-q", "--path", "p:0,0.025,0.04:1,0.025,0.04:100000000", "-o",
             tmp / "b.sid.h5"], 2, r"2 <= n <= 100000 samples")


@case("hang")
def beam_with_100000_modes(tmp):
    return (["beam", "--length", 1, "--section", "circle:0.02", "--modes", "xz:1-100000", "-o", tmp / "b.sid.h5"],
            2, r"xz:1-100000 is not a range 1 <= first <= last <= 100")


@case("hang")
def scene_t_end_1e300(tmp):
    return (["simulate", pendulum(tmp, {"t_end = 1.0 ": "t_end = 1e300 "}), "-q", "-o", tmp / "r.h5"], 2,
            r"t_end = 1e\+300 s with step = 0.001 s: 1e\+303 steps")


@case("hang")
def scene_t_end_1e300_absolute_nodal(tmp):
    scene = tmp / "an.toml"
    scene.write_text((ROOT / "examples" / "two_link_manipulator" / "scene.toml").read_text())
    text = re.sub(r"(?m)^t_end\s*=.*$", "t_end = 1e300", scene.read_text())
    scene.write_text(text)
    return ["simulate", scene, "-q", "-o", tmp / "r.h5"], 2, r"steps, more than"


# ------------------------------------------------------------------------------------------------
# 3. internal errors: every number that enters is finite and in range
# ------------------------------------------------------------------------------------------------

def study(tmp: Path, batch: str) -> Path:
    path = tmp / "study.toml"
    path.write_text(f'[job]\nmesh = "{BAR}"\nmodes = 2\n\n[batch]\n{batch}\n')
    return path


@case("internal")
def batch_workers_minus_2(tmp):
    return ["batch", study(tmp, "workers = -2"), "-q"], 2, r"study\.toml: \[batch\] workers = -2: must be >= 1"


@case("silent")
def batch_memory_limit_minus_5(tmp):
    return ["batch", BAR, "--memory-limit", -5, "-q", "-o", tmp / "out"], 2, r"memory_limit_mb = -5.0: must be a positive"


@case("internal")
def study_nan_memory_limit(tmp):
    return ["batch", study(tmp, "memory_limit_mb = nan"), "-q"], 2, r"memory_limit_mb = nan: numbers must be finite"


@case("internal")
def path_with_nan_point(tmp):
    return (["reduce", BAR, "--modes", 2, "-q", "--path", "p:0,nan,0.04:1,0.025,0.04", "-o", tmp / "b.sid.h5"],
            2, r"coordinates must be finite")


@case("internal")
def beam_length_nan(tmp):
    return ["beam", "--length", "nan", "--section", "circle:0.02", "--modes", "xz:1", "-o", tmp / "b.sid.h5"], 2, \
        r"--length nan: must be a finite number"


@case("internal")
def scene_step_1e_300(tmp):
    return (["simulate", pendulum(tmp, {"step = 1e-3 ": "step = 1e-300 "}), "-q", "-o", tmp / "r.h5"], 2,
            r"step = 1e-300 s: shorter than 1e-12 s")


@case("internal")
def simulate_t_end_inf_option(tmp):
    return ["simulate", pendulum(tmp), "--t-end", "inf", "-q", "-o", tmp / "r.h5"], 2, r"--t-end inf: must be a finite"


# ------------------------------------------------------------------------------------------------
# 4. damaged SID files: validated at read (errors for simulate, one-line warnings for info / view)
# ------------------------------------------------------------------------------------------------

def damaged_hdf5(tmp: Path, edit: str) -> Path:
    """The pendulum's bar.sid.h5 with one damage: "nan_mass", "neg_mass", "nan_J", "neg_Jyy", "inf_Ke"."""
    import h5py
    import numpy as np

    path = tmp / f"bar_{edit}.sid.h5"
    shutil.copy(PENDULUM / "bar.sid.h5", path)
    member, index, value = {"nan_mass": (None, None, np.nan), "neg_mass": (None, None, -2.0),
                            "nan_J": ("modal/J/M0", (1, 0), np.nan), "neg_Jyy": ("modal/J/M0", (1, 0), -1.0),
                            "inf_Ke": ("modal/Ke/M0", (0, 0), np.inf)}[edit]
    with h5py.File(path, "r+") as f:
        if member is None:
            f["refmod"].attrs["mass"] = value
        else:
            a = f[member][()]
            a[index] = value
            f[member][...] = a
    return path


def damaged_sid_fem(tmp: Path, mass: str) -> Path:
    """A Beam's .SID_FEM with the mass line set to ``mass`` (e.g. "1.0D+999", "NaN")."""
    if not (tmp / "beam.SID_FEM").exists():
        assert sidprep("beam", "--length", 1, "--section", "circle:0.02", "--modes", "xz:1-2", "--sid-fem",
                       "-o", tmp / "beam.sid.h5").returncode == 0
    path = tmp / f"beam_{mass.replace('+', '')}.SID_FEM"
    path.write_text(re.sub(r"(mass\s+=\s*)\S+", lambda m: m.group(1) + mass,
                           (tmp / "beam.SID_FEM").read_text(), count=1))
    return path


WARNING = r"^sidprep: warning: .*{}.*sidprep check"
for _edit, _needle in (("nan_mass", r"non-finite number mass\[0\] = nan"), ("neg_mass", r"mass = -2 kg \(must be > 0\)"),
                       ("nan_J", r"non-finite number J\.M0\[1, 0\] = nan"),
                       ("neg_Jyy", "inertia about the centre of mass not positive definite"),
                       ("inf_Ke", r"non-finite number Ke\.M0\[0, 0\] = inf")):
    CASES[f"info_{_edit}"] = Case(f"info_{_edit}", "sid-check", lambda tmp, e=_edit, n=_needle: (
        ["info", damaged_hdf5(tmp, e)], 0, WARNING.format(n)))
    CASES[f"simulate_{_edit}"] = Case(f"simulate_{_edit}", "sid-check", lambda tmp, e=_edit, n=_needle: (
        ["simulate", pendulum(tmp, {'sid = "bar.sid.h5"': f'sid = "{damaged_hdf5(tmp, e)}"'}), "-q",
         "-o", tmp / "r.h5"], 2, r"not a physically possible body: " + n))
for _mass in ("1.0D+999", "NaN"):
    CASES[f"info_sid_fem_mass_{_mass}"] = Case(f"info_sid_fem_mass_{_mass}", "sid-check", lambda tmp, m=_mass: (
        ["info", damaged_sid_fem(tmp, m)], 0, WARNING.format(r"non-finite number mass")))
    CASES[f"simulate_sid_fem_mass_{_mass}"] = Case(f"simulate_sid_fem_mass_{_mass}", "sid-check", lambda tmp, m=_mass: (
        ["simulate", pendulum(tmp, {'sid = "bar.sid.h5"': f'sid = "{damaged_sid_fem(tmp, m)}"'}), "-q",
         "-o", tmp / "r.h5"], 2, r"not a physically possible body: non-finite number mass"))
CASES["view_nan_J"] = Case("view_nan_J", "sid-check", lambda tmp: (
    ["view", damaged_hdf5(tmp, "nan_J"), "-o", tmp / "v.html"], 0, WARNING.format(r"non-finite number J\.M0")))


@case("internal")
def animate_empty_file(tmp):
    (tmp / "empty.h5").write_bytes(b"")
    return ["animate", tmp / "empty.h5"], 2, r"empty\.h5: not a readable HDF5 file"


# ------------------------------------------------------------------------------------------------
# 5. security: a SID or results file reads no file the user did not name
# ------------------------------------------------------------------------------------------------

def foreign_hdf5(tmp: Path, kind: str, source: Path = PENDULUM / "bar.sid.h5", member: str = "modal/Ke/M0") -> Path:
    """A copy of ``source`` whose ``member`` is replaced by an external link / external storage /
    virtual dataset reading ``tmp/secret.*``."""
    import h5py
    import numpy as np

    path = tmp / f"{kind}{''.join(source.suffixes)}"
    shutil.copy(source, path)
    with h5py.File(path, "r+") as f:
        shape = f[member].shape
        del f[member]
        if kind == "external_link":
            with h5py.File(tmp / "secret.h5", "w") as g:
                g["data"] = np.ones(shape)
            f[member] = h5py.ExternalLink(str(tmp / "secret.h5"), "data")
        elif kind == "external_storage":
            (tmp / "secret.txt").write_bytes(b"password" * int(np.prod(shape)))
            f.create_dataset(member, shape=shape, dtype="<f8", external=[(str(tmp / "secret.txt"), 0, h5py.h5f.UNLIMITED)])
        else:
            with h5py.File(tmp / "secret.h5", "w") as g:
                g["data"] = np.ones(shape)
            layout = h5py.VirtualLayout(shape=shape, dtype="f8")
            layout[...] = h5py.VirtualSource(str(tmp / "secret.h5"), "data", shape=shape)
            f.create_virtual_dataset(member, layout)
    return path


for _kind, _needle in (("external_link", "is an external link to"), ("external_storage", "stores its data in the external file"),
                       ("virtual", "is a virtual dataset mapped from")):
    CASES[f"info_{_kind}"] = Case(f"info_{_kind}", "security", lambda tmp, k=_kind, n=_needle: (
        ["info", foreign_hdf5(tmp, k)], 2, rf"/modal/Ke/M0 {n} .*secret.*refused"))
    CASES[f"simulate_{_kind}"] = Case(f"simulate_{_kind}", "security", lambda tmp, k=_kind, n=_needle: (
        ["simulate", pendulum(tmp, {'sid = "bar.sid.h5"': f'sid = "{foreign_hdf5(tmp, k)}"'}), "-q",
         "-o", tmp / "r.h5"], 2, rf"{n} .*secret.*refused"))


@case("security")
def animate_results_with_external_link(tmp):
    proc = sidprep("simulate", pendulum(tmp), "--t-end", 0.01, "-q", "-o", tmp / "r.h5")
    assert proc.returncode == 0, proc.stderr
    return ["animate", foreign_hdf5(tmp, "external_link", tmp / "r.h5", "time")], 2, r"/time is an external link"


@case("security")
def job_output_outside_its_folder(tmp):
    (tmp / "jobs").mkdir()
    job = tmp / "jobs" / "job.toml"
    job.write_text(f'mesh = "{BAR}"\nmodes = 2\noutput = "../escaped.sid.h5"\nsid_fem = false\nobj = false\n')
    return ["reduce", job, "-q"], 0, r"^sidprep: warning: .*job\.toml: output = '\.\./escaped\.sid\.h5' writes outside"


@case("security")
def study_outdir_outside_its_folder_with_safe(tmp):
    return (["batch", study(tmp, 'outdir = "/tmp/elsewhere"'), "-q", "--safe"], 2,
            r"\[batch\] outdir = '/tmp/elsewhere' writes outside the file's folder .*refused with --safe")


# ------------------------------------------------------------------------------------------------
# 7. silent wrong successes, 8. smaller
# ------------------------------------------------------------------------------------------------

@case("silent")
def beam_output_txt(tmp):
    return (["beam", "--length", 1, "--section", "circle:0.02", "--modes", "xz:1", "-o", tmp / "b.txt"], 2,
            r"b\.txt.*(unknown file type|\.sid\.h5)")


def moving_force(tmp: Path, old: str, new: str) -> Path:
    text = (ROOT / "examples" / "moving_force" / "scene.toml").read_text()
    assert old in text, old
    (tmp / "scene.toml").write_text(text.replace(old, new))
    return tmp / "scene.toml"


@case("silent")
def path_marker_starting_beyond_the_beam(tmp):
    return (["simulate", moving_force(tmp, "start = 0.0 ", "start = 20.0 "), "-q", "-o", tmp / "r.h5"], 2,
            r"path marker load starts at s = 20 m, off its path \(s = 0 \.\. 15 m\)")


@case("silent")
def mass_released_beyond_the_rail(tmp):
    text = (ROOT / "examples" / "moving_mass" / "scene.toml").read_text()
    (tmp / "scene.toml").write_text(text.replace("position = [2.0, 0.0, 0.0]", "position = [20.0, 0.0, 0.0]"))
    return (["simulate", tmp / "scene.toml", "-q", "--t-end", 0.1, "-o", tmp / "r.h5"], 2,
            r"marker slider starts 5 m beyond the end of the path of rail")


def test_moving_force_driven_past_the_path_end_gets_a_note(tmp_path):
    """10 m/s from s = 0 on the 15 m axis leaves it at t = 1.5 s (the sampled time within 1 ms)."""
    proc = sidprep("simulate", moving_force(tmp_path, "t_end = 2.0", "t_end = 1.6"), "-o", tmp_path / "r.h5")
    check_outcome(proc, 0, "")
    assert re.search(r"note: path marker load leaves its path \(s = 0 \.\. 15 m\) at t = 1\.50\d* s", proc.stdout), \
        proc.stdout


@case("smaller")
def scene_make_text_with_control_characters(tmp):
    scene = pendulum(tmp, {'sid = "bar.sid.h5"': 'sid = "missing.sid.h5"',
                           'make = "sidprep reduce': 'make = "evil\\n\\u001b[31m red; sidprep reduce'})
    return ["simulate", scene, "-q", "-o", tmp / "r.h5"], 2, r"make it with `evil\\n\\x1b\[31m red"


# ------------------------------------------------------------------------------------------------
# 9. the newer features: nested TOML, modal stresses, parts and clusters, solver settings, meshes,
#    OBJ surfaces, moving masses, signals
# ------------------------------------------------------------------------------------------------

NESTED_TOML = {"arrays": lambda n: "x = " + "[" * n + "]" * n + "\n",
               "dotted_key": lambda n: ".".join(["a"] * n) + " = 1\n"}
for _command, _kind in (("simulate", "arrays"), ("reduce", "dotted_key"), ("batch", "arrays")):
    CASES[f"toml_200k_levels_{_command}"] = Case(f"toml_200k_levels_{_command}", "internal", lambda tmp, c=_command, k=_kind: (
        [c, _written(tmp / "deep.toml", NESTED_TOML[k](200_000))], 2,
        r"deep\.toml: (arrays or tables nested 200000 levels deep|a dotted key of more than 64 parts)"))


def _written(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


@case("internal")
def stress_at_nan(tmp):
    return ["stress", tmp / "r.h5", "--at", "nan,0,0"], 2, r"--at nan,0\.0,0\.0: give three finite coordinates"


@case("internal")
def parts_with_workers_minus_3(tmp):
    return ["reduce", BAR, "--parts", 2, "--workers", -3, "-q", "-o", tmp / "b.sid.h5"], 2, r"--workers -3: must be >= 1"


@case("silent")
def parts_with_workers_0(tmp):
    return ["reduce", BAR, "--parts", 2, "--workers", 0, "-q", "-o", tmp / "b.sid.h5"], 2, r"--workers 0: must be >= 1"


@case("internal")
def scheduler_address_malformed(tmp):
    return (["reduce", BAR, "--parts", 2, "--scheduler", "tcp://host:99999", "-q", "-o", tmp / "b.sid.h5"], 2,
            r"--scheduler tcp://host:99999: not a scheduler address; give .* tcp://HOST:PORT")


@case("internal")
def study_scheduler_of_another_scheme(tmp):
    return ["batch", study(tmp, 'scheduler = "http://10.0.0.5:8786"'), "-q"], 2, r"unknown scheme 'http'"


@case("internal")
def simulate_step_1e300(tmp):
    return (["simulate", pendulum(tmp), "--step", "1e300", "-q", "-o", tmp / "r.h5"], 2,
            r"step = 1e\+300 s is longer than t_end = 1 s")


@case("silent")
def simulate_rtol_with_fixed_step_rk4(tmp):
    return (["simulate", pendulum(tmp), "--method", "rk4", "--rtol", "1e-6", "-q", "-o", tmp / "r.h5"], 2,
            r"rtol = 1e-06: rk4 steps at the fixed step h and has no error control")


@case("hang")
def sparse_2gb_mesh(tmp):
    path = tmp / "sparse.msh"
    with open(path, "wb") as f:
        f.write((BAR.read_bytes())[:4000])
        f.truncate(2 << 30)
    return ["modes", path, "--count", 2, "-q"], 2, r"sparse\.msh: 20\d\d of its 2048 MiB were never written"


@case("hang")
def text_mesh_of_zeros(tmp):
    path = tmp / "zeros.inp"
    path.write_bytes(bytes(3 << 20))
    return ["reduce", path, "-q", "-o", tmp / "z.sid.h5"], 2, r"zeros\.inp: a NUL byte at byte 0 of a text mesh format"


@case("internal")
def obj_face_index_3e9(tmp):
    pendulum(tmp)
    (tmp / "pendulum" / "box.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3000000000\n")
    box = '\n[bodies.box]\ntype = "rigid"\nmass = 1.0\ninertia = [0.1, 0.1, 0.1]\nobj = "box.obj"\n'
    return (["simulate", pendulum(tmp, append=box), "--animate", "-q", "--t-end", 0.01, "-o", tmp / "r.h5"], 2,
            r"box\.obj: cannot read the OBJ surface \(IndexError")


@case("silent")
def moving_mass_slides_off_its_rail(tmp):
    """100 kg released at s = 2 m with 10 m/s along the 15 m rail: off its end at ~1.3 s."""
    text = (ROOT / "examples" / "moving_mass" / "scene.toml").read_text()
    text = re.sub(r"(?m)^t_end\s*=.*$", "t_end = 2.0", text).replace(
        "position = [2.0, 0.0, 0.0]", "position = [2.0, 0.0, 0.0]\nvelocity = [10.0, 0.0, 0.0]")
    return (["simulate", _written(tmp / "scene.toml", text), "-q", "-o", tmp / "r.h5"], 2,
            r"on_path joint slide: marker slider left the path of rail \(s = 0 \.\. 15 m\) at t = 1\.[23]\d* s")


@case("silent")
def effort_of_a_joint_without_driver(tmp):
    scene = pendulum(tmp, {'signals = ["hinge.coordinate"': 'signals = ["hinge.effort", "hinge.coordinate"'})
    return (["simulate", scene, "-q", "-o", tmp / "r.h5"], 2,
            r"signals: 'hinge\.effort': joint 'hinge' has no effort of its own")


def test_a_mesh_path_with_non_ascii_characters_gives_all_three_files(tmp_path):
    mesh = tmp_path / "bär é.msh"
    shutil.copy(BAR, mesh)
    proc = sidprep("reduce", mesh, "--modes", 2, "-q", cwd=tmp_path)
    check_outcome(proc, 0, "")
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == ["bär é.SID_FEM", "bär é.msh", "bär é.obj", "bär é.sid.h5"], names
    assert "# sidprep reduce b\\xe4r \\xe9.msh" in (tmp_path / "bär é.obj").read_text(encoding="ascii")


def test_a_failed_run_keeps_its_results_under_a_name_of_their_own(tmp_path):
    """rk45 with rtol = 1 gives up at once; its results are r.failed.h5, r.h5 is not written."""
    proc = sidprep("simulate", pendulum(tmp_path), "--method", "rk45", "--rtol", 1, "--t-end", 0.05, "-q", "-o",
                   tmp_path / "r.h5")
    check_outcome(proc, 2, r"the results up to t = .* s are kept in .*r\.failed\.h5 \(.*r\.h5 not written\)")
    assert (tmp_path / "r.failed.h5").is_file() and not (tmp_path / "r.h5").exists()


def test_the_progress_line_names_the_method_of_the_run(tmp_path):
    proc = sidprep("simulate", pendulum(tmp_path), "--method", "rk4", "--step", "1e-4", "--t-end", 0.002, "-o",
                   tmp_path / "r.h5")
    check_outcome(proc, 0, r"simulate 0 \.\. 0\.002 s, rk4, step 0\.0001 s")


# 6. interrupted work and shared folders (batch, simulate): the tests after the corpus run

# ------------------------------------------------------------------------------------------------
# the corpus run
# ------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("name", sorted(CASES), ids=lambda n: f"{CASES[n].kind}-{n}")
def test_bad_input_case(name, tmp_path):
    c = CASES[name]
    with full_disk(tmp_path / "full") if c.full_disk else contextlib.nullcontext() as preexec:
        argv, code, pattern = c.build(tmp_path)
        proc = sidprep(*argv, cwd=tmp_path, preexec_fn=preexec)
        found = leftovers(tmp_path)
    check_outcome(proc, code, pattern)
    assert not found, found


# ------------------------------------------------------------------------------------------------
# 6. interrupts and locks
# ------------------------------------------------------------------------------------------------

#: seconds to wait for a batch's workers to start (imports and the DOF estimates come first)
START_S = 90
#: seconds a worker may outlive a killed batch (its watchdog polls every 0.5 s, grace 5 s)
ORPHAN_S = 15


def descendants(pid: int) -> set[int]:
    """Process ids below ``pid`` (from /proc)."""
    children: dict[int, list[int]] = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        with contextlib.suppress(OSError, ValueError, IndexError):
            fields = stat.read_text().rsplit(")", 1)[1].split()
            children.setdefault(int(fields[1]), []).append(int(stat.parent.name))
    out, todo = set(), [pid]
    while todo:
        for c in children.get(todo.pop(), []):
            out.add(c)
            todo.append(c)
    return out


def alive(pids) -> set[int]:
    return {p for p in pids if Path(f"/proc/{p}").exists() and "(Z)" not in _state(p)}


def _state(pid: int) -> str:
    with contextlib.suppress(OSError):
        return "(" + Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] + ")"
    return "(Z)"


def default_sigint() -> None:
    """SIGINT to its default in a child: a test run as a background job inherits SIG_IGN, and
    Python keeps an ignored SIGINT ignored (no KeyboardInterrupt to test)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def running_batch(tmp: Path) -> tuple[subprocess.Popen, Path]:
    """A batch of four reductions of the bar with two workers, once its workers run."""
    import time

    study = tmp / "study.toml"
    study.write_text(f'[job]\nmesh = "{BAR}"\n[sweep]\nmodes = [2, 3, 4, 5]\n[batch]\noutdir = "out"\nworkers = 2\n')
    proc = subprocess.Popen([sys.executable, "-m", "sidprep.cli.main", "batch", str(study), "-q"], env=env(),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=default_sigint)
    deadline = time.monotonic() + START_S
    while len(descendants(proc.pid)) < 3 and time.monotonic() < deadline:   # forkserver + 2 workers
        time.sleep(0.2)
    assert proc.poll() is None and len(descendants(proc.pid)) >= 3, "the batch's workers did not start"
    time.sleep(1.0)
    return proc, tmp / "out"


@pytest.mark.parametrize("sig, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)], ids=["batch_sigint", "batch_sigterm"])
def test_signal_stops_batch_workers_cleanly(tmp_path, sig, code):
    import time

    proc, out = running_batch(tmp_path)
    workers = descendants(proc.pid)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=TIMEOUT_S)
    assert proc.returncode == code, err
    assert "Traceback" not in err and err.strip().splitlines()[-1] in ("sidprep: interrupted", "sidprep: terminated"), err
    deadline = time.monotonic() + ORPHAN_S
    while alive(workers) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not alive(workers)
    assert not leftovers(out) and not (out / ".sidprep-batch.lock").exists()


def test_batch_sigkill_leaves_no_worker(tmp_path):
    import time

    proc, out = running_batch(tmp_path)
    workers = descendants(proc.pid)
    proc.kill()
    proc.communicate()
    deadline = time.monotonic() + ORPHAN_S
    while alive(workers) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not alive(workers), [Path(f"/proc/{p}/cmdline").read_text()[:120] for p in alive(workers)]


def test_second_batch_into_a_locked_folder_stops_naming_the_first(tmp_path):
    import json
    import socket

    out = tmp_path / "out"
    out.mkdir()
    (out / ".sidprep-batch.lock").write_text(json.dumps({"pid": os.getpid(), "host": socket.gethostname(),
                                                         "started_unix_s": 0}))
    proc = sidprep("batch", BAR, "--modes", 2, "-q", "-o", out)
    check_outcome(proc, 2, rf"another sidprep batch writes this folder \(pid {os.getpid()} on")
    assert sorted(p.name for p in out.iterdir()) == [".sidprep-batch.lock"]


def test_stale_lock_is_taken_over_and_part_files_removed(tmp_path):
    import json
    import socket

    from sidprep.jobs.guard import LOCK_NAME, folder_lock

    dead = subprocess.Popen(["true"])
    dead.wait()
    (tmp_path / LOCK_NAME).write_text(json.dumps({"pid": dead.pid, "host": socket.gethostname()}))
    (tmp_path / ".job.sid.h5.x1.part").write_text("half")
    with folder_lock(tmp_path) as lock:
        assert json.loads(lock.read_text())["pid"] == os.getpid()
    assert list(tmp_path.iterdir()) == []


def test_simulate_sigterm_exits_143_without_traceback_or_part_file(tmp_path):
    import time

    # 1000 s of pendulum (~40 CPU s): the signal arrives mid-run however fast the run starts
    scene = pendulum(tmp_path, {"t_end = 1.0 ": "t_end = 1000.0 "})
    proc = subprocess.Popen([sys.executable, "-m", "sidprep.cli.main", "simulate", str(scene), "-o",
                             str(tmp_path / "r.h5")], env=env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    deadline = time.monotonic() + START_S
    while proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.2)
        if "simulate" in Path(f"/proc/{proc.pid}/cmdline").read_text() and _stderr_so_far(proc):
            break
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=TIMEOUT_S)
    assert proc.returncode == 143, err
    assert "Traceback" not in err and err.strip().splitlines()[-1] == "sidprep: terminated", err
    assert not leftovers(tmp_path)


def _stderr_so_far(proc) -> bool:
    """True once the run printed its first progress line (the scene is loaded, the run starts)."""
    import select

    return bool(select.select([proc.stderr], [], [], 0)[0])


# ------------------------------------------------------------------------------------------------
# signals while the outputs are written and while the process ends
# ------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("sig, code", [(signal.SIGTERM, 143), (signal.SIGINT, 130)], ids=["sigterm", "sigint"])
@pytest.mark.parametrize("when", ["sid_fem", "obj"])
def test_a_signal_while_a_reduction_is_written_leaves_no_file(tmp_path, monkeypatch, capsys, sig, code, when):
    """The signal arrives while the second or third file of the set is written (.SID_FEM, .obj):
    none of the three appears, no temporary file is left, one line and the signal's exit code."""
    import sidprep.sid.io as sid_io
    from sidprep.cli.main import main

    writer = {"sid_fem": "_write_sid_fem", "obj": "_write_surface"}[when]
    original = getattr(sid_io, writer)
    fmt = next(f for f in sid_io.FORMATS if f.write is original)

    def interrupted(sid, path, comment):
        os.kill(os.getpid(), sig)           # delivered at once: the handler raises in this thread
        return original(sid, path, comment)

    monkeypatch.setattr(sid_io, "FORMATS", tuple(f if f is not fmt else type(f)(f.name, f.suffixes, f.read, interrupted)
                                                 for f in sid_io.FORMATS))
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        assert main(["reduce", str(BAR), "--modes", "2", "-q", "-o", str(tmp_path / "bar.sid.h5")]) == code
    finally:
        signal.signal(signal.SIGINT, previous)
    assert capsys.readouterr().err.strip().splitlines()[-1] in ("sidprep: terminated", "sidprep: interrupted")
    assert list(tmp_path.iterdir()) == []


def test_a_signal_while_the_process_ends_gives_its_exit_code_and_one_line(capsys):
    from sidprep.cli.main import ShutdownSignals

    saved = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        shutdown = ShutdownSignals()
        assert shutdown.exit_code(0) == 0
        os.kill(os.getpid(), signal.SIGTERM)    # noted, not raised: the exit handlers go on
        assert shutdown.exit_code(0) == 143
    finally:
        for s, handler in saved.items():
            signal.signal(s, handler)
    assert capsys.readouterr().err == "sidprep: terminated\n"


def test_sigterm_during_a_process_end_is_not_a_traceback(tmp_path):
    """A signal that lands in the exit handlers of a finished command (here an exit handler that
    sends it): exit 143 and one line, no traceback, the command's output complete."""
    script = ("import atexit, os, signal, sys\n"
              "from sidprep.cli import main\n"
              "atexit.register(lambda: os.kill(os.getpid(), signal.SIGTERM))\n"
              f"sys.argv = ['sidprep', 'info', {str(PENDULUM / 'bar.sid.h5')!r}]\n"
              "main.command()\n")
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env(), timeout=TIMEOUT_S)
    assert proc.returncode == 143, proc.stderr
    assert "Traceback" not in proc.stderr and proc.stderr.strip().splitlines()[-1] == "sidprep: terminated"
    assert "mass" in proc.stdout


#: a stop raised inside a weakref callback (Python drops it there): the process must still stop
STOP_IN_A_WEAKREF_CALLBACK = """\
import os, signal, sys, weakref
{install}
class Body: pass
def callback(_):
    os.kill(os.getpid(), signal.{sig})
    for _ in range(10000): pass          # the handler runs here, inside the callback
body = Body()
ref = weakref.ref(body, callback)
try:
    del body
    for _ in range(10**7): pass
    print("went on")
except {stop}:
    print("stopped")
"""


@pytest.mark.parametrize("install, sig, stop", [
    ("from sidprep.errors import terminate_on_sigterm\nterminate_on_sigterm()", "SIGTERM",
     "__import__('sidprep.errors').errors.Terminated"),
    ("from sidprep.errors import keep_stops_raisable\nkeep_stops_raisable()", "SIGINT", "KeyboardInterrupt"),
], ids=["cli_sigterm", "sigint"])
def test_a_stop_that_lands_in_a_weakref_callback_still_stops(install, sig, stop):
    script = STOP_IN_A_WEAKREF_CALLBACK.format(install=install, sig=sig, stop=stop)
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env(),
                          timeout=TIMEOUT_S, preexec_fn=default_sigint)
    assert proc.stdout == "stopped\n" and "Exception ignored" not in proc.stderr, proc.stdout + proc.stderr


def test_a_batch_workers_sigterm_in_a_weakref_callback_still_ends_the_worker():
    script = ("import os, signal, sys, weakref\n"
              "from sidprep.jobs.guard import guarded, worker_setup\n"
              "worker_setup(os.getppid())\n"
              "class Body: pass\n"
              "def callback(_):\n"
              "    os.kill(os.getpid(), signal.SIGTERM)\n"
              "    for _ in range(10000): pass\n"
              "def job():\n"
              "    body = Body(); ref = weakref.ref(body, callback); del body\n"
              "    for _ in range(10**7): pass\n"
              "    print('went on')\n"
              "guarded(job)\n")
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env(),
                          timeout=TIMEOUT_S)
    assert proc.returncode == 143 and proc.stdout == "" and "Exception ignored" not in proc.stderr, proc.stderr
