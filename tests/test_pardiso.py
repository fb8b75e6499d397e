"""sidprep.fe.pardiso: the inertia and Schur complement of a sparse symmetric indefinite LDL^T
against dense LAPACK references (eigenvalue signs by numpy.linalg.eigvalsh, the Schur complement
by a dense solve)."""

import numpy as np
import pytest
import scipy.sparse as sp

from sidprep.fe.pardiso import ldlt_inertia, pardiso_available

pytestmark = pytest.mark.skipif(not pardiso_available(), reason="needs the PyPI wheel mkl (PARDISO)")

#: Schur complement against the dense formula, relative to its largest entry
SCHUR_RTOL = 1e-10


def indefinite(n: int, seed: int) -> sp.csr_matrix:
    rng = np.random.default_rng(seed)
    A = sp.random(n, n, density=0.02, random_state=seed)
    return (A + A.T + sp.diags(3 * rng.standard_normal(n))).tocsr()


def test_inertia_is_the_count_of_negative_eigenvalues():
    A = indefinite(500, 1)
    inertia = ldlt_inertia(A)
    lam = np.linalg.eigvalsh(A.toarray())
    assert inertia.n_perturbed == 0 and inertia.schur is None
    assert (inertia.n_negative, inertia.n_positive) == (np.sum(lam < 0), np.sum(lam > 0))


def test_schur_complement_and_the_interior_inertia():
    A = indefinite(400, 2)
    B = np.sort(np.random.default_rng(3).choice(400, 40, replace=False))
    I = np.setdiff1d(np.arange(400), B)
    D = A.toarray()
    S_ref = D[np.ix_(B, B)] - D[np.ix_(B, I)] @ np.linalg.solve(D[np.ix_(I, I)], D[np.ix_(I, B)])
    inertia = ldlt_inertia(A, B)
    assert np.abs(inertia.schur - S_ref).max() < SCHUR_RTOL * np.abs(S_ref).max()
    assert inertia.n_negative == np.sum(np.linalg.eigvalsh(D[np.ix_(I, I)]) < 0)
    # Sylvester: the interior's negative count plus the Schur complement's is the whole matrix's
    assert inertia.n_negative + np.sum(np.linalg.eigvalsh(inertia.schur) < 0) == np.sum(np.linalg.eigvalsh(D) < 0)


def test_a_matrix_without_stored_diagonal_entries():
    A = sp.csr_matrix(np.array([[0.0, 2.0, 0.0], [2.0, 0.0, 1.0], [0.0, 1.0, 3.0]]))                     # nonsingular, zeros on the diagonal
    inertia = ldlt_inertia(A)
    lam = np.linalg.eigvalsh(A.toarray())
    assert inertia.n_perturbed == 0
    assert (inertia.n_negative, inertia.n_positive) == (np.sum(lam < 0), np.sum(lam > 0))
