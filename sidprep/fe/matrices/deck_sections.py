"""The solid elements of an Abaqus / CalculiX deck with each element's material, for the stresses
of a model whose K and M were imported (``sidprep reduce MODEL.inp --matrices FILE --stress``).

Read from the deck (``*INCLUDE`` followed; keywords and names case-insensitive, as CalculiX reads them):

* ``*ELEMENT, TYPE=..., ELSET=...`` blocks (data lines continued over several lines);
* ``*ELSET, ELSET=...`` (element numbers, other set names, ``GENERATE`` ranges);
* ``*SOLID SECTION, ELSET=..., MATERIAL=...``;
* ``*MATERIAL, NAME=...`` with ``*ELASTIC`` (E, nu) and ``*DENSITY`` (their first data line; also
  used by the unit check, sidprep.fe.plausibility).

The stresses are those of sidprep.fe.element_stress.  Refused (InputError, one line): a deck that
is not an ``.inp``, element types without a recovery rule there (named), an element without a
solid section, a section naming an unknown material or set, a material without an isotropic,
temperature-independent ``*ELASTIC`` (one data line, TYPE=ISO or none).  Point masses, springs and dashpots carry no stress and are
skipped.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from sidprep.errors import InputError
from sidprep.fe.element_stress import SUPPORTED, DeckStress, ElementBlock
from sidprep.fe.material import NU_RANGE, Material, check_material
from sidprep.fe.readers.abaqus import abaqus_lines

#: nodes per element of the CalculiX solid element types (beyond SUPPORTED: refused by name)
ELEMENT_NODES = {"C3D4": 4, "C3D10": 10, "C3D8": 8, "C3D8R": 8, "C3D8I": 8, "C3D20": 20, "C3D20R": 20,
                 "C3D6": 6, "C3D15": 15, "C3D5": 5, "C3D13": 13, "C3D10T": 10, "C3D10I": 10}
#: element types that carry no stress (point masses, discrete springs and dashpots): skipped
NO_STRESS = ("MASS", "ROTARYI", "SPRING", "DASHPOT", "GAP")


@dataclass(frozen=True)
class DeckMaterial:
    """A material of the deck in its own units: E, nu, and rho (None when not given) from the first
    data line of its cards; ``isotropic`` False for an anisotropic *ELASTIC, ``tabulated`` True when
    a card holds several lines (a temperature table)."""

    E: float | None = None
    nu: float | None = None
    rho: float | None = None
    isotropic: bool = True
    tabulated: bool = False


@dataclass(frozen=True)
class DeckSections:
    """What the deck says about its elements: blocks [(type, element numbers (ne,), deck node
    numbers (ne, nn))], element sets {name: element numbers}, sections {element set: material},
    materials {name: DeckMaterial}; names upper case."""

    blocks: list
    elsets: dict
    sections: dict
    materials: dict


def keyword(line: str) -> tuple[str, dict]:
    """("SOLID SECTION", {"ELSET": "EALL", ...}) of a keyword line, upper case."""
    words = [w.strip().upper() for w in line[1:].split(",")]
    return words[0], {k.strip(): v.strip() for k, _, v in (w.partition("=") for w in words[1:] if w)}


def keyword_blocks(path):
    """(keyword, parameters, data lines) of every keyword of the deck, in order (module docstring)."""
    key, params, data = None, {}, []
    for line in abaqus_lines(path):
        if line.startswith("**") or not line.strip():
            continue
        if line.startswith("*"):
            if key is not None:
                yield key, params, data
            (key, params), data = keyword(line), []
        else:
            data.append(line)
    if key is not None:
        yield key, params, data


#: the keywords that define materials
MATERIAL_KEYS = ("MATERIAL", "ELASTIC", "DENSITY")


def deck_materials(path, cards=None) -> dict:
    """{material name: DeckMaterial} of the deck's *MATERIAL, *ELASTIC and *DENSITY cards (``cards``:
    those keyword blocks when already read, else the deck's)."""
    materials, name = {}, None
    for key, params, data in cards if cards is not None else keyword_blocks(path):
        if key == "MATERIAL":
            name = params.get("NAME")
            materials.setdefault(name, DeckMaterial())
        elif key in ("ELASTIC", "DENSITY") and name is not None:
            materials[name] = material_data(materials[name], key, params, data, name, path)
    return materials


