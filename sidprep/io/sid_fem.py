"""The ASCII ``.SID_FEM`` format (Wallrapp's Standard Input Data): reader and writer.

Grammar, writer and reader rules and the dialect table: ../shared/design/sid-spec.md section 7.
The reader accepts the dialects seen in the wild (section 7.6): ``m1(row, q, col)`` (native) or
``m1(row, col, q)`` (welib, FEMBeam); J as 6x1 or 3x3; Gr/Ge in a-block or k-block column layout,
auto-detected with the invariant relations of section 4.8; nq = 0 in order-0 blocks; structure
codes 0-4 with symmetric mirroring; D/d/E/e exponents; omitted or written zeros; a
``Geo_Stiff= yes`` token on line 1.  In memory, Gr/Ge are always a-block (sidprep.sid).

Numbers are written ``%19.11E`` with a D exponent (12 significant digits).  The format carries no
units: the writer states SI in the line-1 comment, the reader assumes SI.
"""

from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from sidprep.errors import InputError
from sidprep.io.atomic import atomic_path
from sidprep.sid import (DIAGONAL, GENERAL, IDENTITY, SID, SYMMETRIC, ZERO, SIDNode, Taylor,
                         frequencies_from_stiffness, inertia_matrix, j6, skew)

MODAL_MEMBERS = ("mdCM", "J", "Ct", "Cr", "Me", "Gr", "Ge", "Oe", "ksigma", "Ke", "De")
NODE_MEMBERS = ("origin", "phi", "psi", "AP", "sigma")
LAYOUTS = ("a-block", "k-block")
HEADER_FIELDS = ("order", "nrow", "ncol", "nq", "nqn", "structure")

#: relative residual of an invariant relation below which a Gr/Ge layout counts as matching
LAYOUT_MATCH_TOL = 1e-6

_COUNTS = re.compile(r"^\s*(\d+)\s+(\d+)\s*(?::No\. nodes, No\. modes:)?(.*)$")
_INDEXED = re.compile(r"^(m[01n]|ielastq)\s*\(\s*(\d+)\s*(?:,\s*(\d+)\s*)?(?:,\s*(\d+)\s*)?\)$")
_FREQ = re.compile(r":\s*([-+]?\d+(?:\.\d*)?(?:[eEdD][-+]?\d+)?)\s*Hz")
_LAYOUT_HINT = re.compile(r"Gr/Ge\s+(a-block|k-block)")
_GEO_STIFF = re.compile(r"Geo_Stiff\s*=\s*yes", re.IGNORECASE)


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


def _m0_entries(M0: np.ndarray, structure: int):
    """(i, j) 0-based entries of M0 the writer emits for ``structure`` (sid-spec.md 2, 7.4)."""
    if structure in (ZERO, IDENTITY):
        return []
    if structure == DIAGONAL:
        return [(i, i) for i in range(min(M0.shape)) if M0[i, i] != 0]
    return [(i, j) for i, j in zip(*np.nonzero(M0))]


def _taylor_lines(name: str, T: Taylor, nq: int, indent: int) -> list[str]:
    inner = 26                                   # column of the fields in genuine files
    lines = [" " * indent + name]
    header = {"order": T.order, "nrow": T.nrow, "ncol": T.ncol, "nq": nq, "nqn": 0,
              "structure": T.structure}
    lines += [_assign(inner, k, f"{v:5d}") for k, v in header.items()]
    lines += [_assign(inner, f"m0({i + 1:2d},{j + 1:2d})", _number(T.M0[i, j]))
              for i, j in _m0_entries(T.M0, T.structure)]
    if T.M1 is not None:
        cols, rows, qs = np.nonzero(T.M1.transpose(2, 0, 1))     # as genuine files: q fastest
        lines += [_assign(inner, f"m1({i + 1:2d},{k + 1:2d},{j + 1:2d})", _number(T.M1[i, k, j]))
                  for j, i, k in zip(cols, rows, qs)]
    lines.append(" " * indent + f"end {name}")
    return lines


def format_sid_fem(sid: SID, layout: str = "a-block", comment: str = "") -> str:
    """The text of a ``.SID_FEM`` file (grammar sid-spec.md 7.2, writer rules 7.4)."""
    if layout not in LAYOUTS:
        raise InputError(f"SID_FEM layout {layout!r} is unknown; use one of {', '.join(LAYOUTS)}")
    nq = sid.nq
    geo = any(key.startswith("K0") for key in sid.stiffening)
    units = f"{sid.units} (kg, m, s, N, rad)" if sid.units == "SI" else sid.units
    comment = " ".join(comment.split())                         # line 1 must stay one line
    text = (f"sidprep SID, units {units}, Gr/Ge {layout}"
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
    """A Taylor block as written: header fields and 1-based entries with their line numbers."""

    name: str
    line: int
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


def _read_taylor(lines: _Lines, name: str, line: int) -> _RawTaylor:
    raw = _RawTaylor(name, line)
    while True:
        n, text = lines.next(f"'end {name}'")
        if _is_end(text, name):
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
            out["members"][key] = _read_taylor(lines, key, n)
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
            node.members[key] = _read_taylor(lines, key, m)
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


def _build_taylor(lines: _Lines, raw: _RawTaylor, nq: int, m1_order: str) -> Taylor:
    """Apply the reader rules of sid-spec.md 2 / 7.5 to one block."""
    h = raw.header
    if "nrow" not in h or "ncol" not in h:
        raise lines.error(raw.line, f"{raw.name} lacks nrow/ncol")
    nrow, ncol, structure = h["nrow"], h["ncol"], h.get("structure", GENERAL)
    if h.get("nq", nq) not in (nq, 0):
        raise lines.error(raw.line, f"{raw.name} has nq = {h['nq']} but nelastq = {nq}")
    if structure not in (ZERO, DIAGONAL, SYMMETRIC, GENERAL, IDENTITY):
        raise lines.error(raw.line, f"{raw.name} has unknown structure {structure}")
    if structure == IDENTITY and nrow != ncol:
        raise lines.error(raw.line, f"{raw.name}: structure 4 (identity) needs a square matrix")
    M0 = np.eye(nrow) if structure == IDENTITY else np.zeros((nrow, ncol))
    given = np.zeros((nrow, ncol), dtype=bool)
    for n, i, j, v in raw.m0:
        if i > nrow or j > ncol:
            raise lines.error(n, f"m0({i},{j}) is outside the {nrow}x{ncol} matrix {raw.name}")
        M0[i - 1, j - 1] = v
        given[i - 1, j - 1] = True
    if structure == SYMMETRIC and nrow == ncol:
        M0 = np.where(given | ~given.T, M0, M0.T)
    M1 = None
    if h.get("order", 0) >= 1 or raw.m1:
        M1 = np.zeros((nrow, nq, ncol))
        for n, a, b, c, v in raw.m1:
            k, j = (b, c) if m1_order == "row,q,col" else (c, b)
            if a > nrow or k > nq or j > ncol:
                raise lines.error(n, f"m1({a},{b},{c}) is outside {raw.name} ({nrow}x{nq}x{ncol})")
            M1[a - 1, k - 1, j - 1] = v
    return Taylor(M0, M1, structure)


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
    }
    return SID(
        mass=raw["mass"][1], labels=labels, nodes=tuple(nodes), **members,
        frequencies_hz=frequencies,
        mode_kinds=tuple("eigen" if s.strip().lower().startswith("eigen mode") else "other"
                         for s in labels),
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
