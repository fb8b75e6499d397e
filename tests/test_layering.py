"""The solver reads SID files only: importing it must not import sidprep's FE side."""

import subprocess
import sys

FE_MODULES = ("sidprep.fe.mesh", "sidprep.fe.assemble", "sidprep.fe.linalg", "sidprep.reduction.craig_bampton",
              "sidprep.reduction.modes", "sidprep.reduction.interfaces", "sidprep.reduction.stiffening", "sidprep.jobs.reduce", "sidprep.jobs.modal", "skfem")


def test_solver_does_not_import_fe_side():
    code = (
        "import sys, importlib, pkgutil\n"
        "from sidprep import solver\n"
        "for m in pkgutil.walk_packages(solver.__path__, 'sidprep.solver.'):\n"
        "    importlib.import_module(m.name)\n"
        f"print(','.join(m for m in {FE_MODULES!r} if m in sys.modules))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""