def read_sections(path) -> DeckSections:
    """Parse the element, set and section keywords of the module docstring (InputError on malformed data)."""
    blocks, elsets, sections, cards = [], {}, {}, []
    for key, params, data in keyword_blocks(path):
        if key in MATERIAL_KEYS:
            cards.append((key, params, data))
        elif key == "ELEMENT" and data and not params.get("TYPE", "").startswith(NO_STRESS):
            kind = params.get("TYPE", "")
            if kind not in ELEMENT_NODES:                        # shells, beams, ...: refused by deck_stress
                blocks.append((kind or "(no TYPE)", np.zeros(0, np.int64), None))
                continue
            table = integer_table(data, ELEMENT_NODES[kind] + 1, path)
            blocks.append((kind, table[:, 0], table[:, 1:]))
            if "ELSET" in params:
                elsets[params["ELSET"]] = np.concatenate([elsets.get(params["ELSET"], []), table[:, 0]])
        elif key == "ELSET" and "ELSET" in params:
            members = element_set(data, elsets, "GENERATE" in params, path)
            elsets[params["ELSET"]] = np.concatenate([elsets.get(params["ELSET"], []), members])
        elif key == "SOLID SECTION":
            if "ELSET" not in params or "MATERIAL" not in params:
                raise InputError(f"{path}: a *SOLID SECTION without ELSET= or MATERIAL=; fix the deck")
            sections[params["ELSET"]] = params["MATERIAL"]
    return DeckSections(blocks, {k: np.asarray(v, np.int64) for k, v in elsets.items()}, sections,
                        deck_materials(path, cards))


def integer_table(lines: list[str], per: int, path) -> np.ndarray:
    """(n, per) integers of data lines continued over several lines."""
    tokens = [v for v in ",".join(lines).replace("\n", ",").split(",") if v.strip()]
    try:
        values = np.array(tokens, dtype=np.int64)
    except ValueError:
        raise InputError(f"{path}: an *ELEMENT block holds a non-integer entry; fix the deck") from None
    if values.size % per:
        raise InputError(f"{path}: an *ELEMENT block does not hold {per - 1} nodes per element; fix the deck")
    return values.reshape(-1, per)


def element_set(lines: list[str], known: dict, generate: bool, path) -> np.ndarray:
    """Element numbers of an *ELSET's data lines: numbers and set names, or start, end[, step]."""
    tokens = [v.strip().upper() for v in ",".join(lines).replace("\n", ",").split(",") if v.strip()]
    if generate:
        out = []
        for start in range(0, len(tokens), 3):
            a, b, *step = (int(t) for t in tokens[start:start + 3])
            out.append(np.arange(a, b + 1, step[0] if step else 1))
        return np.concatenate(out) if out else np.zeros(0, np.int64)
    out = []
    for t in tokens:
        if t.lstrip("-").isdigit():
            out.append([int(t)])
        elif t in known:
            out.append(known[t])
        else:
            raise InputError(f"{path}: *ELSET names the unknown set {t}; define it before use")
    return np.concatenate(out).astype(np.int64) if out else np.zeros(0, np.int64)


def material_data(m: DeckMaterial, key: str, params: dict, lines: list[str], name: str, path) -> DeckMaterial:
    """``m`` with the values of an *ELASTIC or *DENSITY card (its first data line)."""
    if not lines:
        raise InputError(f"{path}: material {name}: *{key} without a data line; fix the deck")
    try:
        values = [float(v.replace("D", "E").replace("d", "e")) for v in lines[0].split(",") if v.strip()]
    except ValueError:
        raise InputError(f"{path}: material {name}: *{key} data line {lines[0].strip()!r} is not numbers") from None
    tabulated = m.tabulated or len(lines) > 1
    if key == "DENSITY":
        return replace(m, rho=values[0], tabulated=tabulated)
    if len(values) < 2:
        raise InputError(f"{path}: material {name}: *ELASTIC needs E, nu")
    return replace(m, E=values[0], nu=values[1], tabulated=tabulated,
                   isotropic=params.get("TYPE", "ISO") in ("ISO", "ISOTROPIC"))


