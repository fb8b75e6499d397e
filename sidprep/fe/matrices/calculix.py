"""CalculiX: K and M of ``*FREQUENCY, SOLVER=MATRIXSTORAGE``, eigenvalues of ``*FREQUENCY, STORAGE=YES``.

``SOLVER=MATRIXSTORAGE`` (CalculiX 2.x, src/matrixstorage.c) writes three ASCII files and stops:
``jobname.sti`` and ``jobname.mas``, one nonzero of the upper triangle per line
``row column value`` (1-based equation numbers), and ``jobname.dof``, one line ``node.direction``
per equation (direction 1-3: x, y, z; 4-6 rotations of expanded beam/shell nodes).  DOFs fixed by
``*BOUNDARY`` or made dependent by ``*EQUATION``/MPCs have no equation and are absent.

``STORAGE=YES`` writes the binary ``jobname.eig`` (src/arpack.c): int32 cyclic flag (0), int32
Hermitian flag, int32 perturbation flag (then the reference displacements when it is 1), int32
number of eigenvalues nev, nev float64 eigenvalues (rad/s)^2, then the diagonal and the strict
lower triangle of K and of M in CalculiX's compressed-column order and the eigenvectors.  The
positions of those matrix entries (the sparsity structure) are not in the file - CalculiX rebuilds
them from the deck - so sidprep takes K and M from the MATRIXSTORAGE files and the eigenvalues
(CalculiX's own frequencies, for comparison) from ``.eig``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sidprep.errors import InputError
from sidprep.fe.matrices import FEMatrices, symmetric_matrix, text_blocks

#: the layout read here, as written by CalculiX 2.11-2.21 (matrixstorage.c, arpack.c)
FORMAT_VERSION = "calculix-matrixstorage 2.20"
EIG_FORMAT_VERSION = "calculix-eig 2.20"
#: byte sizes of CalculiX's ITG (32-bit build, the Debian package) and of a double
ITG_BYTES, DOUBLE_BYTES = 4, 8


def read(path) -> FEMatrices:
    """K (``.sti``), M (``.mas``) and the DOF map (``.dof``) of a MATRIXSTORAGE run; ``path`` is
    any of the three files (or the ``.eig`` of a STORAGE=YES run: InputError naming the fix)."""
    path = Path(path)
    if path.suffix.lower() == ".eig":
        raise InputError(f"{path}: a CalculiX .eig file holds the values of K and M but not their sparsity "
                         "structure (CalculiX rebuilds it from the deck); write the matrices with "
                         "*FREQUENCY, SOLVER=MATRIXSTORAGE and give --matrices jobname.sti")
    stem = path.with_suffix("")
    files = {k: stem.with_suffix(k) for k in (".sti", ".mas", ".dof")}
    missing = [str(p) for p in files.values() if not p.is_file()]
    if missing:
        raise InputError(f"{path}: CalculiX matrix storage needs {', '.join(missing)} beside it; run ccx with "
                         "*FREQUENCY, SOLVER=MATRIXSTORAGE and keep the three files together")
    dofs = read_dof_file(files[".dof"])
    n = len(dofs)
    K = storage_matrix(files[".sti"], n, "stiffness matrix")
    M = storage_matrix(files[".mas"], n, "mass matrix")
    return FEMatrices(K, M, dofs, str(files[".sti"]), FORMAT_VERSION)


def read_dof_file(path) -> np.ndarray:
    """(n, 2) int64 node number and direction of each equation of a ``jobname.dof`` file."""
    text = Path(path).read_text(errors="replace").split()
    node, dot, direction = np.char.partition(np.array(text, dtype=str), ".").T if text else ([],) * 3
    if not len(text) or not (np.all(dot == ".") and np.all(np.char.isdigit(node))
                             and np.all(np.isin(direction, ["1", "2", "3", "4", "5", "6"]))):
        raise InputError(f"{path}: not a CalculiX .dof file (one 'node.direction' per line, direction 1-6); "
                         "write it again with *FREQUENCY, SOLVER=MATRIXSTORAGE")
    return np.column_stack([node.astype(np.int64), direction.astype(np.int64)])


def storage_matrix(path, n: int, what: str):
    """The symmetric (n, n) CSR matrix of a ``.sti`` / ``.mas`` file (upper triangle, 1-based)."""
    rows, cols, vals = [], [], []
    for block in text_blocks(path, 3, f"CalculiX {what}"):
        rows.append(block[:, 0].astype(np.int64) - 1)
        cols.append(block[:, 1].astype(np.int64) - 1)
        vals.append(block[:, 2])
    if not rows:
        raise InputError(f"{path}: empty {what}; run ccx again with *FREQUENCY, SOLVER=MATRIXSTORAGE")
    rows, cols, vals = np.concatenate(rows), np.concatenate(cols), np.concatenate(vals)
    top = int(max(rows.max(), cols.max())) + 1
    if rows.min() < 0 or cols.min() < 0 or top > n:
        raise InputError(f"{path}: equation number {top} beyond the {n} DOF of the .dof file; the "
                         ".sti/.mas/.dof files come from different runs: run ccx again")
    return symmetric_matrix(rows, cols, vals, n, path, what)


def read_eigenvalues(path) -> np.ndarray:
    """CalculiX's own eigenvalues (rad/s)^2 from a ``jobname.eig`` file (layout: module docstring)."""
    path = Path(path)
    data = path.read_bytes()
    header = np.frombuffer(data[:3 * ITG_BYTES], dtype=np.int32) if len(data) >= 3 * ITG_BYTES else None
    if header is None or header[0] != 0 or header[1] not in (0, 1) or header[2] != 0:
        raise InputError(f"{path}: not the .eig file of a plain CalculiX *FREQUENCY, STORAGE=YES run "
                         "(cyclic symmetry and perturbed steps are not read); run ccx again")
    nev = int(np.frombuffer(data[3 * ITG_BYTES:4 * ITG_BYTES], dtype=np.int32)[0])
    start = 4 * ITG_BYTES
    if nev < 1 or len(data) < start + nev * DOUBLE_BYTES:
        raise InputError(f"{path}: truncated .eig file ({len(data)} bytes, {nev} eigenvalues announced); "
                         "run ccx again")
    return np.frombuffer(data[start:start + nev * DOUBLE_BYTES], dtype=np.float64).copy()
