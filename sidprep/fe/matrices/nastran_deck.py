"""MODEL of a Nastran bulk deck (``.bdf``, ``.nas``, ``.dat``): grids and the element connectivity.

Read card by card with the punch reader's field splitter (sidprep.fe.matrices.nastran.cards: small,
large and free field, continuations, INCLUDE files), so that decks meshio cannot read (Femap ``.dat`` files with
free-field continuations, element cards it does not know) are read as Nastran reads them.  Only the
geometry is taken: ``GRID`` (position in the basic system) and the grids of each element card
(MSC/NX Nastran Quick Reference Guide, bulk data entries), grouped by meshio cell type:

=====================================  ============================================
cards                                  cell type (corner nodes first, VTK order)
=====================================  ============================================
CTETRA, CHEXA, CPENTA, CPYRA           tetra, hexahedron, wedge, pyramid (+ mid-side)
CTRIA3, CTRIAR, CTRIA6                 triangle, triangle6 (shells)
CQUAD4, CQUADR, CSHEAR, CQUAD8         quad, quad8 (shells)
CBAR, CBEAM, CROD, CTUBE, CBUSH,       line (beams, rods, bushes between two grids)
CONROD
CONM2, CONM1                           vertex (point masses)
=====================================  ============================================

Refused with one line: grids in a local input (CP) or displacement (CD) system (the matrices' DOFs
would be in that system), plane-strain / axisymmetric elements (no 3D motion), and an element on
a grid the deck does not define.
"""

from __future__ import annotations

from pathlib import Path

import meshio
import numpy as np

from sidprep.errors import InputError
from sidprep.fe.matrices.nastran import cards, nastran_real

#: element card -> (meshio cell type, first grid field, largest grid count); solids: by grid count
ELEMENT_CARDS = {
    "CTRIA3": ("triangle", 3, 3), "CTRIAR": ("triangle", 3, 3), "CTRIA6": ("triangle6", 3, 6),
    "CQUAD4": ("quad", 3, 4), "CQUADR": ("quad", 3, 4), "CSHEAR": ("quad", 3, 4), "CQUAD8": ("quad8", 3, 8),
    "CBAR": ("line", 3, 2), "CBEAM": ("line", 3, 2), "CROD": ("line", 3, 2), "CTUBE": ("line", 3, 2),
    "CBUSH": ("line", 3, 2), "CONROD": ("line", 2, 2),
    "CONM2": ("vertex", 2, 1), "CONM1": ("vertex", 2, 1),
    "CTETRA": ("tetra", 3, 10), "CHEXA": ("hexahedron", 3, 20), "CPENTA": ("wedge", 3, 15),
    "CPYRA": ("pyramid", 3, 13),
}
#: solid cell type by (card, grid count)
SOLID_TYPES = {("CTETRA", 4): "tetra", ("CTETRA", 10): "tetra10", ("CHEXA", 8): "hexahedron",
               ("CHEXA", 20): "hexahedron20", ("CPENTA", 6): "wedge", ("CPENTA", 15): "wedge15",
               ("CPYRA", 5): "pyramid", ("CPYRA", 13): "pyramid13"}
SOLID_CARDS = ("CTETRA", "CHEXA", "CPENTA", "CPYRA")
#: grids of the cell types whose card may leave some blank
CELL_NODES = {"triangle6": 6, "quad8": 8, "line": 2}
#: elements of a 2D (plane or axisymmetric) model: no 3D motion for a SID
PLANAR_CARDS = ("CTRIAX", "CTRIAX6", "CQUADX", "CQUADX4", "CQUADX8", "CTRAX3", "CTRAX6", "CPLSTN3", "CPLSTN4",
                "CPLSTN6", "CPLSTN8", "CPLSTS3", "CPLSTS4", "CPLSTS6", "CPLSTS8")


