"""The README number checker (tests/readme_numbers.py) fails when a printed result moves."""

import pytest

from readme_numbers import check_numbers, formatted_like, printed_numbers

README = """# x
<!-- numbers: r -->
| t [s] | flap | q1 (7.9 Hz) |
|---|---|---|
| 0.5 | +0.0312 | 1.138e-2 |

the hinge force `m g + 2 m^2 g d^2 / I_h` = 769.3 N, q3 1.2e-4.
<!-- /numbers -->
12.5 outside
"""


@pytest.fixture
def readme(tmp_path):
    path = tmp_path / "README.md"
    path.write_text(README)
    return path


def test_numbers_in_words_and_code_spans_are_not_results():
    assert [m.group() for m in printed_numbers(README)] == ["7.9", "0.5", "+0.0312", "1.138e-2", "769.3", "1.2e-4",
                                                            "12.5"]


def test_values_that_round_to_the_printed_digits_pass(readme):
    check_numbers(readme, "r", [7.91, 0.5, 0.031249, 0.0113849, 769.34, 1.249e-4])


@pytest.mark.parametrize("k, value", [(2, 0.03126), (3, 0.011386), (4, 769.36), (0, 7.96)])
def test_a_moved_digit_fails(readme, k, value):
    values = [7.9, 0.5, 0.0312, 0.01138, 769.3, 1.2e-4]
    values[k] = value
    with pytest.raises(AssertionError, match="moved"):
        check_numbers(readme, "r", values)


def test_a_missing_number_fails(readme):
    with pytest.raises(AssertionError, match="prints 6 numbers"):
        check_numbers(readme, "r", [7.9, 0.5, 0.0312, 0.01138, 769.3])


def test_update_rewrites_in_the_printed_format(readme, monkeypatch):
    monkeypatch.setenv("SIDPREP_UPDATE_READMES", "1")
    check_numbers(readme, "r", [7.9, 0.5, 0.0299, 0.00987651, 770.04, -3.3e-5])
    assert "| 0.5 | +0.0299 | 9.877e-3 |" in readme.read_text() and "= 770.0 N, q3 -3.3e-5." in readme.read_text()
    assert formatted_like(-0.0, "-0.0000") == "-0.0000" and formatted_like(2.04e-10, "1e-14") == "2e-10"


def test_the_examples_index_quotes_what_each_example_readme_says():
    """Every number of the index's "reference" column (examples/README.md) is one its example's
    README states (the README's numbers are the ones its test computes)."""
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[1] / "examples"
    rows = re.findall(r"^\| `([a-z_]+)/` \|.*\| ([^|]*) \|$", (root / "README.md").read_text(), re.M)
    assert len(rows) >= 10
    for name, reference in rows:
        stated = {float(m.group()) for m in printed_numbers((root / name / "README.md").read_text())}
        quoted = [m.group() for m in printed_numbers(reference)]
        missing = [q for q in quoted if float(q) not in stated]
        assert not missing, f"examples/README.md quotes {missing} for {name}/, which its README does not state"
