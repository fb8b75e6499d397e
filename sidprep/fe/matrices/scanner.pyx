# cython: language_level=3, boundscheck=False, wraparound=False, initializedcheck=False, cdivision=True
"""The number scanner of ASCII matrix files: one pass over the bytes, no Python object per number.

A table is lines of the same columns, each an integer (``[+-]digits``) or a real
(``[+-]digits[.digits][(e|E|d|D)[+-]digits]``, Fortran's D exponent included), separated by blanks,
tabs, commas or line ends; a line that starts with ``*`` or ``$`` is a comment.

A real is read as an integer mantissa (its first 18 significant digits) times a power of ten.  With at
most 15 significant digits and a decimal exponent within +-22 both are exact doubles, and one
multiplication or division rounds correctly (Clinger 1990, "How to read floating point numbers
accurately", section 3, the fast path).  Other reals take up to three more roundings (the mantissa,
10^shift from ``pow``, a split of small powers that keeps 10^shift normal): a few ulp.
"""

from libc.math cimport pow

cdef enum:
    MANTISSA_DIGITS = 18        # significant digits kept in the integer mantissa (10^18 < 2^63)
    EXACT_POW10 = 22            # the largest exact power of ten of a double (5^22 < 2^53)
    EXPONENT_CAP = 100000       # exponents beyond this saturate (the value is 0 or inf long before)

cdef double POW10[EXACT_POW10 + 1]
for _k in range(EXACT_POW10 + 1):
    POW10[_k] = 10.0 ** _k


cdef struct Decimal:
    unsigned long long mantissa     # the first MANTISSA_DIGITS significant digits
    int digits                      # significant digits held in mantissa
    long long shift                 # the number is mantissa * 10^shift


cdef inline bint is_blank(unsigned char c) noexcept nogil:
    """A separator within a line: blank, tab, comma or carriage return."""
    return c == c' ' or c == c'\t' or c == c',' or c == c'\r'


cdef inline bint is_digit(unsigned char c) noexcept nogil:
    return c'0' <= c <= c'9'


cdef inline Py_ssize_t sign_at(const unsigned char* s, Py_ssize_t n, Py_ssize_t i, bint* negative) noexcept nogil:
    """An optional sign at s[i]: sets ``negative``, returns the position after it."""
    negative[0] = i < n and s[i] == c'-'
    if i < n and (s[i] == c'+' or s[i] == c'-'):
        i += 1
    return i


cdef Py_ssize_t digits_into(const unsigned char* s, Py_ssize_t n, Py_ssize_t i, Decimal* d,
                            bint fraction) noexcept nogil:
    """Decimal digits from s[i] on appended to ``d`` (those of a fraction shift it down, those of an
    integer part beyond MANTISSA_DIGITS up); returns the position after them."""
    while i < n and is_digit(s[i]):
        if d.digits < MANTISSA_DIGITS:
            d.mantissa = d.mantissa * 10 + (s[i] - c'0')
            if d.mantissa:
                d.digits += 1
            if fraction:
                d.shift -= 1
        elif not fraction:
            d.shift += 1
        i += 1
    return i


cdef inline double times_pow10(double x, long long shift) noexcept nogil:
    """x 10^shift: exact powers in one rounding (Clinger's fast path), else through ``pow``, the
    smallest split so that the power stays a normal double."""
    if 0 <= shift <= EXACT_POW10:
        return x * POW10[shift]
    if -EXACT_POW10 <= shift < 0:
        return x / POW10[-shift]
    if shift > 0:
        return x * pow(10.0, <double>shift)
    return x * pow(10.0, <double>(shift + EXACT_POW10)) / POW10[EXACT_POW10]


