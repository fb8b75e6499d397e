"""Numbers of ASCII matrix files, parsed by compiled scanners (numpy's text parsers read 12-15 MB/s:
6x sidprep's own assembly at 16k DOF; these read 100-200 MB/s), and the symmetric CSR matrix of one
triangle of triplets built in two compiled passes.

Tokens are separated by blanks, tabs, commas or line ends; a line that starts with ``*`` or ``$`` is a
comment (Abaqus headings, Nastran comments).  Each line holds the same columns, each an integer
(``[+-]digits``) or a real (``[+-]digits[.digits][(e|E|d|D)[+-]digits]``, Fortran's D exponent
included).  Reals with at most 15 significant digits and a decimal exponent within +-22 are correctly
rounded (Clinger's fast path: an exact integer times or divided by an exact power of ten); others
(longer mantissas: the first 18 digits are kept) within a few ulp.
"""

from __future__ import annotations

import numba
import numpy as np
import scipy.sparse as sp

#: bytes read per block when streaming a file
BLOCK_BYTES = 1 << 26
#: exact powers of ten of float64
_POW10 = np.array([10.0 ** k for k in range(23)])


@numba.njit(cache=True)
def _is_space(c) -> bool:
    return c == 32 or c == 9 or c == 44 or c == 13


@numba.njit(cache=True)
def _digits(buf, i, mant, digits, shift, fraction):
    """Decimal digits from ``buf[i]`` on into the integer mantissa (its first 18 significant digits)
    and the decimal shift; returns (next position, mantissa, significant digits, shift, any digit)."""
    seen = False
    while i < len(buf) and 48 <= buf[i] <= 57:
        seen = True
        if digits < 18:
            mant = mant * 10 + (buf[i] - 48)
            if mant:
                digits += 1
            if fraction:
                shift -= 1
        elif not fraction:
            shift += 1
        i += 1
    return i, mant, digits, shift, seen


@numba.njit(cache=True)
def _real(buf, i, pow10):
    """(value, next position, ok) of the real number starting at ``buf[i]``."""
    n = len(buf)
    negative = False
    if i < n and (buf[i] == 43 or buf[i] == 45):
        negative = buf[i] == 45
        i += 1
    i, mant, digits, shift, seen = _digits(buf, i, 0, 0, 0, False)
    if i < n and buf[i] == 46:
        i, mant, digits, shift, seen_fraction = _digits(buf, i + 1, mant, digits, shift, True)
        seen = seen or seen_fraction
    if not seen:
        return 0.0, i, False
    if i < n and (buf[i] == 101 or buf[i] == 69 or buf[i] == 100 or buf[i] == 68):
        i += 1
        eneg = False
        if i < n and (buf[i] == 43 or buf[i] == 45):
            eneg = buf[i] == 45
            i += 1
        e = 0
        edigits = 0
        while i < n and 48 <= buf[i] <= 57:
            e = min(e * 10 + (buf[i] - 48), 100000)
            edigits += 1
            i += 1
        if edigits == 0:
            return 0.0, i, False
        shift += -e if eneg else e
    value = float(mant)
    if 0 <= shift <= 22:
        value = value * pow10[shift]
    elif -22 <= shift < 0:
        value = value / pow10[-shift]
    else:
        value = value * 10.0 ** shift
    return (-value if negative else value), i, True


@numba.njit(cache=True)
def _integer(buf, i):
    """(value, next position, ok) of the integer starting at ``buf[i]``."""
    n = len(buf)
    negative = False
    if i < n and (buf[i] == 43 or buf[i] == 45):
        negative = buf[i] == 45
        i += 1
    value = 0
    seen = False
    while i < n and 48 <= buf[i] <= 57:
        value = value * 10 + (buf[i] - 48)
        seen = True
        i += 1
    return (-value if negative else value), i, seen


