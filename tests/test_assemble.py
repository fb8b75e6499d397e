"""Assembly of K, M, Ms for tet4 / tet10 against independent references.

References: scikit-fem's own assembly (linear_elasticity, rho u.v) on the same mesh, the
closed-form strain energy of a quadratic displacement field, rigid-body motions (zero energy)
and the total mass rho V (V known in closed form, also for a curved tet10 mesh).
"""

from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
from skfem import Basis, BilinearForm, ElementTetP1, ElementTetP2, ElementVector, MeshTet, asm
from skfem.helpers import dot
from skfem.models.elasticity import linear_elasticity

from sidprep.fe.assemble import (_keast_points, lumped_scalar_mass, mass_matrix, scalar_mass_matrix, stiffness_matrix,
    vector_mass)
from sidprep.errors import InputError
from sidprep.fe.linalg import rigid_body_modes
from sidprep.fe.material import Material
from sidprep.fe.mesh import FEMesh, read_mesh
from sidprep.fe.topology import TET10_EDGES

#: assembled matrices agree with scikit-fem's to round-off (relative Frobenius norm)
SKFEM_RTOL = 1e-12
#: exactly integrated quantities (energy of a quadratic field, mass) to round-off
EXACT_RTOL = 1e-12
#: rigid-body motions: ||K r|| relative to ||K|| ||r||
NULL_RTOL = 1e-12

MAT = Material(E=210e9, nu=0.3, rho=7850.0, name="steel")


def skfem_box(n=3, seed=0):
    """A unit-cube MeshTet with jittered interior vertices (non-uniform element shapes)."""
    m = MeshTet.init_tensor(*(np.linspace(0.0, 1.0, n + 1),) * 3)
    p = m.p.copy()
    interior = np.all((p > 1e-9) & (p < 1 - 1e-9), axis=0)
    p[:, interior] += np.random.default_rng(seed).uniform(-0.15, 0.15, (3, interior.sum())) / n
    return MeshTet(p, m.t)


def femesh(m: MeshTet, order: int):
    """FEMesh (positively oriented, canonical VTK order) of a scikit-fem mesh, and the map
    sidprep DOF (3 i + c) -> scikit-fem DOF of the matching P1/P2 vector basis."""
    t = m.t.T.copy()
    x = m.p.T
    vol = np.einsum("ij,ij->i", np.cross(x[t[:, 1]] - x[t[:, 0]], x[t[:, 2]] - x[t[:, 0]]), x[t[:, 3]] - x[t[:, 0]])
    t[vol < 0] = t[vol < 0][:, [0, 2, 1, 3]]
    basis = Basis(m, ElementVector(ElementTetP2() if order == 2 else ElementTetP1()))
    dof_of_node = [basis.nodal_dofs.T]
    points = [x]
    if order == 2:
        edge_index = {tuple(e): k for k, e in enumerate(np.sort(m.edges, axis=0).T.tolist())}
        mids = np.array([[edge_index[tuple(sorted((a[i], a[j])))] for i, j in TET10_EDGES] for a in t.tolist()])
        t = np.hstack([t, x.shape[0] + mids])
        points.append(0.5 * (x[m.edges[0]] + x[m.edges[1]]))
        dof_of_node.append(basis.edge_dofs.T)
    mesh = FEMesh(points=np.vstack(points), cells=t, node_ids=np.arange(sum(len(q) for q in points)) + 1)
    return mesh, basis, np.vstack(dof_of_node).ravel()


def rel_diff(A, B):
    return np.linalg.norm((A - B).toarray()) / np.linalg.norm(B.toarray())


@pytest.mark.parametrize("order", [1, 2])
def test_matrices_equal_scikit_fem_assembly(order):
    mesh, basis, perm = femesh(skfem_box(), order)
    lam, mu = MAT.lame

    @BilinearForm
    def mass(u, v, w):
        return MAT.rho * dot(u, v)

    K_ref = asm(linear_elasticity(lam, mu), basis)[perm][:, perm]
    M_ref = asm(mass, basis)[perm][:, perm]
    assert rel_diff(stiffness_matrix(mesh, MAT), K_ref) < SKFEM_RTOL
    assert rel_diff(mass_matrix(mesh, MAT), M_ref) < SKFEM_RTOL


def quadratic_field(points):
    """u = (x y, y z, z x); on the unit cube its strain energy is (2.5 lam + 3 mu) / 2."""
    x, y, z = points.T
    return np.stack([x * y, y * z, z * x], axis=1).ravel()


