"""Write block.inp: a free steel block 200 x 50 x 50 mm of 8 x 2 x 2 C3D20 hexahedra (CalculiX /
Abaqus node order), with node sets END_A (x = 0) and END_B (x = 0.2 m) for the interfaces, in SI.

    python make_deck.py            # writes block_mesh.inp (nodes, elements, sets)

block.inp (the deck run by ccx) includes it and asks for the matrices.
"""

from pathlib import Path

import numpy as np

#: size (m) and hexahedra per direction
LENGTHS = (0.2, 0.05, 0.05)
DIVISIONS = (8, 2, 2)
#: C3D20 corner then mid-edge nodes as offsets on the doubled grid (Abaqus order)
C3D20 = [(0, 0, 0), (2, 0, 0), (2, 2, 0), (0, 2, 0), (0, 0, 2), (2, 0, 2), (2, 2, 2), (0, 2, 2),
         (1, 0, 0), (2, 1, 0), (1, 2, 0), (0, 1, 0), (1, 0, 2), (2, 1, 2), (1, 2, 2), (0, 1, 2),
         (0, 0, 1), (2, 0, 1), (2, 2, 1), (0, 2, 1)]


def block_mesh(lengths=LENGTHS, divisions=DIVISIONS) -> str:
    """*NODE, *ELEMENT (C3D20) and the END_A / END_B node sets of the block, as deck text."""
    n = [2 * d + 1 for d in divisions]
    ids, lines = {}, []
    for k in range(n[2]):
        for j in range(n[1]):
            for i in range(n[0]):
                if (i % 2) + (j % 2) + (k % 2) >= 2:          # face and body centres: not C3D20 nodes
                    continue
                ids[i, j, k] = len(ids) + 1
                x = np.array([i, j, k]) / (np.array(n) - 1) * lengths
                lines.append(f"{ids[i, j, k]}, {x[0]:.10g}, {x[1]:.10g}, {x[2]:.10g}")
    out = ["*NODE, NSET=NALL", *lines, "*ELEMENT, TYPE=C3D20, ELSET=EALL"]
    e = 0
    for k in range(divisions[2]):
        for j in range(divisions[1]):
            for i in range(divisions[0]):
                e += 1
                nodes = [ids[2 * i + a, 2 * j + b, 2 * k + c] for a, b, c in C3D20]
                out += [f"{e}, " + ", ".join(map(str, nodes[:15])) + ",", ", ".join(map(str, nodes[15:]))]
    for name, i in (("END_A", 0), ("END_B", n[0] - 1)):
        members = [v for (a, _, _), v in ids.items() if a == i]
        out.append(f"*NSET, NSET={name}")
        out += [", ".join(map(str, members[s:s + 10])) for s in range(0, len(members), 10)]
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    Path(__file__).with_name("block_mesh.inp").write_text(block_mesh())