@numba.njit(cache=True)
def _scan_table(buf, is_int, ints, reals, pow10):
    """Parse lines of len(is_int) columns into ``ints`` (k, n_int) and ``reals`` (k, n_real); returns
    (rows parsed, -1 or the position of the first byte that breaks the layout)."""
    n = len(buf)
    ncol = len(is_int)
    i = 0
    row = 0
    while i < n:
        while i < n and (_is_space(buf[i]) or buf[i] == 10):
            i += 1
        if i >= n:
            break
        if buf[i] == 42 or buf[i] == 36:                        # '*' or '$' comment line
            while i < n and buf[i] != 10:
                i += 1
            continue
        if row >= ints.shape[0]:
            return row, i
        ki = 0
        kr = 0
        for col in range(ncol):
            while i < n and _is_space(buf[i]):
                i += 1
            if is_int[col]:
                v, i, ok = _integer(buf, i)
                ints[row, ki] = v
                ki += 1
            else:
                x, i, ok = _real(buf, i, pow10)
                reals[row, kr] = x
                kr += 1
            if not ok or (i < n and not (_is_space(buf[i]) or buf[i] == 10)):
                return row, i
        while i < n and _is_space(buf[i]):
            i += 1
        if i < n and buf[i] != 10:
            return row, i
        row += 1
    return row, -1


def table_blocks(path, kinds: str):
    """Yield (ints (k, n_int) int64, reals (k, n_real) float64) of the lines of an ASCII file whose
    columns are ``kinds`` ("i" integer, "r" real, e.g. "iir"), BLOCK_BYTES at a time cut at line
    ends; raises ValueError(byte offset, complete lines read) where a line breaks the layout."""
    is_int = np.array([k == "i" for k in kinds])
    with open(path, "rb") as f:
        offset, lines = 0, 0
        while True:
            block = f.read(BLOCK_BYTES)
            if not block:
                return
            block += f.readline()
            buf = np.frombuffer(block, dtype=np.uint8)
            most = len(block) // (2 * len(kinds)) + 1           # a line holds >= 2 bytes per column
            ints = np.empty((most, int(is_int.sum())), dtype=np.int64)
            reals = np.empty((most, len(kinds) - int(is_int.sum())))
            rows, bad = _scan_table(buf, is_int, ints, reals, _POW10)
            if bad >= 0:
                raise ValueError(offset + bad, lines + rows)
            yield ints[:rows], reals[:rows]
            offset += len(block)
            lines += rows


@numba.njit(cache=True)
def _mirror_counts(i, j, n):
    counts = np.zeros(n + 1, dtype=np.int64)
    for k in range(len(i)):
        counts[i[k] + 1] += 1
        if i[k] != j[k]:
            counts[j[k] + 1] += 1
    return counts


@numba.njit(cache=True)
def _mirror_fill(i, j, v, indptr, indices, data):
    fill = indptr[:-1].copy()
    for k in range(len(i)):
        a, b = i[k], j[k]
        indices[fill[a]] = b
        data[fill[a]] = v[k]
        fill[a] += 1
        if a != b:
            indices[fill[b]] = a
            data[fill[b]] = v[k]
            fill[b] += 1


def mirrored(i: np.ndarray, j: np.ndarray, v: np.ndarray, n: int) -> sp.csr_matrix:
    """The symmetric (n, n) CSR matrix of the triplets of one triangle (each pair once; duplicates
    summed), in two compiled passes; written in CalculiX's order (upper triangle column by column)
    the rows come out sorted and no sort is needed."""
    indptr = np.cumsum(_mirror_counts(i, j, n))
    indices = np.empty(indptr[-1], dtype=np.int32 if n < 2 ** 31 else np.int64)
    data = np.empty(indptr[-1])
    _mirror_fill(i, j, v, indptr, indices, data)
    A = sp.csr_matrix((data, indices, indptr), shape=(n, n))
    A.sum_duplicates()                                    # sorts rows only when they are not sorted
    return A


@numba.njit(cache=True)
def indefinite_entries(indptr, indices, data, diagonal, rtol):
    """Number of stored entries of a CSR matrix with A_ij^2 > A_ii A_jj (1 + rtol): a symmetric
    positive semi-definite matrix has none (every 2 x 2 principal minor is >= 0)."""
    bad = 0
    for r in range(len(indptr) - 1):
        for k in range(indptr[r], indptr[r + 1]):
            if data[k] * data[k] > diagonal[r] * diagonal[indices[k]] * (1.0 + rtol):
                bad += 1
    return bad
