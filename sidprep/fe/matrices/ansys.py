"""Ansys: the ``.full`` file (binary, written by a modal or substructure solve, or ``WRFULL``), read
through the optional package ansys-mapdl-reader (``pip install "sidprep[ansys]"``: it pulls pyvista
and vtk, ~150 MB, so it is not a default dependency).

``FullFile.load_km(sort=True)`` gives the upper triangles of K and M (CSC) and the DOF reference
(node, DOF 0..5 = UX UY UZ ROTX ROTY ROTZ); DOFs constrained by ``D`` commands are listed in
``FullFile.const`` and have empty rows.  sidprep reduces free models: a file with constrained DOFs
is refused (export the model without ``D`` constraints).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from sidprep.errors import InputError
from sidprep.fe.matrices.record import FEMatrices

#: the layout read here: ansys-mapdl-reader 0.5x (MAPDL .full of releases 14.5 - 2024 R2)
FORMAT_VERSION = "ansys-full (ansys-mapdl-reader 0.5x)"


def full_matrices(path) -> tuple[FEMatrices, np.ndarray]:
    """(K, M and DOF map of a ``.full`` file, (n,) bool: DOFs constrained by D commands)."""
    try:  # optional dependency (pyvista + vtk): imported only when a .full file is read
        from ansys.mapdl import reader as mapdl_reader  # deferred: optional dependency
    except ImportError:
        raise InputError(f"{path}: reading Ansys .full files needs ansys-mapdl-reader; "
                         'pip install "sidprep[ansys]"') from None
    try:
        full = mapdl_reader.read_binary(str(path))
        dof_ref, k, m = full.load_km(sort=True)
        const = np.asarray(full.const, dtype=np.int64).reshape(-1, 2)
    except Exception as exc:                               # the reader raises bare exceptions on bad files
        raise InputError(f"{path}: ansys-mapdl-reader could not read it ({type(exc).__name__}: "
                         f"{(str(exc).strip().splitlines() or [''])[0][:80]}); the file is truncated or not an "
                         "Ansys .full file") from None
    dofs = np.column_stack([dof_ref[:, 0], dof_ref[:, 1] + 1]).astype(np.int64)
    K, M = (sp.csr_matrix(a + sp.triu(a, 1).T) for a in (k, m))
    constrained = np.isin(dof_ref[:, 0] * 8 + dof_ref[:, 1], const[:, 0] * 8 + const[:, 1])
    return FEMatrices(K, M, dofs, str(path), FORMAT_VERSION), constrained


def read(path) -> FEMatrices:
    """K, M and the DOF map of a ``.full`` file of a free model (module docstring)."""
    fe, constrained = full_matrices(path)
    if constrained.any():
        first = fe.dofs[constrained][0]
        raise InputError(f"{path}: {int(constrained.sum())} DOFs are constrained by D commands (first: node "
                         f"{first[0]} DOF {first[1]}); export the free model (no D constraints): sidprep adds "
                         "its own interfaces")
    return fe
