"""Keyword blocks of an Abaqus / CalculiX input deck, read as CalculiX reads them.

A deck is a sequence of keyword lines (``*NAME, PARAM=value, FLAG``) each followed by its data
lines; ``**`` lines are comments, ``*INCLUDE`` is resolved (sidprep.fe.readers.abaqus).  CalculiX (ccx
2.x User's Manual, "Input deck format") accepts any number of ``*NODE`` blocks and numbers the
nodes by the numbers written, not by their order; meshio keeps only the last block, so a deck with
several is handed to meshio as one block (:func:`single_node_block`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sidprep.errors import InputError
from sidprep.fe.readers.abaqus import abaqus_lines


@dataclass(frozen=True)
class Block:
    """One keyword and its data: keyword upper case without ``*`` and blanks (RIGIDBODY); params {NAME: value} (upper case
    keys and values, "" for a flag); lines: the data lines (stripped, comments dropped)."""

    keyword: str
    params: dict
    lines: tuple[str, ...]


def keyword_blocks(path) -> list[Block]:
    """The keyword blocks of the deck ``path`` (``*INCLUDE`` followed), in file order."""
    blocks, head, data = [], None, []
    for line in abaqus_lines(path) + ["*END OF DECK\n"]:
        if line.startswith("**") or not line.strip():
            continue
        if line.startswith("*"):
            if head is not None:
                blocks.append(Block(head[0], head[1], tuple(data)))
            words = [w.strip() for w in line[1:].split(",")]
            params = {}
            for w in words[1:]:
                key, _, value = w.partition("=")
                if key:
                    params[key.strip().upper().replace(" ", "")] = value.strip().upper()
            head, data = (words[0].upper().replace(" ", ""), params), []
        else:
            data.append(line.strip())
    return blocks


def fields(lines) -> list[str]:
    """The comma-separated fields of data lines, empty trailing fields dropped."""
    return [f.strip() for line in lines for f in line.rstrip(",").split(",")]


def deck_nodes(blocks, path) -> tuple[np.ndarray, np.ndarray]:
    """(ids (n,) int64, coordinates (n, 3)) of every ``*NODE`` block, in file order (missing
    coordinates are 0, as CalculiX reads them)."""
    ids, xyz = [], []
    for b in blocks:
        if b.keyword != "NODE":
            continue
        for line in b.lines:
            row = [f.strip() for f in line.split(",")]
            try:
                ids.append(int(row[0]))
                xyz.append([float(v) if v else 0.0 for v in (row[1:4] + ["", "", ""])[:3]])
            except ValueError:
                raise InputError(f"{path}: *NODE line '{line}' is not 'number, x, y, z'; fix the deck") from None
    return np.array(ids, np.int64), np.array(xyz, float).reshape(-1, 3)


def node_sets(blocks, path) -> dict[str, np.ndarray]:
    """{name: node numbers} of the ``*NSET`` blocks (numbers, ranges with GENERATE, other sets by
    name) and of ``*NODE, NSET=``; names upper case, as CalculiX compares them."""
    sets: dict[str, list] = {}
    for b in blocks:
        if b.keyword == "NODE" and "NSET" in b.params:
            sets.setdefault(b.params["NSET"], []).extend(int(line.split(",")[0]) for line in b.lines)
        if b.keyword != "NSET" or "NSET" not in b.params:
            continue
        out = sets.setdefault(b.params["NSET"], [])
        values = [v for v in fields(b.lines) if v]
        try:
            if "GENERATE" in b.params:
                for k in range(0, len(values) - 1, 3):
                    step = int(values[k + 2]) if k + 2 < len(values) else 1
                    out.extend(range(int(values[k]), int(values[k + 1]) + 1, step))
                continue
            for v in values:
                out.extend([int(v)] if v.lstrip("-").isdigit() else sets[v.upper()])
        except (KeyError, ValueError):
            raise InputError(f"{path}: *NSET, NSET={b.params['NSET']} names an unknown set or holds a field that is "
                             "not a node number; define the sets it uses before it") from None
    return {k: np.unique(np.array(v, np.int64)) for k, v in sets.items()}


def single_node_block(path) -> str | None:
    """The deck's text with all ``*NODE`` blocks merged into the first (``NSET=`` of the others
    written as ``*NSET`` blocks), or None when it has at most one: what meshio needs to read a deck
    of several blocks."""
    lines = abaqus_lines(path)
    heads = [k for k, line in enumerate(lines) if line[:5].upper() == "*NODE" and line[5:6] in (",", "\n", " ", "\r")]
    if len(heads) < 2:
        return None
    merged, sets, out, k = [], [], [], 0
    while k < len(lines):
        line = lines[k]
        if k in heads:
            first = k == heads[0]
            nset = dict((w.split("=", 1) + [""])[:2] for w in (x.strip() for x in line.split(",")[1:]) if w)
            body = []
            k += 1
            while k < len(lines) and not (lines[k].startswith("*") and not lines[k].startswith("**")):
                if lines[k].strip() and not lines[k].startswith("**"):
                    body.append(lines[k])
                k += 1
            merged += body
            name = {key.upper(): v for key, v in nset.items()}.get("NSET")
            if name:
                sets += [f"*NSET, NSET={name}\n"] + [b.split(",", 1)[0] + "\n" for b in body]
            if first:
                out += ["*NODE\n", None]                     # None: where the merged lines go
            continue
        out.append(line)
        k += 1
    at = out.index(None)
    return "".join(out[:at] + merged + sets + out[at + 1:])


def deck_text_path(path, tmp) -> Path:
    """``path`` itself, or a copy in the directory ``tmp`` with one ``*NODE`` block
    (:func:`single_node_block`), for readers that keep only the last block."""
    text = single_node_block(path)
    if text is None:
        return Path(path)
    flat = Path(tmp) / Path(path).name
    flat.write_text(text)
    return flat


#: corner-node faces S1, S2, ... of the solid element families (Abaqus / CalculiX local numbering,
#: 0-based; ccx 2.x User's Manual, "*SURFACE"); a face's nodes are these corners and the mid-edge
#: nodes between two of them
FACE_CORNERS = {"C3D8": [(0, 1, 2, 3), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)],
                "C3D4": [(0, 1, 2), (0, 1, 3), (1, 2, 3), (0, 2, 3)],
                "C3D6": [(0, 1, 2), (3, 4, 5), (0, 1, 4, 3), (1, 2, 5, 4), (2, 0, 3, 5)]}
#: the element edges of the mid-edge nodes, in local order after the corners
MID_EDGES = {"C3D20": [(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4), (0, 4), (1, 5), (2, 6),
                       (3, 7)],
             "C3D10": [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)],
             "C3D15": [(0, 1), (1, 2), (2, 0), (3, 4), (4, 5), (5, 3), (0, 3), (1, 4), (2, 5)]}
#: quadratic type -> its linear family, nodes per element
FAMILIES = {"C3D8": ("C3D8", 8), "C3D20": ("C3D8", 20), "C3D4": ("C3D4", 4), "C3D10": ("C3D4", 10),
            "C3D6": ("C3D6", 6), "C3D15": ("C3D6", 15)}


def elements(blocks) -> dict[int, tuple[str, np.ndarray]]:
    """{element number: (type without R/H/I/M suffix, node numbers)} of the solid *ELEMENT blocks."""
    out = {}
    for b in blocks:
        kind = b.params.get("TYPE", "").rstrip("RHIM")
        if b.keyword != "ELEMENT" or kind not in FAMILIES:
            continue
        values = np.array([int(v) for v in fields(b.lines) if v], np.int64)
        rows = values.reshape(-1, FAMILIES[kind][1] + 1)
        out.update({int(r[0]): (kind, r[1:]) for r in rows})
    return out


def element_sets(blocks, path) -> dict[str, np.ndarray]:
    """{name: element numbers} of ``*ELEMENT, ELSET=`` and ``*ELSET`` (numbers, GENERATE, other sets)."""
    sets: dict[str, list] = {}
    for b in blocks:
        if b.keyword == "ELEMENT" and "ELSET" in b.params:
            sets.setdefault(b.params["ELSET"], []).extend(int(line.split(",")[0]) for line in b.lines
                                                           if line.split(",")[0].strip().isdigit())
        if b.keyword != "ELSET" or "ELSET" not in b.params:
            continue
        out = sets.setdefault(b.params["ELSET"], [])
        values = [v for v in fields(b.lines) if v]
        try:
            if "GENERATE" in b.params:
                for k in range(0, len(values) - 1, 3):
                    out.extend(range(int(values[k]), int(values[k + 1]) + 1, int(values[k + 2]) if k + 2 < len(values)
                                     else 1))
                continue
            for v in values:
                out.extend([int(v)] if v.isdigit() else sets[v.upper()])
        except (KeyError, ValueError):
            raise InputError(f"{path}: *ELSET, ELSET={b.params['ELSET']} names an unknown set or holds a field that "
                             "is not an element number; define the sets it uses before it") from None
    return {k: np.unique(np.array(v, np.int64)) for k, v in sets.items()}


def face_nodes(kind: str, nodes: np.ndarray, face: int) -> np.ndarray:
    """Node numbers on face S``face`` (1-based) of one element of type ``kind``."""
    family = FAMILIES[kind][0]
    corners = FACE_CORNERS[family][face - 1]
    mids = [FAMILIES[family][1] + k for k, (a, b) in enumerate(MID_EDGES.get(kind, []))
            if a in corners and b in corners]
    return nodes[list(corners) + mids]


def surface_nodes(blocks, name: str, path) -> np.ndarray:
    """The node numbers of the ``*SURFACE, NAME=name`` (TYPE=NODE: node sets or numbers; TYPE=ELEMENT,
    the default: ``element or element set, S<k>`` lines, the nodes of those faces)."""
    found = [b for b in blocks if b.keyword == "SURFACE" and b.params.get("NAME") == name]
    if not found:
        raise InputError(f"{path}: no *SURFACE, NAME={name} in the deck; define the surface the coupling names")
    out = []
    nsets, table, esets = None, None, None
    for b in found:
        if b.params.get("TYPE", "ELEMENT") == "NODE":
            nsets = node_sets(blocks, path) if nsets is None else nsets
            for line in b.lines:
                item = line.split(",")[0].strip().upper()
                out.extend([int(item)] if item.isdigit() else nsets.get(item, np.zeros(0, np.int64)).tolist())
            continue
        table = elements(blocks) if table is None else table
        esets = element_sets(blocks, path) if esets is None else esets
        for line in b.lines:
            item, _, side = (x.strip().upper() for x in line.partition(","))
            ids = [int(item)] if item.isdigit() else esets.get(item, np.zeros(0, np.int64)).tolist()
            try:
                face = int(side.lstrip("S"))
                out.extend(n for e in ids for n in face_nodes(*table[e], face).tolist())
            except (KeyError, ValueError, IndexError):
                raise InputError(f"{path}: *SURFACE, NAME={name}: line '{line}' is not 'element or element set, "
                                 "S<face>' of solid elements of the deck; fix the surface") from None
    return np.unique(np.array(out, np.int64))
