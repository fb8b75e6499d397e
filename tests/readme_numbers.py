"""The numbers an example README states, checked against what the example computes.

A README marks the text whose numbers are results with

    <!-- numbers: NAME -->
    ... prose, tables, quoted warnings ...
    <!-- /numbers -->

The example's test computes every number of the block, in reading order, and calls
``check_numbers(readme, NAME, values)``: each number printed in the block must equal its computed
value rounded to the precision printed (half a unit of the last printed digit), so a change that
moves a result by a printed digit fails the test. Numbers inside `code spans` (commands, formulas)
and inside words (``q1``, ``m^2``) are not results and are skipped. Set-up data, inputs and CPU
times stay outside the blocks.

``SIDPREP_UPDATE_READMES=1 pytest ...`` rewrites the block's numbers with the computed values at the
printed precision and format (then review the diff: the prose around them may need to change too).
"""

from __future__ import annotations

import math
import os
import re
from pathlib import Path
from typing import Sequence

#: a number standing alone: not part of a word (q1, m^2, x1.5) or of a dotted name
NUMBER = re.compile(r"(?<![\w.^/])[+-]?(?:\d+\.\d+|\.\d+|\d+)(?:[eE][+-]?\d+)?(?!\w|\.\d)")
CODE_SPAN = re.compile(r"`[^`\n]*`")
#: slack on the half-unit rounding window for the binary representation of the printed decimal
ROUNDING_SLACK = 1e-9


def block_span(text: str, name: str) -> tuple[int, int]:
    """Character range of the body of block ``name`` in ``text``."""
    start = re.search(rf"<!-- numbers: {re.escape(name)} -->\n", text)
    assert start, f"no '<!-- numbers: {name} -->' block"
    end = text.find("<!-- /numbers -->", start.end())
    assert end > 0, f"block '{name}' has no '<!-- /numbers -->'"
    return start.end(), end


def printed_numbers(body: str) -> list[re.Match]:
    """The result numbers of a block body, in reading order (code spans left out)."""
    spans = [m.span() for m in CODE_SPAN.finditer(body)]
    return [m for m in NUMBER.finditer(body) if not any(a <= m.start() < b for a, b in spans)]


def last_digit_unit(token: str) -> float:
    """Value of one unit in the last printed digit of ``token`` ('0.0301' -> 1e-4, '1.2e-4' -> 1e-5)."""
    mantissa, _, exponent = token.lower().lstrip("+-").partition("e")
    decimals = len(mantissa.partition(".")[2])
    return 10.0 ** (int(exponent or 0) - decimals)


def formatted_like(value: float, token: str) -> str:
    """``value`` printed in the style of ``token`` (sign, decimals, exponent form)."""
    mantissa, e, exponent = token.lstrip("+-").partition("e" if "e" in token else "E")
    decimals = len(mantissa.partition(".")[2])
    sign = "+" if token.startswith("+") else ""
    if not e:
        return f"{value:{sign}.{decimals}f}"
    text = f"{value:{sign}.{decimals}e}"
    head, _, power = text.partition("e")
    digits = len(exponent.lstrip("+-"))
    return f"{head}{e}{'-' if int(power) < 0 else ('+' if exponent.startswith('+') else '')}{abs(int(power)):0{digits}d}"


def matches(value: float, token: str) -> bool:
    """Does ``value`` round to the printed ``token``?"""
    printed = float(token)
    return math.isfinite(value) and abs(value - printed) <= 0.5 * last_digit_unit(token) * (1 + ROUNDING_SLACK) \
        + ROUNDING_SLACK * abs(printed)


def check_numbers(readme: Path, name: str, values: Sequence[float]) -> None:
    """Assert that block ``name`` of ``readme`` prints ``values`` (in reading order) at the
    precision printed; with SIDPREP_UPDATE_READMES=1, rewrite them instead."""
    text = readme.read_text()
    start, end = block_span(text, name)
    body = text[start:end]
    found = printed_numbers(body)
    where = f"{readme.name} block '{name}'"
    assert len(found) == len(values), (f"{where} prints {len(found)} numbers "
                                       f"({[m.group() for m in found]}), the test computes {len(values)}")
    if os.environ.get("SIDPREP_UPDATE_READMES"):
        for m, v in reversed(list(zip(found, values))):
            body = body[:m.start()] + formatted_like(float(v), m.group()) + body[m.end():]
        readme.write_text(text[:start] + body + text[end:])
        return
    wrong = []
    for k, (m, v) in enumerate(zip(found, values), 1):
        if not matches(float(v), m.group()):
            line = body[body.rfind("\n", 0, m.start()) + 1:body.find("\n", m.end())]
            wrong.append(f"  number {k} '{m.group()}' computes {v:.6g} (prints {formatted_like(float(v), m.group())})"
                         f" in: {line.strip()[:120]}")
    assert not wrong, f"{where}: numbers that moved (SIDPREP_UPDATE_READMES=1 rewrites them):\n" + "\n".join(wrong)


def quoted_lines(readme: Path, name: str) -> list[str]:
    """The lines of block ``name`` inside a plain ``` fence (quoted program output)."""
    text = readme.read_text()
    start, end = block_span(text, name)
    return [line for chunk in re.findall(r"```\n(.*?)```", text[start:end], re.S) for line in chunk.splitlines()]
