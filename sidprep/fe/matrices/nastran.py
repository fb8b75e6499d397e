"""Nastran: DMIG matrices in a punch file (``PARAM,EXTOUT,DMIGPCH``, or any ``.pch`` of DMIG cards).

DMIG (MSC/NX Nastran Quick Reference Guide, bulk data entry DMIG): a header card
``DMIG NAME 0 IFO TIN TOUT ...`` (IFO 6 symmetric: one triangle given, 1 square: both), then one
card per column ``DMIG NAME GJ CJ (blank) G1 C1 A1 B1 G2 C2 A2 B2 ...`` with continuations; small
field (8 characters), large field (``DMIG*``, 16 characters, ``*`` continuations) or free field
(commas); ``D`` exponents.  The stiffness is the one matrix whose name starts with K (KAAX,
KGG, ...), the mass the one starting with M.  Real matrices only (TIN 1, 2); grid DOFs C = 1..6
(scalar points, C = 0, are refused).  Parsed line by line in Python (~2 s per million entries).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sidprep.errors import InputError
from sidprep.fe.matrices.record import FEMatrices, symmetric_matrix

#: the layout read here (MSC Nastran 2024 / NX Nastran 2312 QRG, DMIG)
FORMAT_VERSION = "nastran-dmig-punch 2024"


def read(path) -> FEMatrices:
    """K and M of the DMIG cards of a punch file (module docstring)."""
    path = Path(path)
    columns = {}
    for fields in cards(path):
        if fields[0].rstrip("*").upper() != "DMIG":
            continue
        name = fields[1].upper()
        if fields[2] == "0":                               # header card
            tin = fields[4] if len(fields) > 4 else ""
            if tin not in ("1", "2"):
                raise InputError(f"{path}: DMIG {name} has TIN = {tin or '(blank)'}; sidprep reads real matrices "
                                 "(TIN 1 or 2): export the real stiffness and mass")
            columns.setdefault(name, [])
            continue
        columns.setdefault(name, []).append(fields)
    K_name, M_name = (pick(path, columns, letter) for letter in ("K", "M"))
    parsed = {name: entries(path, name, columns[name]) for name in (K_name, M_name)}
    keys = np.unique(np.concatenate([np.concatenate([e[0], e[1]]) for e in parsed.values()]))
    n = len(keys)
    K, M = (symmetric_matrix(np.searchsorted(keys, parsed[nm][0]), np.searchsorted(keys, parsed[nm][1]),
                             parsed[nm][2], n, path, f"DMIG {nm}") for nm in (K_name, M_name))
    return FEMatrices(K, M, np.column_stack([keys // 8, keys % 8]), str(path), FORMAT_VERSION)


def pick(path, columns: dict, letter: str) -> str:
    """The one DMIG name starting with ``letter`` (K stiffness, M mass)."""
    names = sorted(n for n in columns if n.startswith(letter))
    if len(names) != 1:
        raise InputError(f"{path}: {len(names)} DMIG matrices named {letter}... ({', '.join(names) or 'none'}; "
                         f"all: {', '.join(sorted(columns)) or 'none'}); the file must hold one stiffness (K...) "
                         "and one mass (M...) matrix, e.g. KAAX and MAAX of PARAM,EXTOUT,DMIGPCH")
    return names[0]


def entries(path, name: str, cards_: list) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(row keys, column keys, values), key = 8 grid + component, of the column cards of one matrix."""
    rows, cols, vals = [], [], []
    try:
        for fields in cards_:
            col = 8 * int(fields[2]) + int(fields[3])
            groups = fields[5:]
            for k in range(0, len(groups) - 2, 4):
                if not groups[k]:
                    continue
                rows.append(8 * int(groups[k]) + int(groups[k + 1]))
                cols.append(col)
                vals.append(nastran_real(groups[k + 2]))
    except (ValueError, IndexError):
        raise InputError(f"{path}: DMIG {name}: a column card has a field that is not a number; the file is "
                         "damaged or truncated: punch it again") from None
    keys = np.array(rows + cols, dtype=np.int64)
    if len(keys) == 0 or (keys % 8 == 0).any() or (keys % 8 > 6).any():
        raise InputError(f"{path}: DMIG {name}: no entries, or components outside 1-6 (scalar points); "
                         "sidprep reads grid-point DOFs 1-6")
    return np.array(rows, np.int64), np.array(cols, np.int64), np.array(vals)


