"""Lowest natural frequencies of a bundled mesh with some node sets held (plain scikit-fem).

Independent of sidprep's own assembly: P2 elasticity on the corner-node MeshTet (the bundled
meshes have straight-sided tet10, so this is exactly their discretisation), consistent mass,
shift-invert Lanczos.  Used by the generator scripts' ``--check`` option.
"""

import numpy as np


def clamped_frequencies_hz(mesh, held_sets, E, nu, rho, count=3):
    """(count,) lowest frequencies in Hz with all DOFs of the nodes in ``held_sets`` fixed."""
    import skfem
    from scipy.sparse.linalg import eigsh
    from skfem.models.elasticity import lame_parameters, linear_elasticity

    corners = np.unique(mesh.cells[:, :4])
    renumber = np.full(mesh.n_nodes, -1)
    renumber[corners] = np.arange(len(corners))
    m = skfem.MeshTet(mesh.points[corners].T.copy(), renumber[mesh.cells[:, :4]].T.copy())
    basis = skfem.Basis(m, skfem.ElementVector(skfem.ElementTetP2()))
    K = skfem.asm(linear_elasticity(*lame_parameters(E, nu)), basis)

    @skfem.BilinearForm
    def mass(u, v, w):
        return rho * skfem.helpers.dot(u, v)

    M = skfem.asm(mass, basis)
    held = np.zeros(mesh.n_nodes, dtype=bool)
    for name in held_sets:
        held[mesh.node_sets[name]] = True
    held_corner = held[corners]
    facets = np.flatnonzero(held_corner[m.facets].all(axis=0))
    fixed = basis.get_dofs(facets=facets).all()
    free = np.setdiff1d(np.arange(basis.N), fixed)
    lam = eigsh(K[free][:, free], count, M[free][:, free], sigma=0, which="LM")[0]
    return np.sort(np.sqrt(np.abs(lam)) / (2 * np.pi))
