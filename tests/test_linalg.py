"""Factorisations and the eigen solver against dense LAPACK (scipy.linalg.eigh) on small models."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp

from sidprep.assemble import stiffness_and_mass
from sidprep.errors import InputError
from sidprep.linalg import (clamp_dofs, eigen_modes, factorize, node_dofs, rigid_body_modes,
                            spectral_scale)
from test_assemble import MAT, femesh, skfem_box

#: direct shift-invert Lanczos vs dense eigh: relative eigenvalue difference
DIRECT_RTOL = 1e-9
#: elastic-mode relative residual ||K phi - lam M phi|| / ||K phi|| reached by the direct path
RESIDUAL_TOL = 1e-8
#: AMG-LOBPCG (tolerance LOBPCG_TOL on the residual) vs the direct path
LOBPCG_RTOL = 1e-6


@pytest.fixture(scope="module")
def free_box():
    mesh = femesh(skfem_box(n=2), 2)[0]
    K, M = stiffness_and_mass(mesh, MAT)
    lam = sla.eigh(K.toarray(), M.toarray(), eigvals_only=True)
    return mesh, K, M, lam


def test_cholmod_and_superlu_solve_the_same_system(free_box):
    _, K, M, _ = free_box
    A = (K + 1e-6 * spectral_scale(K, M) * M).tocsr()
    b = np.random.default_rng(1).standard_normal((A.shape[0], 2))
    x_chol = factorize(A, "cholmod").solve(b)
    x_lu = factorize(A, "superlu").solve(b)
    x_fortran = factorize(A, "cholmod").solve(np.asfortranarray(b))  # column slices arrive F-ordered
    assert np.array_equal(x_fortran, x_chol)
    assert np.linalg.norm(A @ x_chol - b) / np.linalg.norm(b) < 1e-8
    assert np.linalg.norm(x_chol - x_lu) / np.linalg.norm(x_lu) < 1e-8
    with pytest.raises(np.linalg.LinAlgError):
        factorize(K - 1e-3 * spectral_scale(K, M) * M, "cholmod")  # indefinite


@pytest.mark.parametrize("backend", ["cholmod", "superlu"])
def test_free_body_modes_match_dense_eigh(free_box, backend):
    _, K, M, lam_ref = free_box
    res = eigen_modes(K, M, count=8, backend=backend)
    assert res.n_rigid == 6 and res.backend == backend
    assert np.allclose(res.eigenvalues[6:], lam_ref[6:14], rtol=DIRECT_RTOL, atol=0)
    assert res.residuals[6:].max() < RESIDUAL_TOL and res.residuals[:6].max() < RESIDUAL_TOL
    assert np.allclose(res.vectors.T @ (M @ res.vectors), np.eye(14), atol=1e-9)
    assert res.sigma < 0


def test_repeat_runs_are_bit_identical(free_box):
    _, K, M, _ = free_box
    a, b = (eigen_modes(K, M, count=5) for _ in range(2))
    assert np.array_equal(a.eigenvalues, b.eigenvalues) and np.array_equal(a.vectors, b.vectors)


def test_fmax_returns_every_mode_below_it(free_box):
    _, K, M, lam_ref = free_box
    f_ref = np.sqrt(np.abs(lam_ref[6:])) / (2 * np.pi)
    fmax = 0.5 * (f_ref[29] + f_ref[30])  # 30 elastic modes below: forces the block to grow
    res = eigen_modes(K, M, fmax=fmax)
    assert res.n_rigid == 6 and len(res.eigenvalues) == 36
    assert np.allclose(res.frequencies_hz[6:], f_ref[:30], rtol=DIRECT_RTOL)


def test_clamped_box_and_restriction_round_trip(free_box):
    mesh, K, M, _ = free_box
    fixed = node_dofs(np.flatnonzero(mesh.points[:, 0] < 1e-9))
    r = clamp_dofs(mesh.n_dof, fixed)
    Kf, Mf = r.restrict(K), r.restrict(M)
    lam_ref = sla.eigh(Kf.toarray(), Mf.toarray(), eigvals_only=True, subset_by_index=[0, 4])
    res = eigen_modes(Kf, Mf, count=5)
    assert res.n_rigid == 0
    assert np.allclose(res.eigenvalues, lam_ref, rtol=DIRECT_RTOL)
    full = r.expand(res.vectors)
    assert full.shape == (mesh.n_dof, 5) and not full[fixed].any()
    assert np.array_equal(full[r.free], res.vectors)


def test_lobpcg_backend_matches_direct(free_box):
    mesh, K, M, _ = free_box
    direct = eigen_modes(K, M, count=6)
    amg = eigen_modes(K, M, count=6, backend="lobpcg", near_null=rigid_body_modes(mesh.points))
    assert amg.n_rigid == 6 and amg.backend == "lobpcg"
    assert np.allclose(amg.eigenvalues[6:], direct.eigenvalues[6:], rtol=LOBPCG_RTOL)


def test_rigid_body_modes_are_m_orthogonal_to_elastic_modes(free_box):
    mesh, K, M, _ = free_box
    res = eigen_modes(K, M, count=3)
    R = rigid_body_modes(mesh.points)
    assert np.abs(R.T @ (M @ res.vectors[:, 6:])).max() < 1e-8 * np.abs(R).max()


@pytest.mark.parametrize("kwargs, fragment", [({}, "exactly one"), ({"count": 3, "fmax": 10.0}, "exactly one"),
                                              ({"count": 0}, "--count"), ({"fmax": -1.0}, "--fmax"),
                                              ({"count": 2, "sigma": 1.0}, "negative"),
                                              ({"count": 2, "backend": "mumps"}, "--backend")])
def test_bad_solver_options_are_input_errors(kwargs, fragment):
    K = sp.identity(30, format="csr")
    with pytest.raises(InputError, match=fragment):
        eigen_modes(K, K, **kwargs)


def test_interposed_blas_gives_the_reference_blas_result():
    """CHOLMOD with the optimised BLAS (if installed) vs the wheel's own reference BLAS."""
    script = ("import json, numpy as np, sys; sys.path.insert(0, 'tests'); from test_assemble import *; "
              "from sidprep.assemble import stiffness_and_mass; from sidprep.linalg import eigen_modes, fast_blas; "
              "K, M = stiffness_and_mass(femesh(skfem_box(n=2), 2)[0], MAT); "
              "print(fast_blas()); print(json.dumps(eigen_modes(K, M, count=4, backend='cholmod').eigenvalues[6:].tolist()))")
    out = {}
    for flag in ("0", "1"):
        proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True,
                              cwd=Path(__file__).resolve().parents[1], env=dict(os.environ, SIDPREP_FAST_BLAS=flag))
        blas, values = proc.stdout.strip().splitlines()
        out[flag] = (blas, np.array(json.loads(values)))
    assert out["0"][0] == "reference"
    assert np.allclose(out["1"][1], out["0"][1], rtol=DIRECT_RTOL)