def is_nastran(path) -> bool:
    """The ending of a Nastran bulk deck."""
    return Path(path).suffix.lower() in (".bdf", ".nas", ".dat")


def nastran_mesh(path) -> tuple[meshio.Mesh, np.ndarray]:
    """(meshio Mesh of the deck's grids and elements, (n,) grid numbers of its points) of the Nastran
    deck ``path`` (module docstring)."""
    path = Path(path)
    grids, elements = {}, {}
    for card in cards(path, bulk_only=True):
        name = card[0].rstrip("*").upper()
        name = name.rstrip("_") if name.rstrip("_") in SOLID_CARDS else name     # meshio writes CHEXA_ for 20 grids
        try:
            if name == "GRID":
                grids[int(card[1])] = grid_position(card, path)
            elif name in PLANAR_CARDS:
                raise InputError(f"{path}: {name} elements are plane or axisymmetric; a SID needs the 3D motion of "
                                 "every node (its invariants are 3D): export the 3D model (solids, shells, beams)")
            elif name in ELEMENT_CARDS:
                kind, first, most = ELEMENT_CARDS[name]
                nodes = [int(g) for g in card[first:first + most] if g.strip()]
                kind = SOLID_TYPES.get((name, len(nodes)), "") if name in SOLID_CARDS else kind
                if kind == "line" and len(nodes) == 1:
                    continue                                   # a bush to ground: the rigid-body check decides
                if not kind or len(nodes) != CELL_NODES.get(kind, len(nodes)):
                    raise InputError(f"{path}: {name} {card[1]} has {len(nodes)} grids (blank mid-side grids are not "
                                     "read); give every grid of the element")
                elements.setdefault(kind, []).append(nodes)
        except (ValueError, IndexError):
            raise InputError(f"{path}: a {name} card has a field that is not a number; fix the deck") from None
    if not grids:
        raise InputError(f"{path}: no GRID cards after BEGIN BULK; give the Nastran bulk deck of the model")
    ids = np.array(sorted(grids), np.int64)
    cells = []
    for kind, rows in elements.items():
        table = np.array(rows, np.int64)
        row = np.searchsorted(ids, table)
        missing = (row >= len(ids)) | (ids[np.minimum(row, len(ids) - 1)] != table)
        if missing.any():
            raise InputError(f"{path}: an element uses grid {int(table[missing][0])}, which has no GRID card; "
                             "define it or remove the element")
        cells.append((kind, row))
    points = np.array([grids[g] for g in ids], float)
    return meshio.Mesh(points, cells), ids


def nastran_materials(path) -> tuple[list[float], list[float]]:
    """(Young's moduli, densities) of the deck's MAT1 cards (MID, E, G, NU, RHO, ...), blanks left
    out, in the deck's units: what the unit check compares (sidprep.fe.plausibility)."""
    moduli, densities = [], []
    for card in cards(path, bulk_only=True):
        if card[0].rstrip("*").upper() != "MAT1":
            continue
        try:
            moduli += [nastran_real(card[2])] if len(card) > 2 and card[2].strip() else []
            densities += [nastran_real(card[5])] if len(card) > 5 and card[5].strip() else []
        except ValueError:
            raise InputError(f"{path}: MAT1 {card[1]} has a field that is not a number; fix the deck") from None
    return moduli, densities


def grid_position(card, path) -> np.ndarray:
    """(3,) position of a GRID card in the basic system; InputError for a local input (CP) or
    displacement (CD) coordinate system."""
    for k, what in ((2, "input (CP)"), (6, "displacement (CD)")):
        if len(card) > k and card[k].strip("0 "):
            raise InputError(f"{path}: GRID {card[1]} is in the local {what} coordinate system {card[k]}; sidprep "
                             "reads grids and matrix DOFs in the basic system: export with CP = CD = 0")
    return np.array([nastran_real(v) if v.strip() else 0.0 for v in (list(card[3:6]) + ["", "", ""])[:3]])
