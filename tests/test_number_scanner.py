"""The compiled number scanner and triangle passes of sidprep.fe.matrices against independent references.

References: Python's ``float()`` and ``int()`` (CPython's correctly rounded decimal conversion, David
Gay's algorithm) on random decimal strings, and scipy's own COO -> CSR conversion of both triangles.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from sidprep.fe.matrices.numbers import indefinite_entries, mirrored, table_blocks

#: random strings per case (a few hundred kB of text: milliseconds to scan)
STRINGS = 20_000
#: the module docstring's claim beyond Clinger's fast path: a few ulp (2 measured on 200k strings)
LONG_MANTISSA_ULP = 4


def significant_digits(rng, count: int) -> str:
    """``count`` random decimal digits, the first one nonzero."""
    return str(rng.integers(1, 10)) + "".join(map(str, rng.integers(0, 10, count - 1)))


def fast_path_string(rng) -> str:
    """A real of at most 15 significant digits whose decimal shift is within +-22, in one of the
    spellings matrix files use (point anywhere, leading zeros, sign, e/E/d/D exponent or none)."""
    digits = significant_digits(rng, int(rng.integers(1, 16)))
    point = int(rng.integers(0, len(digits) + 1))
    zeros = "0" * int(rng.integers(0, 3)) if point == 0 else ""        # 0.00ddd: not significant
    whole, fraction = digits[:point] or "0", zeros + digits[point:]
    text = rng.choice(["", "+", "-"]) + whole + ("." + fraction if fraction or rng.random() < 0.5 else "")
    if rng.random() < 0.7:
        shift = int(rng.integers(-22, 23))
        exponent = shift + len(fraction)                       # value = digits * 10^shift
        text += str(rng.choice(["e", "E", "d", "D"])) + (f"{exponent:+d}" if rng.random() < 0.5 else str(exponent))
    return text


def long_string(rng) -> str:
    """A real of 16 to 25 significant digits in scientific notation, exponent within +-300."""
    digits = significant_digits(rng, int(rng.integers(16, 26)))
    return f"{rng.choice(['', '-'])}{digits[0]}.{digits[1:]}E{int(rng.integers(-300, 301)):+04d}"


def scanned(tmp_path, lines: list[str], kinds: str):
    """(ints, reals) of the lines written to a file, through table_blocks."""
    path = tmp_path / "numbers.txt"
    path.write_text("\n".join(lines) + "\n")
    blocks = list(table_blocks(path, kinds))
    return np.concatenate([b[0] for b in blocks]), np.concatenate([b[1] for b in blocks])


def python_float(text: str) -> float:
    return float(text.replace("d", "e").replace("D", "e"))


def test_fast_path_reals_are_correctly_rounded(tmp_path):
    """At most 15 digits and a shift within +-22: the same double as float(), bit for bit."""
    rng = np.random.default_rng(20)
    texts = [fast_path_string(rng) for _ in range(STRINGS)]
    _, reals = scanned(tmp_path, texts, "r")
    expected = np.array([python_float(t) for t in texts])
    wrong = np.flatnonzero(reals[:, 0].view(np.int64) != expected.view(np.int64))
    assert not len(wrong), [(texts[k], reals[k, 0], expected[k]) for k in wrong[:5]]


def test_long_mantissas_are_within_a_few_ulp(tmp_path):
    rng = np.random.default_rng(21)
    texts = [long_string(rng) for _ in range(STRINGS)]
    _, reals = scanned(tmp_path, texts, "r")
    expected = np.array([python_float(t) for t in texts])
    ulp = np.abs(reals[:, 0] - expected) / np.spacing(np.abs(expected))
    assert ulp.max() <= LONG_MANTISSA_ULP, texts[int(ulp.argmax())]


def test_integer_and_real_columns_with_separators_and_comments(tmp_path):
    """Blank, tab and comma separators, CR LF line ends, ``*`` / ``$`` comment lines; int() and float()."""
    rng = np.random.default_rng(22)
    rows = [(int(rng.integers(-10 ** 17, 10 ** 17)), int(rng.integers(0, 10 ** 6)), fast_path_string(rng))
            for _ in range(2000)]
    lines = ["** heading", "$ comment"]
    for k, (a, b, x) in enumerate(rows):
        lines.append(f"{a}{[' ', chr(9), ', '][k % 3]}{b}   {x}{chr(13) if k % 5 == 0 else ''}")
    ints, reals = scanned(tmp_path, lines, "iir")
    assert ints.tolist() == [[a, b] for a, b, _ in rows]
    assert reals[:, 0].tolist() == [python_float(x) for _, _, x in rows]


@pytest.mark.parametrize("bad, line", [("1 2 3.0.1", 1), ("1 2 1.0e", 1), ("1 2", 1), ("1 2 3 4", 1),
                                       ("1 x 3.0", 1), ("1 2 --3", 1)])
def test_a_line_that_breaks_the_layout_names_its_byte_and_the_lines_before(tmp_path, bad, line):
    good = "7 8 9.5"
    path = tmp_path / "bad.txt"
    path.write_text(f"{good}\n{bad}\n{good}\n")
    with pytest.raises(ValueError) as caught:
        list(table_blocks(path, "iir"))
    offset, lines = caught.value.args
    assert lines == line and len(good) + 1 <= offset <= len(good) + 1 + len(bad)


def test_mirrored_triangle_equals_scipys_csr_of_both_triangles():
    """Random upper-triangle triplets with duplicates: the same matrix as scipy's COO -> CSR of the
    triplets and their transposes (diagonal once)."""
    rng = np.random.default_rng(23)
    n, nnz = 300, 4000
    a, b = rng.integers(0, n, nnz), rng.integers(0, n, nnz)
    i, j, v = np.minimum(a, b), np.maximum(a, b), rng.standard_normal(nnz)
    off = i != j
    reference = sp.coo_matrix((np.concatenate([v, v[off]]), (np.concatenate([i, j[off]]), np.concatenate([j, i[off]]))),
                              shape=(n, n)).tocsr()
    got = mirrored(i, j, v, n)
    assert abs(got - reference).max() <= 1e-15 * abs(reference).max()
    assert got.has_sorted_indices
    with pytest.raises(ValueError, match="outside"):
        mirrored(np.array([0, n]), np.array([0, 0]), np.ones(2), n)


@pytest.mark.parametrize("index", [np.int32, np.int64])
def test_indefinite_entries_count_the_failed_two_by_two_minors(index):
    rng = np.random.default_rng(24)
    A = sp.random(200, 200, density=0.05, random_state=rng, format="csr")
    A = (A + A.T + sp.diags(rng.uniform(0.05, 2.0, 200))).tocsr()
    A.indptr, A.indices = A.indptr.astype(index), A.indices.astype(index)
    d = A.diagonal()
    rows = np.repeat(np.arange(200), np.diff(A.indptr))
    expected = int(np.count_nonzero(A.data ** 2 > d[rows] * d[A.indices] * (1 + 1e-9)))
    assert expected > 0
    assert indefinite_entries(A.indptr, A.indices, A.data, d, 1e-9) == expected
