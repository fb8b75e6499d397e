"""The frequency check without a full eigen solve: certified bounds against the full re-solve."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import sidprep.reduction.fe_checks as fe_checks
from sidprep.fe.assemble import mass_matrix, stiffness_matrix
from sidprep.reduction.interfaces import make_interface
from sidprep.jobs.reduce import reduce_body
from sidprep.fe.material import builtin_material
from sidprep.fe.mesh import read_mesh
from sidprep.reduction.modes import hz

MESHES = Path(__file__).resolve().parents[1] / "data" / "meshes"
#: round-off slack of "the bound contains the full re-solve's frequency" (eigen solve tolerance)
CONTAIN_RTOL = 1e-9


def reduction(mesh_path, frame, n_modes):
    mesh = read_mesh(mesh_path)
    steel = builtin_material("steel")
    itfs = [make_interface(mesh, name) for name in sorted(mesh.node_sets)]
    return reduce_body(mesh, stiffness_matrix(mesh, steel), mass_matrix(mesh, steel), itfs, frame=frame,
                       n_modes=n_modes)


@pytest.fixture(scope="module")
def square_bar(tmp_path_factory):
    """A square-section bar: its bending modes come in degenerate pairs."""
    out = tmp_path_factory.mktemp("square") / "square.msh"
    subprocess.run([sys.executable, str(MESHES / "make_bar.py"), "--box", "1.0", "0.06", "0.06", "--size", "0.03",
                    "--out", str(out)], check=True, capture_output=True)
    return out


@pytest.mark.parametrize("case", [("bar.msh", "free", 10), ("bar.msh", "fixed_end", 6),
                                  ("piston_rod.msh", "free", 8), ("square", "free", 8), ("square", "fixed_end", 7)])
def test_bounds_contain_the_full_eigen_solve(case, square_bar):
    """Certified (no fallback), and the full model's frequencies lie within the bounds, which are
    tight: the bound on the error is at most twice the error of the reduced frequency."""
    name, frame, n = case
    red = reduction(square_bar if name == "square" else MESHES / name, frame, n)
    f_red = red.basis.frequencies_hz[:n]
    lower, upper, reason = fe_checks.frequency_bounds(red, n)
    assert reason == ""
    f_full = fe_checks.full_model_frequencies(red, n)
    assert np.all(hz(lower) <= f_full * (1 + CONTAIN_RTOL)) and np.all(f_full <= hz(upper) * (1 + CONTAIN_RTOL))
    error, bound = f_red / f_full - 1, f_red / hz(lower) - 1
    assert np.all(bound <= 2 * error + 1e-7)


def test_eigenvalue_count_matches_the_full_spectrum():
    red = reduction(MESHES / "bar.msh", "fixed_end", 6)
    f = fe_checks.full_model_frequencies(red, 6)
    lam = (2 * np.pi * f) ** 2
    for k, sigma in enumerate(np.sqrt(lam[:-1] * lam[1:]), start=1):
        assert fe_checks.eigenvalue_count(red, sigma) == k
    top = (2 * np.pi * red.cb.fixed_interface_hz[-1]) ** 2
    assert fe_checks.eigenvalue_count(red, 1.01 * top) is None        # beyond the computed interior spectrum


def test_uncertified_bounds_fall_back_to_the_full_eigen_solve(monkeypatch):
    red = reduction(MESHES / "bar.msh", "free", 4)
    monkeypatch.setattr(fe_checks, "eigenvalue_count", lambda red, sigma: None)
    lower, upper, reason = fe_checks.frequency_bounds(red, 4)
    assert np.isnan(lower).all() and "did not converge" in reason
    checks = fe_checks.frequency_checks(red)
    assert checks["frequency_check"].startswith("full-model eigen solve")
    np.testing.assert_allclose(np.array(checks["frequencies_full_hz_bounds"])[:, 0],
                               fe_checks.full_model_frequencies(red, 4))
