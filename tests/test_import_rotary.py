"""Rotary inertia on 6-DOF nodes of imported matrices (a beam stiffener's node with a point inertia,
as Nastran's CONM2 writes it): carried by auxiliary point masses (sidprep.fe.matrices.rotary).

Reference: a rotary inertia J at a node adds J to the body's inertia tensor (no parallel-axis term)
and nothing to its mass or centre of mass; the same model without J is reduced beside it."""

import numpy as np
import pytest
import scipy.sparse as sp
from test_import_formats import BAR, stiffened_bar, write_mtx6

from sidprep.errors import InputError
from sidprep.fe.assemble import mass_matrix, stiffness_matrix
from sidprep.fe.material import builtin_material
from sidprep.fe.mesh import read_mesh
from sidprep.jobs.options import ReduceOptions
from sidprep.jobs.reduce import reduce
from sidprep.sid.model import inertia_matrix

#: the point inertia (kg m^2) about y and z, with a product of inertia, at the stiffener's middle node
J_POINT = np.array([[0.0, 0.0, 0.0], [0.0, 2e-4, 5e-5], [0.0, 5e-5, 3e-4]])
#: inertia and mass of the two SIDs: the auxiliary masses reproduce J exactly (round-off of the
#: 17-digit files and of the least-squares fit)
INERTIA_RTOL = 1e-9


def reduce_with(tmp_path, name, J):
    mesh = read_mesh(BAR)
    steel = builtin_material("steel")
    K6, M6, edge = stiffened_bar(mesh, stiffness_matrix(mesh, steel).tocoo(), mass_matrix(mesh, steel).tocoo())
    r = 3 * mesh.n_nodes + 3 * (len(edge) // 2) + np.arange(3)           # the middle edge node's rotations
    M6 = (M6 + sp.csr_matrix((J.ravel(), (np.repeat(r, 3), np.tile(r, 3))), shape=M6.shape)).tocsr()
    write_mtx6(tmp_path / f"{name}_STIF1.mtx", mesh, K6, edge)
    write_mtx6(tmp_path / f"{name}_MASS1.mtx", mesh, M6, edge)
    return reduce(BAR, ReduceOptions(matrices=str(tmp_path / f"{name}_STIF1.mtx"),
                                     interfaces=("fixed_end:rbe3", "free_end:rbe3"), modes=4))


def test_point_inertia_adds_to_the_body_inertia(tmp_path):
    plain = reduce_with(tmp_path, "plain", np.zeros((3, 3)))
    inertia = reduce_with(tmp_path, "inertia", J_POINT)
    assert inertia.passed
    assert inertia.sid.mass == pytest.approx(plain.sid.mass, rel=INERTIA_RTOL)
    np.testing.assert_allclose(inertia.sid.mdCM.M0, plain.sid.mdCM.M0, rtol=INERTIA_RTOL,
                               atol=INERTIA_RTOL * np.abs(plain.sid.mdCM.M0).max())
    added = inertia_matrix(inertia.sid.J.M0) - inertia_matrix(plain.sid.J.M0)
    np.testing.assert_allclose(added, J_POINT, atol=INERTIA_RTOL * np.abs(inertia_matrix(plain.sid.J.M0)).max())
    assert np.abs(inertia.sid.frequencies_hz[:4] / plain.sid.frequencies_hz[:4] - 1).max() > 1e-4
    assert len(inertia.sid.surface.node_ids) == len(plain.sid.surface.node_ids)      # auxiliary nodes: no surface


def test_inertia_about_a_rotation_without_stiffness_is_refused(tmp_path):
    """The stiffener has no torsion stiffness (its rx DOFs are connected to nothing)."""
    with pytest.raises(InputError, match="rotary inertia about an axis it has no stiffness for"):
        reduce_with(tmp_path, "rx", np.diag([1e-4, 0.0, 0.0]))
