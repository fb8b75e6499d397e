"""Small hexahedral CalculiX decks (steel bars in SI) run by ccx (tests/calculix_run.py), and the same
models as Nastran decks and DMIG punches, for the import tests."""

from pathlib import Path

import numpy as np
import scipy.sparse as sp
from calculix_run import run_ccx

#: steel of every deck (Pa, -, kg/m^3)
E, NU, RHO = 210e9, 0.3, 7850.0
#: C3D20 corner then mid-edge nodes as offsets on the doubled grid (Abaqus order)
C3D20 = [(0, 0, 0), (2, 0, 0), (2, 2, 0), (0, 2, 0), (0, 0, 2), (2, 0, 2), (2, 2, 2), (0, 2, 2),
         (1, 0, 0), (2, 1, 0), (1, 2, 0), (0, 1, 0), (1, 0, 2), (2, 1, 2), (1, 2, 2), (0, 1, 2),
         (0, 0, 1), (2, 0, 1), (2, 2, 1), (0, 2, 1)]
C3D8 = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]


#: six corner tetrahedra of a hexahedron around its diagonal 0-6 (conforming on a structured grid)
KUHN = [(0, 1, 2, 6), (0, 2, 3, 6), (0, 3, 7, 6), (0, 7, 4, 6), (0, 4, 5, 6), (0, 5, 1, 6)]


def hex_bar(lengths, divisions, *, x0=0.0, first_node=1, first_element=1, quadratic=False, elset="EALL",
            tets=False):
    """(deck lines of *NODE and *ELEMENT, {grid index: node number}, {node number: (3,) position}) of
    a bar [x0, x0 + Lx] x [0, Ly] x [0, Lz] of C3D8 (or C3D20) hexahedra, or of C3D4 tetrahedra
    (``tets``: six per hexahedron, positive volume)."""
    step = 2 if quadratic else 1
    n = [step * d + 1 for d in divisions]
    ids, xyz, lines = {}, {}, ["*NODE"]
    for k in range(n[2]):
        for j in range(n[1]):
            for i in range(n[0]):
                if quadratic and (i % 2) + (j % 2) + (k % 2) >= 2:     # face and body centres: not C3D20 nodes
                    continue
                ids[i, j, k] = first_node + len(ids)
                x = np.array([i, j, k]) / (np.array(n) - 1) * lengths + [x0, 0, 0]
                xyz[ids[i, j, k]] = x
                lines.append(f"{ids[i, j, k]}, {x[0]:.12e}, {x[1]:.12e}, {x[2]:.12e}")
    lines.append(f"*ELEMENT, TYPE={'C3D4' if tets else 'C3D20' if quadratic else 'C3D8'}, ELSET={elset}")
    e = first_element
    for k in range(divisions[2]):
        for j in range(divisions[1]):
            for i in range(divisions[0]):
                nodes = [ids[step * i + a, step * j + b, step * k + c] for a, b, c in (C3D20 if quadratic else C3D8)]
                if tets:
                    for t in KUHN:
                        x = np.array([xyz[nodes[v]] for v in t])
                        tet = [nodes[v] for v in t]
                        if np.linalg.det(x[1:] - x[0]) < 0:
                            tet[1], tet[2] = tet[2], tet[1]
                        lines.append(f"{e}, " + ", ".join(map(str, tet)))
                        e += 1
                    continue
                lines += [f"{e}, " + ", ".join(map(str, nodes[:15])) + ("," if len(nodes) > 15 else "")]
                if len(nodes) > 15:
                    lines.append(", ".join(map(str, nodes[15:])))
                e += 1
    return lines, ids, xyz


def node_set(name: str, nodes) -> list[str]:
    nodes = list(nodes)
    return [f"*NSET, NSET={name}"] + [", ".join(map(str, nodes[s:s + 10])) for s in range(0, len(nodes), 10)]


def end_sets(ids, nx: int) -> list[str]:
    """END_A (x = first grid plane) and END_B (last) node sets."""
    return (node_set("END_A", [v for (i, _, _), v in ids.items() if i == 0])
            + node_set("END_B", [v for (i, _, _), v in ids.items() if i == nx]))


def material(elsets=("EALL",), modulus=E, density=RHO) -> list[str]:
    out = ["*MATERIAL, NAME=STEEL", "*ELASTIC", f"{modulus:g}, {NU:g}", "*DENSITY", f"{density:g}"]
    return out + [f"*SOLID SECTION, ELSET={s}, MATERIAL=STEEL" for s in elsets]


#: the two steps: the matrices (MATRIXSTORAGE) and ccx's own eigenvalues (.eig)
MATRICES = ["*STEP", "*FREQUENCY, SOLVER=MATRIXSTORAGE", "12", "*END STEP"]
EIGEN = ["*STEP", "*FREQUENCY, STORAGE=YES", "12", "*NODE FILE", "U", "*END STEP"]


def write_pair(folder: Path, name: str, model: list[str]) -> tuple[Path, Path]:
    """``name``.inp (matrices) and ``name``_eig.inp (ccx's own modes) of the same model, both run."""
    decks = folder / f"{name}.inp", folder / f"{name}_eig.inp"
    for deck, step in zip(decks, (MATRICES, EIGEN)):
        deck.write_text("\n".join(model + step) + "\n")
        run_ccx(deck)
    return decks


def write_punch(path, fe, drop=(), renamed=None):
    """A free-field DMIG punch (KAAX, MAAX; lower triangle, 17 digits: the slender beam's bending is
    a 1e-10 part of K, beyond the 10 digits of a large field) of ccx's matrices, without the DOFs
    ``drop``; ``renamed``: (n, 2) node and DOF of each row instead of ccx's."""
    keep = ~np.isin(fe.dofs[:, 1], drop)
    dofs, lines = (fe.dofs if renamed is None else renamed)[keep], []
    for name, A in (("KAAX", fe.K), ("MAAX", fe.M)):
        C = sp.tril(A[keep][:, keep]).tocoo()
        lines.append(f"DMIG,{name},0,6,2,0,,,{C.shape[1]}")
        lines += [f"DMIG,{name},{dofs[j, 0]},{dofs[j, 1]},,{dofs[i, 0]},{dofs[i, 1]},{v:.17e}"
                  for i, j, v in zip(C.row, C.col, C.data)]
    path.write_text("\n".join(lines) + "\n")


def bdf(path, xyz: dict, lines, cards=()):
    """A Nastran bulk deck (small field) of the nodes ``xyz`` {number: (3,)} and the C3D8 elements of
    the deck ``lines`` (CHEXA, PID 1), with ``cards`` added; coordinates printed in 8 characters
    (the bars' grids are multiples of 0.01 m)."""
    out = ["BEGIN BULK"]
    out += [f"GRID    {n:<8d}        {x[0]:<8.6g}{x[1]:<8.6g}{x[2]:<8.6g}" for n, x in xyz.items()]
    for line in lines:
        row = line.split(",")
        if len(row) == 9 and not line.startswith("*") and all(v.strip().isdigit() for v in row):
            e, nodes = int(row[0]), [int(v) for v in row[1:]]
            out += ["CHEXA   " + "".join(f"{v:<8d}" for v in [e, 1, *nodes[:6]]) + "+",
                    "+       " + "".join(f"{v:<8d}" for v in nodes[6:])]
    Path(path).write_text("\n".join(out + list(cards) + ["ENDDATA"]) + "\n")