def test_strain_energy_of_quadratic_field_exact_for_p2_only():
    """Also the tet10 node-order test: a mid-edge node on the wrong edge changes the energy."""
    lam, mu = MAT.lame
    exact = 0.5 * (2.5 * lam + 3.0 * mu)
    energies = {}
    for order in (1, 2):
        mesh, _, _ = femesh(skfem_box(), order)
        u = quadratic_field(mesh.points)
        energies[order] = 0.5 * u @ (stiffness_matrix(mesh, MAT) @ u)
    assert abs(energies[2] / exact - 1) < EXACT_RTOL
    assert abs(energies[1] / exact - 1) > 1e-3


def curved_p2_box():
    """P2 box mapped by x -> x + A x^2 (quadratic, so reproduced exactly by the isoparametric
    geometry: curved edges); det of the map is 1 + 2 A x, so the volume is 1 + A."""
    mesh, _, _ = femesh(skfem_box(n=2), 2)
    p = mesh.points.copy()
    p[:, 0] += CURVE_A * p[:, 0] ** 2
    return FEMesh(points=p, cells=mesh.cells, node_ids=mesh.node_ids)


CURVE_A = 0.3


@pytest.mark.parametrize("make", [lambda: femesh(skfem_box(), 1)[0], lambda: femesh(skfem_box(), 2)[0], curved_p2_box])
def test_rigid_body_modes_are_in_null_space_of_K(make):
    mesh = make()
    K = stiffness_matrix(mesh, MAT)
    R = rigid_body_modes(mesh.points)
    norm_K = np.abs(K).sum(axis=1).max()
    assert np.linalg.norm(K @ R, axis=0).max() / (norm_K * np.linalg.norm(R, axis=0).max()) < NULL_RTOL


@pytest.mark.parametrize("make, volume", [(lambda: femesh(skfem_box(), 1)[0], 1.0),
                                          (lambda: femesh(skfem_box(), 2)[0], 1.0),
                                          (curved_p2_box, 1.0 + CURVE_A)])
def test_total_mass_is_rho_V(make, volume):
    mesh = make()
    total = MAT.rho * volume
    Ms = scalar_mass_matrix(mesh, MAT.rho)
    M = mass_matrix(mesh, MAT)
    tx = rigid_body_modes(mesh.points)[:, 0]
    assert abs(Ms.sum() / total - 1) < EXACT_RTOL
    assert abs(tx @ (M @ tx) / total - 1) < EXACT_RTOL
    lumped = lumped_scalar_mass(mesh, MAT.rho)
    assert abs(lumped.sum() / total - 1) < EXACT_RTOL
    assert (lumped > 0).all()  # HRZ for P2: no negative vertex masses
    assert np.allclose(mass_matrix(mesh, MAT, lumped=True).diagonal(), np.repeat(lumped, 3))


def test_inverted_element_is_input_error():
    mesh, _, _ = femesh(skfem_box(n=1), 2)
    cells = mesh.cells.copy()
    cells[0, [1, 2]] = cells[0, [2, 1]]
    cells[0, [4, 6]] = cells[0, [6, 4]]
    cells[0, [8, 9]] = cells[0, [9, 8]]
    with pytest.raises(InputError, match="non-positive Jacobian"):
        stiffness_matrix(FEMesh(points=mesh.points, cells=cells, node_ids=mesh.node_ids), MAT)


@pytest.mark.parametrize("degree", [2, 4])
def test_quadrature_rules_are_scikit_fems(degree):
    """The Keast rules written out in sidprep.fe.assemble are the ones scikit-fem gives."""
    from skfem.quadrature import get_quadrature
    from skfem.refdom import RefTet

    points, weights = _keast_points()[degree]
    ref_points, ref_weights = get_quadrature(RefTet, degree)
    np.testing.assert_allclose(points, ref_points, atol=1e-15)
    np.testing.assert_allclose(weights, ref_weights, atol=1e-16)


def test_vector_mass_is_the_kronecker_product_with_the_identity():
    # written as CSR directly; the second formulation: scipy's kron, entry for entry, no explicit zeros
    mesh = read_mesh(Path(__file__).resolve().parents[1] / "data" / "meshes" / "piston_rod.msh")
    Ms = scalar_mass_matrix(mesh, 7850.0)
    M, ref = vector_mass(Ms), sp.kron(Ms, sp.identity(3), format="csr")
    assert M.shape == ref.shape and M.nnz == ref.nnz and M.has_sorted_indices
    assert (M != ref).nnz == 0