def deck_stress(mesh, units) -> DeckStress:
    """The stress recovery of MODEL ``mesh`` (an FEMesh in metres read from an ``.inp`` deck, whose
    ``node_ids`` are the deck's node numbers): each solid element with its section's material
    converted to SI with ``units`` (sidprep.fe.material.UnitSystem); InputError as in the module
    docstring."""
    path = Path(mesh.source)
    if path.suffix.lower() != ".inp":
        raise InputError(f"{path}: --stress with --matrices needs the Abaqus/CalculiX deck (.inp) as MODEL: its "
                         "elements and *SOLID SECTION materials give the stresses; give the deck or drop --stress")
    deck = read_sections(path)
    unsupported = sorted({kind for kind, _, _ in deck.blocks} - set(SUPPORTED))
    if unsupported:
        raise InputError(f"{path}: element type {', '.join(unsupported)}: no stress recovery for it; "
                         f"sidprep recovers stresses of {', '.join(SUPPORTED)} (drop --stress)")
    material_of = element_materials(deck, path)
    lame = {name: si_material(deck.materials[name], name, units, path).lame for name in set(material_of.values())}
    ids = np.asarray(mesh.node_ids[:mesh.n_nodes], np.int64)
    sorter = np.argsort(ids)
    blocks = []
    for kind, numbers, nodes in deck.blocks:
        pos = np.clip(np.searchsorted(ids, nodes, sorter=sorter), 0, len(ids) - 1)
        rows = sorter[pos]
        if (ids[rows] != nodes).any():
            raise InputError(f"{path}: element node {int(nodes[ids[rows] != nodes][0])} is not a node of the model; "
                             "fix the deck")
        blocks.append(ElementBlock(kind, rows, np.array([lame[material_of[int(e)]] for e in numbers]), numbers))
    return DeckStress(tuple(blocks), str(path))


def element_materials(deck: DeckSections, path) -> dict:
    """{element number: material name} from the solid sections; InputError for an element without one."""
    out = {}
    for elset, material in deck.sections.items():
        if elset not in deck.elsets:
            raise InputError(f"{path}: *SOLID SECTION names the unknown element set {elset}; fix the deck")
        if material not in deck.materials:
            raise InputError(f"{path}: *SOLID SECTION names the unknown material {material}; fix the deck")
        out.update(dict.fromkeys(deck.elsets[elset].tolist(), material))
    for kind, numbers, _ in deck.blocks:
        missing = [int(e) for e in numbers if int(e) not in out]
        if missing:
            raise InputError(f"{path}: {len(missing)} {kind} element(s) have no *SOLID SECTION (first: element "
                             f"{missing[0]}); give every solid element a section with its material")
    return out


def si_material(m: DeckMaterial, name: str, units, path) -> Material:
    """A deck material in SI (``units``: the deck's unit system), checked (sidprep.fe.material)."""
    if m.E is None:
        raise InputError(f"{path}: material {name} has no *ELASTIC; its stresses need E and nu")
    if not m.isotropic:
        raise InputError(f"{path}: material {name}: *ELASTIC is not isotropic; sidprep's stresses use isotropic "
                         "Hooke: give TYPE=ISO or drop --stress")
    if m.tabulated:
        raise InputError(f"{path}: material {name}: *ELASTIC or *DENSITY is a table of several lines "
                         "(temperatures); sidprep's stresses read one temperature-independent line")
    if not NU_RANGE[0] < m.nu < NU_RANGE[1]:
        raise InputError(f"{path}: material {name}: nu = {m.nu:g} outside ({NU_RANGE[0]:g}, {NU_RANGE[1]:g})")
    if m.rho is None:                          # no density to check the wave speed with: E and nu only
        if not m.E > 0:
            raise InputError(f"{path}: material {name}: E = {m.E:g} must be > 0")
        return Material(m.E * units.stress_to_pa, m.nu, float("nan"), name)
    try:
        return check_material(Material(m.E * units.stress_to_pa, m.nu, m.rho * units.density_to_kg_m3, name))
    except InputError as exc:
        raise InputError(f"{path}: {exc}") from None
