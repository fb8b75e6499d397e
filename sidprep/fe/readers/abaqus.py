"""Abaqus / CalculiX deck text that meshio does not resolve: ``*INCLUDE`` files put inline, and the
node numbers of ``*NODE`` and the element numbers of the tetrahedra (C3D4*, C3D10*) in file order.
Used by the meshio reader (``sidprep.fe.readers.meshio``) and the deck reader of imported
matrices (``sidprep.fe.matrices.deck``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sidprep.errors import InputError


def abaqus_lines(path) -> list[str]:
    """The lines of an Abaqus / CalculiX input file with every ``*INCLUDE`` replaced by its file."""
    lines = []
    with open(path, errors="replace") as f:
        for line in f:
            if line[:8].upper() == "*INCLUDE":
                included = Path(path).parent / line.split("=", 1)[1].strip().strip('"')
                if not included.is_file():
                    raise InputError(
                        f"{path}: *INCLUDE file {included} not found; "
                        "fix INPUT= (a path relative to the including file)"
                    )
                lines.extend(abaqus_lines(included))
            else:
                lines.append(line if line.endswith("\n") else line + "\n")
    return lines


def abaqus_ids(lines) -> tuple[np.ndarray, np.ndarray]:
    """Node numbers of the ``*NODE`` lines and element numbers of the C3D4* / C3D10* elements,
    in file order (the order meshio reads them in)."""
    node_ids, tet_ids = [], []
    block, tokens, per_element = None, [], 0

    def close():
        if block == "ELEMENT" and per_element:
            ids = np.array([int(t) for t in tokens if t.strip()], dtype=np.int64)
            tet_ids.append(ids.reshape(-1, per_element + 1)[:, 0])

    for line in lines:
        if line.startswith("**"):
            continue
        if line.startswith("*"):
            close()
            words = [w.strip().upper() for w in line[1:].split(",")]
            params = dict(w.split("=", 1) for w in words[1:] if "=" in w)
            block, tokens = words[0], []
            kind = params.get("TYPE", "")
            per_element = 10 if kind.startswith("C3D10") else 4 if kind.startswith("C3D4") else 0
        elif block == "NODE" and line.strip():
            node_ids.append(int(line.split(",", 1)[0]))
        elif block == "ELEMENT" and per_element:
            tokens.extend(line.split(","))
    close()
    tets = np.concatenate(tet_ids) if tet_ids else np.zeros(0, np.int64)
    return np.array(node_ids, dtype=np.int64), tets
