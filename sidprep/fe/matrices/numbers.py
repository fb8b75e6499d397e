"""Numbers of ASCII matrix files, parsed by a compiled scanner (numpy's text parsers read 12-15 MB/s,
6x sidprep's own assembly at 16k DOF; this one reads ~150 MB/s).

Tokens are separated by blanks, tabs, commas or line ends; a line that starts with ``*`` or ``$`` is a
comment (Abaqus headings, Nastran comments).  A number is ``[+-]digits[.digits][(e|E|d|D)[+-]digits]``
(Fortran's D exponent included).  Values with at most 15 significant digits and a decimal exponent
within +-22 are correctly rounded (Clinger's fast path: an exact integer times or divided by an exact
power of ten); longer mantissas keep their first 18 digits (error below 1e-17 relative).
"""

from __future__ import annotations

import numba
import numpy as np

#: bytes read per block when streaming a file
BLOCK_BYTES = 1 << 26
#: exact powers of ten of float64
_POW10 = np.array([10.0 ** k for k in range(23)])


@numba.njit(cache=True)
def _scan(buf, out, pow10):
    """Parse the numbers of ``buf`` (uint8) into ``out``; returns (count, position of the first byte
    that is not part of a number, separator or comment, or -1)."""
    n = len(buf)
    i = 0
    count = 0
    line_start = True
    while i < n:
        c = buf[i]
        if c == 10 or c == 13:
            line_start = True
            i += 1
            continue
        if c == 32 or c == 9 or c == 44:
            i += 1
            continue
        if line_start and (c == 42 or c == 36):                 # '*' or '$' comment line
            while i < n and buf[i] != 10:
                i += 1
            continue
        line_start = False
        negative = False
        if c == 43 or c == 45:
            negative = c == 45
            i += 1
        mant = 0
        digits = 0
        shift = 0
        seen = False
        while i < n and 48 <= buf[i] <= 57:
            seen = True
            if digits < 18:
                mant = mant * 10 + (buf[i] - 48)
                if mant:
                    digits += 1
            else:
                shift += 1
            i += 1
        if i < n and buf[i] == 46:
            i += 1
            while i < n and 48 <= buf[i] <= 57:
                seen = True
                if digits < 18:
                    mant = mant * 10 + (buf[i] - 48)
                    shift -= 1
                    if mant:
                        digits += 1
                i += 1
        if not seen:
            return count, i
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
                return count, i
            shift += -e if eneg else e
        if i < n and not (buf[i] == 32 or buf[i] == 9 or buf[i] == 44 or buf[i] == 10 or buf[i] == 13):
            return count, i
        value = float(mant)
        if 0 <= shift <= 22:
            value = value * pow10[shift]
        elif -22 <= shift < 0:
            value = value / pow10[-shift]
        else:
            value = value * 10.0 ** shift
        if count >= len(out):
            return count, i
        out[count] = -value if negative else value
        count += 1
    return count, -1


def parse_numbers(text: bytes) -> tuple[np.ndarray, int]:
    """(numbers (k,) float64, -1 or the offset of the first unreadable byte) of ``text``."""
    buf = np.frombuffer(text, dtype=np.uint8)
    out = np.empty(len(text) // 2 + 1)
    count, bad = _scan(buf, out, _POW10)
    return out[:count], int(bad)


def number_blocks(path, columns: int):
    """Yield ((k, columns) float64 rows, byte offset of the block) of an ASCII file, BLOCK_BYTES at a
    time cut at line ends; raises ValueError(offset, rows read) at an unreadable byte or when the
    numbers do not fill whole rows (a truncated file)."""
    with open(path, "rb") as f:
        offset = 0
        while True:
            block = f.read(BLOCK_BYTES)
            if not block:
                return
            block += f.readline()
            values, bad = parse_numbers(block)
            if bad >= 0 or len(values) % columns:
                raise ValueError(offset + max(bad, 0), len(values) // columns)
            yield values.reshape(-1, columns), offset
            offset += len(block)
