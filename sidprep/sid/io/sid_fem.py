"""The ASCII ``.SID_FEM`` format (Wallrapp's Standard Input Data): reader and writer.

Grammar, writer and reader rules and the dialect table: docs/sid-spec.md section 7.
The reader accepts the dialects seen in the wild (section 7.6): ``m1(row, q, col)`` (native) or
``m1(row, col, q)`` (welib, FEMBeam); J as 6x1 or 3x3; Gr/Ge in a-block or k-block column layout,
auto-detected with the invariant relations of section 4.8; nq = 0 in order-0 blocks; structure
codes 0-4 with symmetric mirroring; D/d/E/e exponents; omitted or written zeros; a
``Geo_Stiff= yes`` token on line 1.  In memory, Gr/Ge are always a-block (sidprep.sid.model).

Numbers are written ``%19.11E`` with a D exponent (12 significant digits).  The format carries no
units: the writer states SI in the line-1 comment, the reader assumes SI.
"""

from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from sidprep.errors import InputError, ascii_line
from sidprep.sid.io.atomic import atomic_path
from sidprep.sid.model import (DIAGONAL, GENERAL, IDENTITY, SID, SYMMETRIC, ZERO, SIDNode, Taylor,
                         frequencies_from_stiffness, inertia_matrix, j6, kind_of_label, skew)

MODAL_MEMBERS = ("mdCM", "J", "Ct", "Cr", "Me", "Gr", "Ge", "Oe", "ksigma", "Ke", "De")
NODE_MEMBERS = ("origin", "phi", "psi", "AP", "sigma")
LAYOUTS = ("a-block", "k-block")
HEADER_FIELDS = ("order", "nrow", "ncol", "nq", "nqn", "structure")

#: relative residual of an invariant relation below which a Gr/Ge layout counts as matching
LAYOUT_MATCH_TOL = 1e-6
#: deviation of a written m0 entry from what its structure code promises (zero off the diagonal,
#: the identity, a symmetric partner), relative to max |M0| (at least 1 for the identity), above
#: which the structure contradicts the entries (12-digit rounding; cartop's Ke triangles differ
#: by 1e-14)
STRUCTURE_MATCH_RTOL = 1e-9
#: line-1 comment of the files whose writer writes every entry, zeros included (sidprep's)
ZEROS_WRITTEN_NOTE = "all entries written"

_COUNTS = re.compile(r"^\s*(\d+)\s+(\d+)\s*(?::No\. nodes, No\. modes:)?(.*)$")
_INDEXED = re.compile(r"^(m[01n]|ielastq)\s*\(\s*(\d+)\s*(?:,\s*(\d+)\s*)?(?:,\s*(\d+)\s*)?\)$")
_FREQ = re.compile(r":\s*([-+]?\d+(?:\.\d*)?(?:[eEdD][-+]?\d+)?)\s*Hz")
_LAYOUT_HINT = re.compile(r"Gr/Ge\s+(a-block|k-block)")
_GEO_STIFF = re.compile(r"Geo_Stiff\s*=\s*yes", re.IGNORECASE)
_ZEROS_WRITTEN = re.compile(re.escape(ZEROS_WRITTEN_NOTE))


# ------------------------------------------------------------------------------------------------
# layouts
# ------------------------------------------------------------------------------------------------

def kblock_permutation(nq: int) -> np.ndarray:
    """Columns c of a k-block matrix come from a-block columns perm[c] (sid-spec.md 3.8, 3.9).

    k-block column 3 k + a (0-based) holds omega component a, mode k; a-block column a nq + k.
    """
    return np.array([a * nq + k for k in range(nq) for a in range(3)], dtype=np.int64)


def to_layout(T: Taylor, nq: int, layout: str) -> Taylor:
    """Gr or Ge Taylor object (a-block in memory) with its columns in ``layout``."""
    if layout == "a-block":
        return T
    perm = kblock_permutation(nq)
    return Taylor(T.M0[:, perm], None if T.M1 is None else T.M1[..., perm], T.structure)


def from_layout(T: Taylor, nq: int, layout: str) -> Taylor:
    """Inverse of ``to_layout``: a Gr/Ge read in ``layout`` -> a-block."""
    if layout == "a-block":
        return T
    inv = np.argsort(kblock_permutation(nq))
    return Taylor(T.M0[:, inv], None if T.M1 is None else T.M1[..., inv], T.structure)


