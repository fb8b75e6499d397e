"""Numbers of ASCII matrix files, parsed by a compiled scanner (sidprep/fe/matrices/scanner.pyx;
numpy's text parsers read 12-15 MB/s: 6x sidprep's own assembly at 16k DOF), and the symmetric CSR
matrix of one triangle of triplets built in two compiled passes (sidprep/fe/matrices/triangles.pyx).

Tokens are separated by blanks, tabs, commas or line ends; a line that starts with ``*`` or ``$`` is a
comment (Abaqus headings, Nastran comments).  Each line holds the same columns, each an integer
(``[+-]digits``) or a real (``[+-]digits[.digits][(e|E|d|D)[+-]digits]``, Fortran's D exponent
included).  Reals with at most 15 significant digits and a decimal exponent within +-22 are correctly
rounded (Clinger's fast path: an exact integer times or divided by an exact power of ten); others
(longer mantissas: the first 18 digits are kept) within a few ulp.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

try:
    from sidprep.fe.matrices.scanner import scan_table
    from sidprep.fe.matrices.triangles import indefinite_entries, mirror_counts, mirror_fill
except ModuleNotFoundError as exc:          # a source checkout whose extensions were never built
    raise ImportError(f"{exc}: sidprep's compiled modules are not built in this checkout; run `pip install -e .` "
                      "in it (a C compiler and Python's headers are needed)") from exc

__all__ = ["indefinite_entries", "mirrored", "table_blocks"]

#: bytes read per block when streaming a file
BLOCK_BYTES = 1 << 26


def table_blocks(path, kinds: str):
    """Yield (ints (k, n_int) int64, reals (k, n_real) float64) of the lines of an ASCII file whose
    columns are ``kinds`` ("i" integer, "r" real, e.g. "iir"), BLOCK_BYTES at a time cut at line
    ends; raises ValueError(byte offset, complete lines read) where a line breaks the layout."""
    is_int = np.array([k == "i" for k in kinds], dtype=np.uint8)
    with open(path, "rb") as f:
        offset, lines = 0, 0
        while True:
            block = f.read(BLOCK_BYTES)
            if not block:
                return
            block += f.readline()
            most = len(block) // (2 * len(kinds)) + 1           # a line holds >= 2 bytes per column
            ints = np.empty((most, int(is_int.sum())), dtype=np.int64)
            reals = np.empty((most, len(kinds) - int(is_int.sum())))
            rows, bad = scan_table(block, is_int, ints, reals)
            if bad >= 0:
                raise ValueError(offset + bad, lines + rows)
            yield ints[:rows], reals[:rows]
            offset += len(block)
            lines += rows


def mirrored(i: np.ndarray, j: np.ndarray, v: np.ndarray, n: int) -> sp.csr_matrix:
    """The symmetric (n, n) CSR matrix of the triplets of one triangle (each pair once; duplicates
    summed), in two compiled passes; written in CalculiX's order (upper triangle column by column)
    the rows come out sorted and no sort is needed.  i, j : (nnz,) integers in 0..n-1; v : (nnz,)."""
    i, j, v = np.asarray(i, dtype=np.int64), np.asarray(j, dtype=np.int64), np.asarray(v, dtype=np.float64)
    indptr = np.cumsum(mirror_counts(i, j, n))
    indices = np.empty(indptr[-1], dtype=np.int32 if n < 2 ** 31 else np.int64)
    data = np.empty(indptr[-1])
    mirror_fill(i, j, v, indptr, indices, data)
    A = sp.csr_matrix((data, indices, indptr), shape=(n, n))
    A.sum_duplicates()                                    # sorts rows only when they are not sorted
    return A
