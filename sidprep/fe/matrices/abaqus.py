"""Abaqus: ``*MATRIX GENERATE, STIFFNESS, MASS`` with ``*MATRIX OUTPUT, STIFFNESS=YES, MASS=YES,
FORMAT=MATRIX INPUT`` writes ``jobname_STIF1.mtx`` and ``jobname_MASS1.mtx`` (Abaqus Keywords
Reference, *MATRIX OUTPUT): ASCII, one nonzero per line ``row node, row DOF, column node, column
DOF, value`` of one triangle of the symmetric matrix (the other is implied; a file with both
triangles is checked for symmetry), ``**`` heading lines.  Give either file: the other is found by
its name (STIF <-> MASS).  Node numbers are the input file's (internal nodes of connector or
Lagrange elements have numbers the deck does not define: InputError when mapped onto MODEL).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from sidprep.errors import InputError
from sidprep.fe.matrices.record import FEMatrices, symmetric_matrix, text_blocks

#: the layout read here (Abaqus 6.9 - 2024, FORMAT=MATRIX INPUT)
FORMAT_VERSION = "abaqus-mtx matrix-input 2024"
#: DOF numbers of Abaqus: 1-3 translations, 4-6 rotations (others, e.g. 8 temperature, are refused)
DOF_RANGE = (1, 6)


def read(path) -> FEMatrices:
    """K and M of a pair of Abaqus ``_STIF<n>.mtx`` / ``_MASS<n>.mtx`` files (module docstring)."""
    path = Path(path)
    stif, mass = (partner(path, kind) for kind in ("STIF", "MASS"))
    entries = {kind: triplets(p) for kind, p in (("K", stif), ("M", mass))}
    keys = np.unique(np.concatenate([np.concatenate([e[0], e[1]]) for e in entries.values()]))
    n = len(keys)
    K, M = (symmetric_matrix(np.searchsorted(keys, e[0]), np.searchsorted(keys, e[1]), e[2], n, p, what)
            for e, p, what in ((entries["K"], stif, "stiffness matrix"), (entries["M"], mass, "mass matrix")))
    dofs = np.column_stack([keys // 8, keys % 8])
    return FEMatrices(K, M, dofs, str(stif), FORMAT_VERSION)


def partner(path: Path, kind: str) -> Path:
    """The _STIF / _MASS file of the pair ``path`` belongs to."""
    match = re.search(r"_(STIF|MASS)(\d*)\.mtx$", path.name, flags=re.IGNORECASE)
    if not match:
        raise InputError(f"{path}: an Abaqus matrix file is named jobname_STIF1.mtx / jobname_MASS1.mtx "
                         "(*MATRIX OUTPUT, STIFFNESS=YES, MASS=YES); give one of them")
    other = path.with_name(path.name[:match.start(1)] + kind + path.name[match.end(1):])
    if not other.is_file():
        raise InputError(f"{path}: its partner {other.name} is missing; write both with *MATRIX OUTPUT, "
                         "STIFFNESS=YES, MASS=YES and keep them together")
    return other


def triplets(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(row keys, column keys, values) with key = 8 node + DOF, from one .mtx file."""
    blocks = list(text_blocks(path, "iiiir", "Abaqus matrix-input (.mtx: node, DOF, node, DOF, value)"))
    if not blocks:
        raise InputError(f"{path}: no matrix entries; write it again with *MATRIX OUTPUT")
    ints = np.concatenate([b[0] for b in blocks])
    values = np.concatenate([b[1][:, 0] for b in blocks])
    dof = ints[:, [1, 3]]
    if (dof < DOF_RANGE[0]).any() or (dof > DOF_RANGE[1]).any() or (ints[:, [0, 2]] < 1).any():
        raise InputError(f"{path}: DOF numbers outside 1-6 or node numbers below 1; sidprep reads structural "
                         "(displacement) DOFs of the input file's nodes")
    return 8 * ints[:, 0] + ints[:, 1], 8 * ints[:, 2] + ints[:, 3], values