def nastran_real(text: str) -> float:
    """A Nastran real: 1.5E+3, 1.5D+3, and the exponent without a letter, 1.5+3 or -2.-4 (QRG, format)."""
    t = text.strip().upper().replace("D", "E")
    if "E" not in t:
        sign = max(t.rfind("+"), t.rfind("-"))
        if sign > 0:
            t = t[:sign] + "E" + t[sign:]
    return float(t)


#: how deep INCLUDE statements may nest (a deck that includes itself stops here)
INCLUDE_DEPTH = 16


def cards(path, bulk_only: bool = False, depth: int = 0):
    """Yield the fields (stripped strings) of each card: small, large (``*``) or free (``,``) field,
    continuation lines (``+``, ``*`` or blank first field) appended; comments (``$``) skipped;
    ``INCLUDE 'file'`` statements followed (the name may run over several lines inside its quotes;
    a relative name is taken from the including file's folder; QRG, INCLUDE), the included file
    read from its own ``BEGIN BULK`` line on when it has one.
    ``bulk_only``: a whole input deck, read from its ``BEGIN BULK`` line on (when it has one);
    ``depth``: how many INCLUDE statements led here."""
    path = Path(path)
    card = None
    with open(path, errors="replace") as f:
        in_bulk = not (bulk_only and any(x.upper().startswith("BEGIN BULK") for x in f))
        f.seek(0)
        for line in f:
            line = line.rstrip("\r\n")
            if not in_bulk:
                in_bulk = line.upper().startswith("BEGIN BULK")
                continue
            if not line.strip() or line.startswith("$") or line.upper().startswith("ENDDATA"):
                continue
            if line.upper().startswith("INCLUDE"):
                if card is not None:
                    yield card
                    card = None
                if depth >= INCLUDE_DEPTH:
                    raise InputError(f"{path}: INCLUDE statements nest more than {INCLUDE_DEPTH} deep (does a file "
                                     "include itself?); remove the loop")
                yield from cards(included_path(path, line, f), bulk_only, depth + 1)
                continue
            head = line[:8].strip()
            continuation = head.startswith(("+", "*")) or not head
            if "," in line:
                fields = [x.strip() for x in line.split(",")]
                if continuation:
                    fields = fields[1:]
            elif line[:8].rstrip().endswith("*") or (continuation and line.startswith("*")):
                fields = [line[8 + 16 * k:24 + 16 * k].strip() for k in range(4)]
                if not continuation:
                    fields = [head] + fields
            else:
                fields = [line[8 + 8 * k:16 + 8 * k].strip() for k in range(8)]
                if not continuation:
                    fields = [head] + fields
            if continuation:
                if card is None:
                    raise InputError(f"{path}: a continuation line before any card: not a Nastran punch file of DMIG cards; check the file and its ending")
                card.extend(fields)
            else:
                if card is not None:
                    yield card
                card = fields
    if card is not None:
        yield card


def included_path(path: Path, line: str, rest) -> Path:
    """The file an ``INCLUDE`` line of ``path`` names: quoted (its quotes may close on a later line of
    the open file ``rest``, the name's pieces joined without their surrounding blanks) or a bare
    word, relative to ``path``'s folder unless absolute."""
    text = line[len("INCLUDE"):].strip()
    if text[:1] in ("'", '"'):
        quote, name = text[0], text[1:]
        while quote not in name:
            more = next(rest, None)
            if more is None:
                raise InputError(f"{path}: the file name of an INCLUDE statement has no closing quote; close it")
            name = name.strip() + more.strip()
        name = name[:name.index(quote)].strip()
    else:
        name = text.split()[0] if text else ""
    if not name:
        raise InputError(f"{path}: an INCLUDE statement names no file; write INCLUDE 'file.bdf'")
    target = Path(name).expanduser()
    target = target if target.is_absolute() else path.parent / target
    if not target.is_file():
        raise InputError(f"{path}: INCLUDE names {target}, which does not exist; give the included file beside the "
                         "deck or its path")
    return target