# ------------------------------------------------------------------------------------------------
# writer
# ------------------------------------------------------------------------------------------------

def _number(v: float) -> str:
    """Fortran-style real: 12 significant digits, D exponent, blank instead of a plus sign."""
    return f"{v: .11E}".replace("E", "D")


def _assign(indent: int, key: str, value: str) -> str:
    return f"{' ' * indent}{key:<{max(48 - indent, len(key) + 1)}}={value}"


def _m0_entries(M0: np.ndarray, structure: int) -> list[tuple[int, int]]:
    """(i, j) 0-based entries of M0 the writer emits for ``structure`` (sid-spec.md 2, 7.4).

    Every entry the structure code leaves open is written, zeros included (not the spec's
    "omit exact zeros"), so that a reader can tell a deleted line from a zero entry.
    """
    if structure in (ZERO, IDENTITY):
        return []
    if structure == DIAGONAL:
        return [(i, i) for i in range(min(M0.shape))]
    return list(np.ndindex(M0.shape))


def _m1_entries(M1: np.ndarray | None) -> list[tuple[int, int, int]]:
    """(row, q, col) 0-based entries of M1 the writer emits: none if M1 vanishes, else all of them,
    zeros included, the modal index fastest as in genuine files."""
    if M1 is None or not np.any(M1):
        return []
    nrow, nq, ncol = M1.shape
    return [(i, k, j) for j, i, k in np.ndindex(ncol, nrow, nq)]


def _taylor_lines(name: str, T: Taylor, nq: int, indent: int) -> list[str]:
    inner = 26                                   # column of the fields in genuine files
    lines = [" " * indent + name]
    header = {"order": T.order, "nrow": T.nrow, "ncol": T.ncol, "nq": nq, "nqn": 0,
              "structure": T.structure}
    lines += [_assign(inner, k, f"{v:5d}") for k, v in header.items()]
    lines += [_assign(inner, f"m0({i + 1:2d},{j + 1:2d})", _number(T.M0[i, j]))
              for i, j in _m0_entries(T.M0, T.structure)]
    lines += [_assign(inner, f"m1({i + 1:2d},{k + 1:2d},{j + 1:2d})", _number(T.M1[i, k, j]))
              for i, k, j in _m1_entries(T.M1)]
    lines.append(" " * indent + f"end {name}")
    return lines


def format_sid_fem(sid: SID, layout: str = "a-block", comment: str = "") -> str:
    """The text of a ``.SID_FEM`` file (grammar sid-spec.md 7.2, writer rules 7.4)."""
    if layout not in LAYOUTS:
        raise InputError(f"SID_FEM layout {layout!r} is unknown; use one of {', '.join(LAYOUTS)}")
    nq = sid.nq
    geo = any(key.startswith("K0") for key in sid.stiffening)
    units = f"{sid.units} (kg, m, s, N, rad)" if sid.units == "SI" else sid.units
    comment = ascii_line(comment)                               # line 1 must stay one line of ASCII
    text = (f"sidprep SID, units {units}, Gr/Ge {layout}, {ZEROS_WRITTEN_NOTE}"
            f"{'. ' + comment if comment else ''}{' Geo_Stiff= yes' if geo else ''}")
    lines = [f"{len(sid.nodes):5d}{nq:5d}    :No. nodes, No. modes:{text}", " part",
             _assign(6, "new modal", ""), " " * 11 + "refmod",
             _assign(16, "mass", _number(sid.mass)), _assign(16, "nelastq", f"{nq:6d}")]
    lines += [_assign(16, f"ielastq ({k + 1:4d})", " " + label) for k, label in enumerate(sid.labels)]
    lines += [" " * 11 + "end refmod", " " * 11 + "frame"]
    for node in sid.nodes:
        lines += [_assign(16, "new node", f"{node.node_id:8d}"), _assign(21, "rframe", " body ref")]
        for member in NODE_MEMBERS:
            T = getattr(node, member)
            if T is not None:
                lines += _taylor_lines(member, T, nq, 21)
        lines.append(" " * 16 + "end node")
    lines.append(" " * 11 + "end frame")
    for member in MODAL_MEMBERS:
        T = getattr(sid, member)
        if member in ("Gr", "Ge"):
            T = to_layout(T, nq, layout)
        lines += _taylor_lines(member, T, nq, 11)
    lines += [" " * 6 + "end modal", " end part", ""]
    return "\n".join(lines)


