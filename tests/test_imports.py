"""What a command's process imports: ``sidprep reduce`` on a mesh loads none of the modules that
only other commands or other inputs need, and the parser (``sidprep --help``, ``sidprep reduce
--help``) none of numpy, scipy and h5py; and when ``sidprep reduce`` starts its BLAS with one
thread.  Guarded by module names in a fresh process, not by timing (the time it saves:
docs/performance.md, "Reduction: `sidprep reduce`")."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BAR = ROOT / "data" / "meshes" / "bar.msh"

#: modules (and their submodules) that ``sidprep reduce MESH.msh`` does not use, with what needs them
NOT_FOR_REDUCE = {
    "meshio": "meshes other than .msh and geometry files, K and M of other FE codes",
    "rich": "meshio; progress on a terminal",
    "pymetis": "--parts",
    "dask": "--scheduler",
    "distributed": "--scheduler",
    "multiprocessing": "the local pool of --parts and batch",
    "matplotlib": "plots",
    "plotly": "pages",
    "skfem": "none (the quadrature rules are written out)",
    "pyamg": "the AMG eigen backend",
    "scipy.interpolate": "--path, the solver's curves and tables",
    "scipy.integrate": "the solver's work integrals",
    "scipy.optimize": "none",
    "scipy.spatial": "none",
    "sidprep.fe.matrices": "--matrices",
    "sidprep.fe.readers.meshio": "as meshio",
    "sidprep.jobs.parts": "--parts",
    "sidprep.jobs.executor": "--parts, assemblies, batch",
    "sidprep.jobs.assembly": "a job file's assembly",
    "sidprep.jobs.batch": "sidprep batch",
    "sidprep.reduction.beam": "sidprep beam",
    "sidprep.reduction.partition": "--parts",
    "sidprep.reduction.component_modes": "--parts",
    "sidprep.view": "sidprep view, the pages",
}
#: the only modules of the solver the parser loads: the integrators' names (simulate's --method choices)
SOLVER_FOR_THE_PARSER = {"sidprep.solver", "sidprep.solver.integrators", "sidprep.solver.integrators.settings"}


def modules_after(code: str, *args: str) -> set[str]:
    """sys.modules of a fresh process after ``code`` (which may read ``sys.argv[1:]``)."""
    script = f"import json, sys\n{code}\nprint(json.dumps(sorted(sys.modules)))"
    r = subprocess.run([sys.executable, "-c", script, *args], capture_output=True, text=True, cwd=ROOT,
                       env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert r.returncode == 0, r.stderr
    return set(json.loads(r.stdout.strip().splitlines()[-1]))


def under(modules: set[str], names) -> list[str]:
    """The modules of ``modules`` that are one of ``names`` or a submodule of one."""
    return sorted(m for m in modules if any(m == n or m.startswith(n + ".") for n in names))


def test_reduce_on_a_mesh_imports_nothing_it_does_not_use(tmp_path):
    # own_process: as the `sidprep` command runs it, with the command's process_setup
    loaded = modules_after("from sidprep.cli.main import main\nassert main(sys.argv[1:], own_process=True) == 0",
                           "reduce", str(BAR), "--modes", "3", "-o", str(tmp_path / "bar.sid.h5"), "-q")
    assert (tmp_path / "bar.sid.h5").is_file()
    assert {"sidprep.jobs.reduce", "scipy.sparse.linalg", "h5py"} <= loaded     # the reduction did run
    assert under(loaded, NOT_FOR_REDUCE) == []
    assert under(loaded, ["sidprep.solver"]) == sorted(SOLVER_FOR_THE_PARSER)


def test_the_parser_imports_no_numpy_scipy_h5py():
    loaded = modules_after("from sidprep.cli.main import build_parser\nbuild_parser()")
    assert under(loaded, ["numpy", "scipy", "h5py", "sidprep.jobs", "sidprep.fe", "sidprep.reduction"]) == []
    assert under(loaded, ["sidprep.solver"]) == sorted(SOLVER_FOR_THE_PARSER)


def test_beam_imports_no_scipy_and_no_fe_side(tmp_path):
    loaded = modules_after("from sidprep.cli.main import main\nassert main(sys.argv[1:]) == 0",
                           "beam", "--length", "1", "--section", "rectangle:0.02,0.03", "--modes", "xz:1",
                           "-o", str(tmp_path / "beam.sid.h5"), "-q")
    assert (tmp_path / "beam.sid.h5").is_file()
    assert under(loaded, ["scipy", "meshio", "sidprep.fe.mesh", "sidprep.fe.linalg", "sidprep.jobs.reduce"]) == []


def test_reduce_process_setup_one_blas_thread_only_without_parts():
    """One BLAS thread from the start for a reduction in one process; --parts and job files keep
    the pools' default (their driver uses every core between rounds, sidprep.fe.linalg.all_cores_blas)."""
    code = ("import os, sys\nfrom sidprep.cli.main import build_parser\n"
            "args = build_parser().parse_args(sys.argv[1:])\nargs.process_setup(args)\n"
            "print(os.environ.get('OPENBLAS_NUM_THREADS'))")
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"} | {"PYTHONPATH": str(ROOT)}
    for argv, threads in ((["reduce", str(BAR)], "1"), (["reduce", str(BAR), "--parts", "2"], "None"),
                          (["reduce", "job.toml"], "None")):
        r = subprocess.run([sys.executable, "-c", code, *argv], capture_output=True, text=True, cwd=ROOT, env=env)
        assert r.stdout.strip().splitlines()[-1] == threads, (argv, r.stdout + r.stderr)
