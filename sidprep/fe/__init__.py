"""The FE model: the mesh and its readers, materials, element assembly of K and M, and the sparse
linear algebra (factorisations, eigen solvers) on them. Imports errors, progress and tables only."""