def write_sid_fem(sid: SID, path, layout: str = "a-block", comment: str = "") -> Path:
    """Write ``sid`` as a ``.SID_FEM`` file atomically; Gr/Ge columns in ``layout``."""
    text = format_sid_fem(sid, layout, comment)
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="ascii", errors="replace")
    return Path(path)


# ------------------------------------------------------------------------------------------------
# reader
# ------------------------------------------------------------------------------------------------

@dataclass
class _RawTaylor:
    """A Taylor block as written: header fields and 1-based entries with their line numbers.

    ``where`` names the block in messages ("Ke", "node 1125 origin"); ``line`` / ``end`` are the
    lines of its name and of its ``end`` line.
    """

    name: str
    line: int
    where: str = ""
    end: int = 0
    header: dict = field(default_factory=dict)
    m0: list = field(default_factory=list)        # (line, i, j, value)
    m1: list = field(default_factory=list)        # (line, a, b, c, value) as written


@dataclass
class _RawNode:
    name: str
    line: int
    members: dict = field(default_factory=dict)


class _Lines:
    """Stripped, non-blank lines with their 1-based numbers, and errors that name them."""

    def __init__(self, path: Path, text: str):
        self.path = path
        self.items = [(n, s.strip()) for n, s in enumerate(text.splitlines(), 1)
                      if s.strip() and not s.strip().startswith("#")]
        self.pos = 0

    def error(self, line: int, problem: str) -> InputError:
        return InputError(f"{self.path}:{line}: {problem}; this is not a readable SID_FEM file "
                          f"(grammar: sid-spec.md section 7.2), fix or regenerate it")

    def next(self, expected: str) -> tuple[int, str]:
        if self.pos >= len(self.items):
            last = self.items[-1][0] if self.items else 1
            raise self.error(last, f"unexpected end of file, expected {expected}")
        self.pos += 1
        return self.items[self.pos - 1]

    def peek(self) -> str:
        return self.items[self.pos][1] if self.pos < len(self.items) else ""


def _split(text: str) -> tuple[str, str | None]:
    """``key = value`` -> (key, value); a line without '=' -> (line, None)."""
    key, eq, value = text.partition("=")
    return (key.strip(), value.strip()) if eq else (text.strip(), None)


def _real(lines: _Lines, line: int, value: str) -> float:
    try:
        return float(value.replace("D", "E").replace("d", "e"))
    except ValueError:
        raise lines.error(line, f"{value!r} is not a number") from None


def _int(lines: _Lines, line: int, value: str) -> int:
    try:
        return int(value)
    except ValueError:
        raise lines.error(line, f"{value!r} is not an integer") from None


def _is_end(text: str, name: str) -> bool:
    return text.split() == ["end", name]


def _read_taylor(lines: _Lines, name: str, line: int, where: str) -> _RawTaylor:
    raw = _RawTaylor(name, line, where)
    while True:
        n, text = lines.next(f"'end {name}'")
        if _is_end(text, name):
            raw.end = n
            return raw
        key, value = _split(text)
        if value is None:
            raise lines.error(n, f"'{text}' inside {name} (missing 'end {name}'?)")
        if key in HEADER_FIELDS:
            raw.header[key] = _int(lines, n, value)
            continue
        match = _INDEXED.match(key)
        if not match or match.group(1) == "ielastq":
            raise lines.error(n, f"unknown entry '{key}' in {name}")
        idx = [int(g) for g in match.groups()[1:] if g is not None]
        kind = match.group(1)
        if len(idx) != (2 if kind == "m0" else 3):
            raise lines.error(n, f"'{key}' has {len(idx)} indices")
        if min(idx) < 1:
            raise lines.error(n, f"'{key}': indices are 1-based")
        if kind == "m0":
            raw.m0.append((n, *idx, _real(lines, n, value)))
        elif kind == "m1":
            raw.m1.append((n, *idx, _real(lines, n, value)))
        elif _real(lines, n, value) != 0.0:
            raise lines.error(n, f"higher-order entry '{key}' is not supported (order <= 1)")


