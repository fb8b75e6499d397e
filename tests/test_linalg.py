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

from sidprep.fe.assemble import stiffness_and_mass
from sidprep.errors import InputError
from sidprep.fe.linalg import (clamp_dofs, eigen_modes, factorize, node_dofs, rigid_body_modes,
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
def test_a_right_hand_side_of_the_wrong_length_is_an_error_not_a_corrupted_heap(free_box, backend):
    _, K, M, _ = free_box
    factor = factorize((K + 1e-6 * spectral_scale(K, M) * M).tocsr(), backend)
    for b in (np.zeros(3), np.zeros((3, 1)), np.zeros((K.shape[0] + 1, 2))):
        with pytest.raises(ValueError):
            factor.solve(b)


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
              "from sidprep.fe.assemble import stiffness_and_mass; from sidprep.fe.linalg import eigen_modes, fast_blas; "
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


#: Kane, Ryan & Banerjee (1987) spin-up beam: L = 10 m, EI = 1.4e4 N m^2, rho A = 1.2 kg/m
KANE_L, KANE_EI, KANE_RHOA = 10.0, 1.4e4, 1.2
#: Euler-Bernoulli beta_1 L: clamped-free 1.87510, free-free 4.73004 (closed form)
BETA_L_CLAMPED, BETA_L_FREE = 1.87510407, 4.73004074
#: 3D tet10 (80 x 1 x 1 boxes, 2 cm square section) vs Euler-Bernoulli: shear and mesh stiffness
KANE_FREQ_RTOL = 0.01


def kane_beam_3d():
    """The soft Kane beam as a 3D tet10 bar, 2 cm square section (E, rho give EI, rho A)."""
    from skfem import MeshTet

    from sidprep.fe.material import Material

    a = 0.02
    mat = Material(E=KANE_EI / (a ** 4 / 12), nu=0.3, rho=KANE_RHOA / a ** 2, name="kane")
    m = MeshTet.init_tensor(np.linspace(0, KANE_L, 81), np.linspace(0, a, 2), np.linspace(0, a, 2))
    mesh = femesh(m, 2)[0]
    return mesh, *stiffness_and_mass(mesh, mat)


def beam_hz(beta_l):
    return beta_l ** 2 / (2 * np.pi * KANE_L ** 2) * np.sqrt(KANE_EI / KANE_RHOA)


def test_soft_clamped_beam_has_no_rigid_mode_and_right_first_frequency():
    """lambda_1 = 14.5 (rad/s)^2 lies far below 1e-10 x median(diag K / diag M) = 2.4e3: an absolute
    bound called it rigid; the gap rule does not."""
    mesh, K, M = kane_beam_3d()
    r = clamp_dofs(mesh.n_dof, node_dofs(np.flatnonzero(mesh.points[:, 0] < 1e-9)))
    Kf, Mf = r.restrict(K), r.restrict(M)
    assert 1e-10 * spectral_scale(Kf, Mf) > 14.5          # the case the old bound got wrong
    res = eigen_modes(Kf, Mf, count=2)
    assert res.n_rigid == 0
    assert np.allclose(res.frequencies_hz, beam_hz(BETA_L_CLAMPED), rtol=KANE_FREQ_RTOL)


def test_soft_free_beam_has_six_rigid_modes():
    _, K, M = kane_beam_3d()
    res = eigen_modes(K, M, count=2)
    assert res.n_rigid == 6
    assert np.allclose(res.frequencies_hz[6:], beam_hz(BETA_L_FREE), rtol=KANE_FREQ_RTOL)


@pytest.mark.parametrize("lam, cap, expected", [
    ([1e-7, -2e-7, 3e-8, 1e-7, 2e-7, -1e-7, 14.5, 14.6], 6, 6),   # free body: gap 1e8
    ([14.5, 14.6, 570.0, 571.0, 4000.0], 6, 0),                    # clamped soft body: no gap
    ([1e-7, 2e-7, 3e-7, 1e-7, 2e-7, 1e-7, 14.5], 0, 0),            # clamped part: no rigid mode allowed
    ([1e-7] * 12 + [14.5], 12, 12),                                 # two free parts
])
def test_rigid_mode_count_by_gap_and_count(lam, cap, expected):
    from sidprep.fe.linalg import rigid_mode_count

    assert rigid_mode_count(np.array(lam), 1e12, cap) == expected


ONE_TET = """$MeshFormat
2.2 0 8
$EndMeshFormat
$Nodes
4
1 0 0 0
2 1 0 0
3 0 1 0
4 0 0 1
$EndNodes
$Elements
1
1 4 2 0 1 1 2 3 4
$EndElements
"""


@pytest.mark.parametrize("command", [["reduce", "--modes", "1"], ["reduce", "--modes", "3"], ["reduce", "--modes", "5"],
                                     ["modes", "--count", "3"], ["modes", "--count", "20"]])
def test_one_tet_mesh_never_crashes_the_process(tmp_path, command):
    """Issue 14 item 1: ARPACK/CHOLMOD on a 12-DOF problem aborted with malloc()/SIGSEGV."""
    mesh = tmp_path / "one_tet.msh"
    mesh.write_text(ONE_TET)
    args = [sys.executable, "-m", "sidprep.cli.main", command[0], str(mesh), *command[1:]]
    if command[0] == "reduce":
        args += ["-o", str(tmp_path / "out.h5")]
    root = Path(__file__).resolve().parents[1]
    proc = subprocess.run(args, capture_output=True, text=True, cwd=root,
                          env=dict(os.environ, PYTHONPATH=str(root)), timeout=120)
    assert proc.returncode in (0, 2), proc.stderr[-2000:]
    assert "Traceback" not in proc.stderr


def test_dense_path_returns_every_mode_of_a_tiny_problem(free_box):
    _, K, M, lam_ref = free_box
    res = eigen_modes(K, M, count=len(lam_ref) - 6, backend="cholmod")  # ARPACK cannot: k >= n - 1
    assert res.backend == "dense" and res.n_rigid == 6
    assert np.allclose(res.eigenvalues[6:], lam_ref[6:], rtol=DIRECT_RTOL)
