"""What every matrix reader returns (:class:`FEMatrices`: K, M and the FE code's DOF map) and the
steps the readers share: a symmetric matrix from one or both triangles of triplets, and the
streamed numeric blocks of an ASCII matrix file.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from sidprep.errors import InputError
from sidprep.fe.matrices.numbers import mirrored, table_blocks


@dataclass(frozen=True)
class FEMatrices:
    """K and M of a whole FE model as its code wrote them.

    K, M : (nd, nd) scipy CSR, symmetric, in the file's unit system (force / length, mass);
    dofs : (nd, 2) int64, node number of the FE code and DOF 1..6 (x, y, z, rx, ry, rz) of each row;
    source : the file read; fmt : format name and the reader's format version;
    eigenvalues : (k,) the FE code's own eigenvalues (rad/s)^2 when the file carries them, else None.
    """

    K: sp.csr_matrix
    M: sp.csr_matrix
    dofs: np.ndarray
    source: str
    fmt: str
    eigenvalues: np.ndarray | None = None


#: |A - A^T| / max |A| above this: the file's matrix is not symmetric
SYMMETRY_RTOL = 1e-8


def symmetric_matrix(rows, cols, values, n: int, path, what: str) -> sp.csr_matrix:
    """The symmetric (n, n) CSR matrix of triplets (0-based): each off-diagonal pair given once (one
    triangle in the FE code's own equation order, mirrored: sidprep.fe.matrices.numbers.mirrored) or
    twice (both triangles, checked to ``SYMMETRY_RTOL``); duplicates summed."""
    rows, cols, values = (np.asarray(a) for a in (rows, cols, values))
    if not ((rows > cols).any() and (rows < cols).any()):
        return mirrored(rows, cols, values, n)            # one triangle by index (CalculiX, most files)
    off = rows != cols
    pattern = sp.csr_matrix((np.ones(int(off.sum())), (rows[off], cols[off])), shape=(n, n))
    pattern.sum_duplicates()
    both = pattern.multiply(pattern.T).nnz
    if both == 0:
        return mirrored(rows, cols, values, n)            # one entry per pair, in the code's own order
    if both != pattern.nnz:
        raise InputError(f"{path}: {what} gives {pattern.nnz - both} off-diagonal entries without their mirror "
                         f"and {both} with it; a file holds one triangle or the whole symmetric matrix: write it again")
    A = sp.csr_matrix((values, (rows, cols)), shape=(n, n))
    scale = max(float(np.abs(A.data).max(initial=0.0)), np.finfo(float).tiny)
    asym = float(np.abs(A - A.T).max()) / scale
    if asym > SYMMETRY_RTOL:
        raise InputError(f"{path}: {what} is not symmetric (|A - A^T| / max|A| = {asym:.1e}); "
                         "export the symmetric matrix of a linear elastic model (no friction, "
                         "follower loads or unsymmetric solver)")
    return A


def text_blocks(path, kinds: str, what: str):
    """Yield (ints, reals) blocks of the lines of an ASCII file with columns ``kinds`` ("i" integer,
    "r" real; blank- or comma-separated, ``*``/``$`` comment lines), streamed
    (sidprep.fe.matrices.numbers.table_blocks); a line that breaks the layout is an InputError (a
    truncated or foreign file)."""
    try:
        yield from table_blocks(path, kinds)
    except ValueError as exc:
        offset, rows = exc.args
        raise InputError(f"{path}: unreadable or incomplete line near byte {offset} (after {rows} complete "
                         f"lines); the file is truncated or not a {what} file: write it again or check "
                         "its ending") from None