def _parse(lines: _Lines) -> dict:
    """The raw content of a file: counts, refmod, nodes and modal members (not yet converted)."""
    out = {"counts": None, "comment": "", "labels": {}, "nodes": [], "members": {}}
    first_line, first = lines.items[0] if lines.items else (1, "")
    match = _COUNTS.match(first)
    if match:
        out["counts"] = (int(match.group(1)), int(match.group(2)))
        out["comment"] = match.group(3).strip()
    while lines.peek() != "part":                   # lines before 'part' are comments
        lines.next("'part'")
    lines.next("'part'")
    n, text = lines.next("'new modal ='")
    if _split(text)[0] != "new modal":
        raise lines.error(n, f"expected 'new modal =', found '{text}'")
    while True:
        n, text = lines.next("'end modal'")
        key, value = _split(text)
        if _is_end(text, "modal"):
            return out
        if key == "refmod":
            _parse_refmod(lines, out)
        elif key in ("frame", "new frame"):
            _parse_frame(lines, out)
        elif key in MODAL_MEMBERS and value is None:
            if key in out["members"]:
                raise lines.error(n, f"member {key} appears twice")
            out["members"][key] = _read_taylor(lines, key, n, key)
        else:
            raise lines.error(n, f"unexpected '{text}' in modal (members: refmod, frame, "
                                 f"{', '.join(MODAL_MEMBERS)})")


def _parse_refmod(lines: _Lines, out: dict) -> None:
    while True:
        n, text = lines.next("'end refmod'")
        if _is_end(text, "refmod"):
            return
        key, value = _split(text)
        if key == "mass" and value is not None:
            out["mass"] = (n, _real(lines, n, value))
        elif key == "nelastq" and value is not None:
            out["nelastq"] = (n, _int(lines, n, value))
        elif (match := _INDEXED.match(key)) and match.group(1) == "ielastq" and value is not None:
            out["labels"][int(match.group(2))] = (n, value)
        else:
            raise lines.error(n, f"unexpected '{text}' in refmod")


def _parse_frame(lines: _Lines, out: dict) -> None:
    while True:
        n, text = lines.next("'end frame'")
        key, value = _split(text)
        if _is_end(text, "frame"):
            return
        if key != "new node" or value is None:
            raise lines.error(n, f"expected 'new node = <id>' or 'end frame', found '{text}'")
        node = _RawNode(value, n)
        while True:
            m, text = lines.next("'end node'")
            key, value = _split(text)
            if _is_end(text, "node"):
                break
            if key == "rframe":
                continue
            if key not in NODE_MEMBERS or value is not None:
                raise lines.error(m, f"unexpected '{text}' in node {node.name}")
            node.members[key] = _read_taylor(lines, key, m, f"node {node.name} {key}")
        out["nodes"].append(node)


def _detect_m1_order(lines: _Lines, blocks: list[_RawTaylor], nq: int) -> str:
    """'row,q,col' (native) unless only 'row,col,q' fits every m1 index (sid-spec.md 7.6)."""
    def fits(swapped: bool) -> bool:
        for raw in blocks:
            nrow, ncol = raw.header.get("nrow", 0), raw.header.get("ncol", 0)
            for _, a, b, c, _ in raw.m1:
                k, j = (c, b) if swapped else (b, c)
                if a > nrow or k > nq or j > ncol:
                    return False
        return True
    if fits(False):
        return "row,q,col"
    if fits(True):
        return "row,col,q"
    bad = next(e for raw in blocks for e in raw.m1 if e[1] > raw.header.get("nrow", 0)
               or max(e[2], e[3]) > max(nq, raw.header.get("ncol", 0)))
    raise lines.error(bad[0], f"m1 index {bad[1:4]} is out of range for nq = {nq}")


def _m1_index(a: int, b: int, c: int, m1_order: str) -> tuple[int, int, int]:
    """0-based (row, q, col) of the written 1-based ``m1(a, b, c)`` in ``m1_order``."""
    return (a - 1, b - 1, c - 1) if m1_order == "row,q,col" else (a - 1, c - 1, b - 1)


def _check_header(lines: _Lines, raw: _RawTaylor, nq: int, zeros_written: bool) -> None:
    """The header of a block: nrow and ncol present, all six fields if the file writes its zeros
    (its writer follows sid-spec.md 7.4 rule 2: a missing one is damage), else the others take
    their defaults (order 0, nq = nelastq, nqn 0, structure 3); nq and structure admissible."""
    required = HEADER_FIELDS if zeros_written else ("nrow", "ncol")
    missing = [key for key in required if key not in raw.header]
    if missing:
        raise lines.error(raw.line, f"{raw.where} lacks its header line(s) {', '.join(missing)}")
    h = raw.header = {"order": 0, "nq": nq, "nqn": 0, "structure": GENERAL, **raw.header}
    if h["nq"] not in (nq, 0):
        raise lines.error(raw.line, f"{raw.where} has nq = {h['nq']} but nelastq = {nq}")
    if h["structure"] not in (ZERO, DIAGONAL, SYMMETRIC, GENERAL, IDENTITY):
        raise lines.error(raw.line, f"{raw.where} has unknown structure {h['structure']}")
    if h["structure"] in (IDENTITY, SYMMETRIC) and h["nrow"] != h["ncol"]:
        raise lines.error(raw.line, f"{raw.where}: structure {h['structure']} needs a square matrix")


