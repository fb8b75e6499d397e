"""The FE model: the mesh and its readers, materials, element assembly of K and M, and the sparse
linear algebra (factorisations, eigen solvers) on them. Imports the base modules only (errors,
progress, tables, lazy)."""

from sidprep.lazy import submodule


def __getattr__(name: str):
    """The package's modules on first use (sidprep.lazy)."""
    return submodule(__name__, name)