cdef Py_ssize_t real_at(const unsigned char* s, Py_ssize_t n, Py_ssize_t i, double* value,
                        bint* ok) noexcept nogil:
    """The real number starting at s[i] into ``value`` (``ok`` False if there is none); returns the
    position after it."""
    cdef Decimal d = Decimal(0, 0, 0)
    cdef bint negative, exponent_negative
    cdef long long exponent = 0
    cdef Py_ssize_t start
    i = sign_at(s, n, i, &negative)
    start = i
    i = digits_into(s, n, i, &d, False)
    ok[0] = i > start
    if i < n and s[i] == c'.':
        start = i + 1
        i = digits_into(s, n, start, &d, True)
        ok[0] = ok[0] or i > start
    if not ok[0]:
        return i
    if i < n and (s[i] == c'e' or s[i] == c'E' or s[i] == c'd' or s[i] == c'D'):
        i = sign_at(s, n, i + 1, &exponent_negative)
        start = i
        while i < n and is_digit(s[i]):
            exponent = min(exponent * 10 + (s[i] - c'0'), EXPONENT_CAP)
            i += 1
        if i == start:
            ok[0] = False
            return i
        d.shift += -exponent if exponent_negative else exponent
    value[0] = times_pow10(<double>d.mantissa, d.shift)
    if negative:
        value[0] = -value[0]
    return i


cdef Py_ssize_t integer_at(const unsigned char* s, Py_ssize_t n, Py_ssize_t i, long long* value,
                           bint* ok) noexcept nogil:
    """The integer starting at s[i] into ``value`` (modulo 2^64 beyond int64, as a C integer wraps;
    ``ok`` False if there is none); returns the position after it."""
    cdef bint negative
    cdef unsigned long long magnitude = 0
    cdef Py_ssize_t start
    i = sign_at(s, n, i, &negative)
    start = i
    while i < n and is_digit(s[i]):
        magnitude = magnitude * 10 + (s[i] - c'0')
        i += 1
    ok[0] = i > start
    value[0] = <long long>(0 - magnitude if negative else magnitude)
    return i


cdef Py_ssize_t scan_lines(const unsigned char* s, Py_ssize_t n, const unsigned char[::1] is_int,
                           long long[:, ::1] ints, double[:, ::1] reals, Py_ssize_t* bad) noexcept nogil:
    """Lines of len(is_int) columns into ``ints`` and ``reals``; returns the rows read and sets ``bad``
    to -1, or to the position of the first byte that breaks the layout."""
    cdef Py_ssize_t i = 0, row = 0, col, ki, kr
    cdef bint ok
    bad[0] = -1
    while i < n:
        while i < n and (is_blank(s[i]) or s[i] == c'\n'):
            i += 1
        if i >= n:
            break
        if s[i] == c'*' or s[i] == c'$':                         # a comment line
            while i < n and s[i] != c'\n':
                i += 1
            continue
        if row >= ints.shape[0]:
            bad[0] = i
            return row
        ki = kr = 0
        for col in range(is_int.shape[0]):
            while i < n and is_blank(s[i]):
                i += 1
            if is_int[col]:
                i = integer_at(s, n, i, &ints[row, ki], &ok)
                ki += 1
            else:
                i = real_at(s, n, i, &reals[row, kr], &ok)
                kr += 1
            if not ok or (i < n and not (is_blank(s[i]) or s[i] == c'\n')):
                bad[0] = i
                return row
        while i < n and is_blank(s[i]):
            i += 1
        if i < n and s[i] != c'\n':
            bad[0] = i
            return row
        row += 1
    return row


def scan_table(const unsigned char[::1] buf, const unsigned char[::1] is_int, long long[:, ::1] ints,
               double[:, ::1] reals):
    """Parse the lines of ``buf`` (bytes) with columns ``is_int`` (1 integer, 0 real) into ``ints``
    (k, n_int) int64 and ``reals`` (k, n_real) float64, k >= the lines; returns (rows parsed, -1 or
    the position of the first byte that breaks the layout)."""
    cdef Py_ssize_t rows, bad
    if ints.shape[1] + reals.shape[1] != is_int.shape[0] or ints.shape[0] != reals.shape[0]:
        raise ValueError("ints and reals must have one row per line and one column per kind")
    with nogil:
        rows = scan_lines(&buf[0] if buf.shape[0] else NULL, buf.shape[0], is_int, ints, reals, &bad)
    return rows, bad