def _check_no_duplicates(lines: _Lines, raw: _RawTaylor) -> None:
    """Each m0 / m1 index is written at most once."""
    seen = {}
    for kind, entries in (("m0", raw.m0), ("m1", raw.m1)):
        for n, *idx, _ in entries:
            key = f"{kind}({','.join(map(str, idx))})"
            if key in seen:
                raise lines.error(n, f"{key} of {raw.where} is written twice (lines {seen[key]} and {n})")
            seen[key] = n


def _structure_violation(M0: np.ndarray, given: np.ndarray, structure: int) -> tuple[int, int] | None:
    """The written m0 entry that contradicts ``structure`` most.

    Zero (0): every written entry is zero; diagonal (1): written off-diagonal entries are zero;
    identity (4): written entries are those of E; symmetric (2): entries written in both triangles
    agree.  Deviations count relative to max |M0| (at least 1 for the identity).

    Parameters
    ----------
    M0 : (nrow, ncol) ndarray
        The matrix with the written entries in place (before mirroring).
    given : (nrow, ncol) bool ndarray
        Which entries are written.
    structure : int
        The declared structure code.

    Returns
    -------
    tuple of int or None
        0-based (i, j) of the worst entry beyond STRUCTURE_MATCH_RTOL, or None.
    """
    if structure == GENERAL or not given.any():
        return None
    if structure == SYMMETRIC:
        deviation = np.where(given & given.T, np.abs(M0 - M0.T), 0.0)
    else:
        promised = {ZERO: np.zeros_like(M0), DIAGONAL: M0 * np.eye(*M0.shape), IDENTITY: np.eye(len(M0))}
        deviation = np.where(given, np.abs(M0 - promised[structure]), 0.0)
    scale = max(np.max(np.abs(M0)), 1.0 if structure == IDENTITY else 0.0)
    worst = np.unravel_index(np.argmax(deviation), deviation.shape)
    return worst if deviation[worst] > STRUCTURE_MATCH_RTOL * scale else None


def _build_taylor(lines: _Lines, raw: _RawTaylor, nq: int, m1_order: str) -> Taylor:
    """Apply the reader rules of sid-spec.md 2 / 7.5 to one block.

    Its header is checked (:func:`_check_header`).  Errors for an index outside the declared
    dimensions, an entry written twice, or a structure code the written entries contradict.
    """
    _check_no_duplicates(lines, raw)
    h = raw.header
    nrow, ncol, structure = h["nrow"], h["ncol"], h["structure"]
    M0 = np.eye(nrow) if structure == IDENTITY else np.zeros((nrow, ncol))
    given = np.zeros((nrow, ncol), dtype=bool)
    for n, i, j, v in raw.m0:
        if i > nrow or j > ncol:
            raise lines.error(n, f"m0({i},{j}) is outside the {nrow}x{ncol} matrix {raw.where}")
        M0[i - 1, j - 1] = v
        given[i - 1, j - 1] = True
    bad = _structure_violation(M0, given, structure)
    if bad is not None:
        line = next(n for n, i, j, _ in raw.m0 if (i - 1, j - 1) == bad)
        raise lines.error(line, f"m0({bad[0] + 1},{bad[1] + 1}) = {M0[bad]:.6g} contradicts "
                                f"structure {structure} of {raw.where}")
    if structure == SYMMETRIC:
        M0 = np.where(given | ~given.T, M0, M0.T)
    M1 = None
    if h["order"] >= 1 or raw.m1:
        M1 = np.zeros((nrow, nq, ncol))
        for n, a, b, c, v in raw.m1:
            i, k, j = _m1_index(a, b, c, m1_order)
            if i >= nrow or k >= nq or j >= ncol:
                raise lines.error(n, f"m1({a},{b},{c}) is outside {raw.where} ({nrow}x{nq}x{ncol})")
            M1[i, k, j] = v
    return Taylor(M0, M1, structure)


