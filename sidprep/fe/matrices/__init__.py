"""Stiffness and mass matrices written by other FE codes: one reader module per format.

Every reader takes the file path and returns :class:`~sidprep.fe.matrices.record.FEMatrices` (sparse K and M in the file's
units, the FE code's DOF map: node number and DOF 1..6 per row), streaming the file into sparse
form (no dense copy).  :func:`read_matrices` picks the reader by the file ending; the mapping onto
the model's nodes, the unit conversion and the checks live in ``sidprep.fe.matrices.onto_model``.

=============  ==============================================  =======================
ending         written by                                      module
=============  ==============================================  =======================
``.sti``       CalculiX ``*FREQUENCY, SOLVER=MATRIXSTORAGE``    ``calculix``
               (``.sti`` K, ``.mas`` M, ``.dof`` DOF map)
``.eig``       CalculiX ``*FREQUENCY, STORAGE=YES``             ``calculix`` (K, M, eigenvalues;
                                                               structure from the deck)
``.mtx``       Abaqus ``*MATRIX GENERATE`` +                   ``abaqus``
               ``*MATRIX OUTPUT, FORMAT=MATRIX INPUT``
``.pch``       Nastran DMIG punch (``PARAM,EXTOUT,DMIGPCH``)   ``nastran``
``.full``      Ansys (modal / substructure solve, ``WRFULL``)  ``ansys`` (optional package)
=============  ==============================================  =======================
"""

from __future__ import annotations

import importlib
from pathlib import Path

import numpy as np

from sidprep.errors import InputError
from sidprep.fe.matrices.record import FEMatrices
from sidprep.lazy import submodule


def reader_for(path):
    """The reader function of the file ending of ``path`` (registry: :data:`READERS`)."""
    path = Path(path)
    name = path.name.lower()
    for suffix, (module, _) in READERS.items():
        if name.endswith(suffix):
            # by name: a reader's own imports (ansys: an optional package) load when its ending is read
            return getattr(importlib.import_module(f"sidprep.fe.matrices.{module}"), "read")
    raise InputError(f"{path}: unknown matrix file ending '{path.suffix}'; use one of "
                     + ", ".join(f"{s} ({what})" for s, (_, what) in READERS.items()))


def read_matrices(path) -> FEMatrices:
    """K, M and the DOF map of ``path`` through the reader of its ending; InputError when the file is
    missing, truncated or not what its ending says."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"matrices = {path}: file not found; check the path")
    fe = reader_for(path)(path)
    check_finite(fe, path)
    return fe


def check_finite(fe: FEMatrices, path) -> None:
    """InputError naming the first NaN or infinite entry of K, M or the eigenvalues (a damaged or
    overflowing file): no such number may reach the eigensolvers (LAPACK, ARPACK)."""
    for what, A in (("stiffness matrix", fe.K), ("mass matrix", fe.M)):
        if np.isfinite(A.data).all():            # CSR: the stored entries
            continue
        bad = np.flatnonzero(~np.isfinite(A.data))
        k = bad[0]
        (n1, d1), (n2, d2) = fe.dofs[np.searchsorted(A.indptr, k, side="right") - 1], fe.dofs[A.indices[k]]
        raise InputError(f"{path}: the {what} holds {bad.size} non-finite entries (first: {A.data[k]} at node {n1} "
                         f"DOF {d1}, node {n2} DOF {d2}); the file is damaged or its numbers overflow: write it "
                         "again")
    if fe.eigenvalues is not None and not np.all(np.isfinite(fe.eigenvalues)):
        k = int(np.flatnonzero(~np.isfinite(fe.eigenvalues))[0])
        raise InputError(f"{path}: eigenvalue {k + 1} is {fe.eigenvalues[k]}, not a finite number; the file is "
                         "damaged: write it again")


#: file ending -> (reader module, what writes it)
READERS = {
    ".sti": ("calculix", "CalculiX *FREQUENCY, SOLVER=MATRIXSTORAGE"),
    ".mas": ("calculix", "the same, its mass file"),
    ".dof": ("calculix", "the same, its DOF map"),
    ".eig": ("calculix", "CalculiX *FREQUENCY, STORAGE=YES"),
    ".mtx": ("abaqus", "Abaqus *MATRIX GENERATE"),
    ".pch": ("nastran", "Nastran DMIG punch, PARAM,EXTOUT,DMIGPCH"),
    ".full": ("ansys", "Ansys .full, through ansys-mapdl-reader"),
}


def __getattr__(name: str):
    """The package's modules on first use (sidprep.lazy)."""
    return submodule(__name__, name)