def _complete_m0_sets(structure: int, nrow: int, ncol: int) -> list[np.ndarray]:
    """Masks of the m0 entry sets a writer that writes zeros may emit for ``structure``.

    Zero and identity: none, or all (welib); diagonal: the diagonal, or all; symmetric: one
    triangle (welib, FEMBeam) or both (cartop); general: all.
    """
    full = np.ones((nrow, ncol), dtype=bool)
    return {ZERO: [~full, full], IDENTITY: [~full, full], DIAGONAL: [np.eye(nrow, ncol, dtype=bool), full],
            SYMMETRIC: [np.tril(full), np.triu(full), full]}.get(structure, [full])


def _absent_entries(raw: _RawTaylor, nq: int, m1_order: str, zeros_written: bool) -> tuple[int, str]:
    """The entries of a block that are not written.

    m0 counts against the closest complete set of :func:`_complete_m0_sets`; m1 (order >= 1 or m1
    lines) against all nrow x nq x ncol entries: a writer that writes zeros may leave out a
    vanishing M1 entirely, a writer that omits zeros leaves out its zero entries.

    Returns
    -------
    count : int
        How many entries are not written.
    first : str
        The first of them as the file would write it ("m0(2,1)", "m1(3,1,1)"); "" if none.
    """
    h = raw.header
    nrow, ncol = h["nrow"], h["ncol"]
    given = np.zeros((nrow, ncol), dtype=bool)
    for _, i, j, _ in raw.m0:
        given[i - 1, j - 1] = True
    m0_absent = min((mask & ~given for mask in _complete_m0_sets(h["structure"], nrow, ncol)
                     if not np.any(given & ~mask)), key=np.count_nonzero)
    m1_absent = np.zeros((nrow, nq, ncol), dtype=bool)
    if raw.m1 or (h["order"] >= 1 and not zeros_written):
        m1_absent[:] = True
        for _, a, b, c, _ in raw.m1:
            m1_absent[_m1_index(a, b, c, m1_order)] = False
    count = int(np.count_nonzero(m0_absent) + np.count_nonzero(m1_absent))
    if np.any(m0_absent):
        i, j = np.argwhere(m0_absent)[0] + 1
        return count, f"m0({i},{j})"
    if np.any(m1_absent):
        i, k, j = np.argwhere(m1_absent)[0] + 1
        return count, f"m1({i},{k},{j})" if m1_order == "row,q,col" else f"m1({i},{j},{k})"
    return 0, ""


def _entry_census(lines: _Lines, blocks: list[_RawTaylor], nq: int, m1_order: str,
                  zeros_written: bool) -> dict:
    """Entries written and left out over all blocks (metadata ``sid_fem_entries``).

    In a file whose writer writes zeros (:data:`ZEROS_WRITTEN_NOTE` on line 1, or any entry
    written as zero), a left-out entry is damage: InputError naming the block and its lines.
    """
    omitted = 0
    for raw in blocks:
        count, first = _absent_entries(raw, nq, m1_order, zeros_written)
        if count and zeros_written:
            total = count + len(raw.m0) + len(raw.m1)
            raise InputError(f"{lines.path}:{raw.line}-{raw.end}: {raw.where} lacks {count} of its "
                             f"{total} entries (first {first}) although this file writes its zero "
                             f"entries: the file is truncated or edited; re-export it")
        omitted += count
    return {"zeros_written": zeros_written, "omitted_entries": omitted,
            "written_entries": sum(len(raw.m0) + len(raw.m1) for raw in blocks)}


def _writes_zeros(comment: str, blocks: list[_RawTaylor]) -> bool:
    """Does the file's writer write zero entries (line-1 note, or any entry written as zero)?"""
    return bool(_ZEROS_WRITTEN.search(comment)) or any(
        entry[-1] == 0.0 for raw in blocks for entry in raw.m0 + raw.m1)


def _j_as_vector(J: Taylor) -> Taylor:
    """J read as a 3x3 matrix (welib, FEMBeam) -> the native 6x1 vector (sid-spec.md 3.4)."""
    M1 = None if J.M1 is None else j6(J.M1.transpose(1, 0, 2)).T[:, :, None]
    return Taylor(j6(J.M0)[:, None], M1, GENERAL)


def _relative(residual: float, scale: float) -> float:
    return residual / scale if scale > 0 else (0.0 if residual == 0 else np.inf)


def _gr_residuals(Gr: Taylor, J: Taylor, Cr: Taylor, nq: int) -> dict:
    """Relative residual of sym(Gr0_k) = I1_k (or Gr0_k - Gr0_k^T = -2 skew(Cr0_k)) per layout."""
    if nq < 2:                                                  # the layouts coincide
        return {layout: np.nan for layout in LAYOUTS}
    out = {}
    for layout in LAYOUTS:
        G = from_layout(Gr, nq, layout).M0.reshape(3, 3, nq).transpose(2, 0, 1)
        if J.M1 is not None and np.any(J.M1):
            ref = np.stack([inertia_matrix(J.M1[:, k, 0]) for k in range(nq)])
            res = np.linalg.norm(0.5 * (G + G.transpose(0, 2, 1)) - ref)
        else:
            ref = -2 * np.stack([skew(c) for c in Cr.M0])
            res = np.linalg.norm(G - G.transpose(0, 2, 1) - ref)
        out[layout] = _relative(res, max(np.linalg.norm(ref), np.linalg.norm(G)))
    return out


def _ge_residuals(Ge: Taylor, Cr: Taylor, nq: int) -> dict:
    """Relative residual of Ge_a = 2 Cr.M1[:, :, a] per layout (antisymmetric parts if needed)."""
    if Cr.M1 is None or nq < 2:
        return {layout: np.nan for layout in LAYOUTS}
    ref = 2 * Cr.M1.transpose(2, 0, 1)
    full, anti = {}, {}
    for layout in LAYOUTS:
        G = from_layout(Ge, nq, layout).M0.reshape(nq, 3, nq).transpose(1, 0, 2)
        scale = max(np.linalg.norm(ref), np.linalg.norm(G))
        full[layout] = _relative(np.linalg.norm(G - ref), scale)
        skew_part = lambda A: A - A.transpose(0, 2, 1)  # noqa: E731
        anti[layout] = _relative(np.linalg.norm(skew_part(G) - skew_part(ref)), scale)
    return full if min(full.values()) <= LAYOUT_MATCH_TOL else anti


def _pick_layout(residuals: dict, hint: str | None) -> tuple[str, bool]:
    """(layout, decided): the clearly smaller residual, else the file's hint or a-block."""
    a, k = residuals["a-block"], residuals["k-block"]
    if np.isfinite(a) and np.isfinite(k) and abs(a - k) > LAYOUT_MATCH_TOL * max(1.0, min(a, k)):
        return ("a-block" if a < k else "k-block"), True
    return hint or "a-block", False


def _dialect(m1_order: str, j_form: str, gr: str, ge: str) -> str:
    if m1_order == "row,col,q" or j_form == "3x3":
        return "welib/FEMBeam"
    return {("a-block", "a-block"): "native", ("k-block", "a-block"): "PY_SID"}.get((gr, ge), "other")


def parse_sid_fem(text: str, path="<text>") -> SID:
    """A SID from the text of a ``.SID_FEM`` file (reader rules sid-spec.md 7.5, 7.6)."""
    lines = _Lines(Path(path), text)
    raw = _parse(lines)
    if "nelastq" not in raw or "mass" not in raw:
        raise lines.error(1, "refmod with mass and nelastq is missing")
    nq_line, nq = raw["nelastq"]
    if sorted(raw["labels"]) != list(range(1, nq + 1)):
        raise lines.error(nq_line, f"nelastq = {nq} but ielastq labels {sorted(raw['labels'])}")
    missing = [m for m in MODAL_MEMBERS if m not in raw["members"]]
    if missing:
        raise lines.error(lines.items[-1][0], f"modal members missing: {', '.join(missing)}")
    if raw["counts"] and raw["counts"] != (len(raw["nodes"]), nq):
        raise lines.error(1, f"line 1 announces {raw['counts'][0]} nodes and {raw['counts'][1]} "
                             f"modes, the file has {len(raw['nodes'])} and {nq}")
    blocks = list(raw["members"].values()) + [t for nd in raw["nodes"] for t in nd.members.values()]
    zeros_written = _writes_zeros(raw["comment"], blocks)
    for block in blocks:
        _check_header(lines, block, nq, zeros_written)
    m1_order = _detect_m1_order(lines, blocks, nq)
    build = lambda r: _build_taylor(lines, r, nq, m1_order)  # noqa: E731
    members = {name: build(r) for name, r in raw["members"].items()}

    j_form = f"{members['J'].nrow}x{members['J'].ncol}"
    if j_form == "3x3":
        members["J"] = _j_as_vector(members["J"])
    elif j_form != "6x1":
        raise lines.error(raw["members"]["J"].line, f"J is {j_form}; expected 6x1 or 3x3")
    expected = {"mdCM": (3, 1), "Ct": (nq, 3), "Cr": (nq, 3), "Me": (nq, nq), "Gr": (3, 3 * nq),
                "Ge": (nq, 3 * nq), "Oe": (nq, 6), "ksigma": (nq, 1), "Ke": (nq, nq), "De": (nq, nq)}
    for name, shape in expected.items():
        if members[name].M0.shape != shape:
            raise lines.error(raw["members"][name].line,
                              f"{name} is {members[name].nrow}x{members[name].ncol}, expected "
                              f"{shape[0]}x{shape[1]} for nelastq = {nq}")
    hint = (m.group(1) if (m := _LAYOUT_HINT.search(raw["comment"])) else None)
    gr_res = _gr_residuals(members["Gr"], members["J"], members["Cr"], nq)
    ge_res = _ge_residuals(members["Ge"], members["Cr"], nq)
    (gr_layout, gr_decided), (ge_layout, ge_decided) = _pick_layout(gr_res, hint), _pick_layout(ge_res, hint)
    members["Gr"] = from_layout(members["Gr"], nq, gr_layout)
    members["Ge"] = from_layout(members["Ge"], nq, ge_layout)

    nodes = []
    for index, nd in enumerate(raw["nodes"]):
        parts = {name: build(r) for name, r in nd.members.items()}
        absent = [m for m in NODE_MEMBERS[:4] if m not in parts]
        if absent:
            raise lines.error(nd.line, f"node {nd.name} lacks {', '.join(absent)}")
        if parts["phi"].M0.shape != (3, nq):
            raise lines.error(nd.members["phi"].line, f"phi of node {nd.name} is not 3x{nq}")
        node_id = int(nd.name) if nd.name.lstrip("-").isdigit() else index + 1
        nodes.append(SIDNode(node_id, parts["origin"], parts["phi"], parts["psi"], parts["AP"],
                             parts.get("sigma"), nd.name))
    entries = _entry_census(lines, blocks, nq, m1_order, zeros_written)

    labels = tuple(raw["labels"][k][1] for k in range(1, nq + 1))
    from_labels = [float(m.group(1).replace("D", "E").replace("d", "e")) if (m := _FREQ.search(s))
                   else np.nan for s in labels]
    from_ke = frequencies_from_stiffness(members["Me"].M0, members["Ke"].M0)
    frequencies = np.where(np.isfinite(from_labels), from_labels, from_ke)
    metadata = {
        "source": str(path),
        "format": "SID_FEM",
        "header_comment": raw["comment"],
        "geo_stiff": bool(_GEO_STIFF.search(raw["comment"])),
        "units_note": "SID_FEM carries no units; SI assumed",
        "sid_fem_dialect": {
            "name": _dialect(m1_order, j_form, gr_layout, ge_layout) + (
                "" if gr_decided and ge_decided else
                " (Gr/Ge layouts coincide for nq < 2)" if nq < 2 else
                " (Gr/Ge layout not detectable, assumed " + gr_layout + ")"),
            "m1_index_order": m1_order, "J": j_form, "Gr_layout": gr_layout,
            "Ge_layout": ge_layout, "layouts_detected": gr_decided and ge_decided,
            "Gr_layout_residuals": {k: float(v) if np.isfinite(v) else None for k, v in gr_res.items()},
            "Ge_layout_residuals": {k: float(v) if np.isfinite(v) else None for k, v in ge_res.items()},
        },
        "frequencies_from_Ke_hz": [float(f) for f in from_ke],
        "sid_fem_entries": entries,
    }
    return SID(
        mass=raw["mass"][1], labels=labels, nodes=tuple(nodes), **members,
        frequencies_hz=frequencies,
        mode_kinds=tuple(kind_of_label(s) for s in labels),
        units="SI", metadata=metadata)


def read_sid_fem(path) -> SID:
    """Read a ``.SID_FEM`` file; bad content raises InputError naming the file and line."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror}); check the path") from None
    sid = parse_sid_fem(data.decode("latin-1"), path)
    return replace(sid, metadata=dict(sid.metadata, sha256=hashlib.sha256(data).hexdigest()))
