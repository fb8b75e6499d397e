"""CalculiX: K and M of ``*FREQUENCY, SOLVER=MATRIXSTORAGE``, eigenvalues of ``*FREQUENCY, STORAGE=YES``.

``SOLVER=MATRIXSTORAGE`` (CalculiX 2.x, src/matrixstorage.c) writes three ASCII files and stops:
``jobname.sti`` and ``jobname.mas``, one nonzero of the upper triangle per line
``row column value`` (1-based equation numbers), and ``jobname.dof``, one line ``node.direction``
per equation (direction 1-3: x, y, z; 4-6 rotations of expanded beam/shell nodes).  DOFs fixed by
``*BOUNDARY`` or made dependent by ``*EQUATION``/MPCs have no equation and are absent.

``STORAGE=YES`` writes the binary ``jobname.eig`` (src/arpack.c): int32 cyclic-symmetry flag (0),
int32 Hermitian flag, int32 perturbation flag (then the reference displacements when it is 1),
int32 number of eigenvalues nev, nev float64 eigenvalues (rad/s)^2, the diagonal ``ad`` (neq) and
the strict lower triangle ``au`` (nzs) of K, the same of M, then nev eigenvectors (neq each).  The
positions of the ``au`` entries are not in the file: CalculiX rebuilds them from the deck
(src/mastruct.f), and so does :func:`read_eig` from ``jobname.inp`` beside the file: equations
numbered node by node in increasing node number, x y z, over the nodes of the elements; column j
holds the rows i > j of every DOF pair of nodes that share an element, in increasing order.  That
rebuild holds for decks without *BOUNDARY, *EQUATION, MPCs and couplings (they remove or add
equations): the entry count it gives must equal the file's, else InputError naming the
MATRIXSTORAGE route.

Shells, beams and plane elements (S3, S4, S6, S8, B31, B32, CPS, CPE, CAX, M3D) are expanded by
CalculiX into solid elements before the matrices are built (ccx 2.x User's Manual, "Shell
elements", "Beam elements"): the files then hold the expanded nodes under the original node
numbers (each node listed twice or three times in the ``.dof``, positions off the mid-surface that
the deck does not give) and the internal nodes of incompatible modes, numbered after the deck's.
They cannot be mapped onto the deck's nodes: such matrices are refused with one line naming the
Nastran (DMIG punch) and Abaqus (``*MATRIX GENERATE``) routes, which write 6 DOFs per node.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import scipy.sparse as sp

from sidprep.errors import InputError
from sidprep.fe.matrices.record import FEMatrices, symmetric_matrix, text_blocks
from sidprep.fe.matrices.deck import abaqus_types, deck_elements
from sidprep.fe.matrices.numbers import mirrored
from sidprep.fe.matrices.triangles import lower_dofs

#: the layout read here, as written by CalculiX 2.11-2.21 (matrixstorage.c, arpack.c)
FORMAT_VERSION = "calculix-matrixstorage 2.20"
EIG_FORMAT_VERSION = "calculix-eig 2.20"
#: byte sizes of CalculiX's ITG (32-bit build, the Debian package) and of a double
ITG_BYTES, DOUBLE_BYTES = 4, 8


def read(path) -> FEMatrices:
    """K (``.sti``), M (``.mas``) and the DOF map (``.dof``) of a MATRIXSTORAGE run (``path`` is any
    of the three files), or K, M, DOF map and eigenvalues of a STORAGE=YES ``.eig`` (:func:`read_eig`)."""
    path = Path(path)
    refuse_expanded(path, path.with_suffix(".inp"))
    if path.suffix.lower() == ".eig":
        return read_eig(path)
    stem = path.with_suffix("")
    files = {k: stem.with_suffix(k) for k in (".sti", ".mas", ".dof")}
    missing = [str(p) for p in files.values() if not p.is_file()]
    if missing:
        raise InputError(f"{path}: CalculiX matrix storage needs {', '.join(missing)} beside it; run ccx with "
                         "*FREQUENCY, SOLVER=MATRIXSTORAGE and keep the three files together")
    dofs = read_dof_file(files[".dof"])
    if len(np.unique(8 * dofs[:, 0] + dofs[:, 1])) != len(dofs):
        refuse_expanded(path)
    n = len(dofs)
    K = storage_matrix(files[".sti"], n, "stiffness matrix")
    M = storage_matrix(files[".mas"], n, "mass matrix")
    return FEMatrices(K, M, dofs, str(files[".sti"]), FORMAT_VERSION)


#: CalculiX element types expanded into solids (prefixes of the *ELEMENT TYPE)
EXPANDED_TYPES = ("S3", "S4", "S6", "S8", "B31", "B32", "CPS", "CPE", "CAX", "M3D")


def refuse_expanded(path, deck=None) -> None:
    """InputError when ``deck`` (a CalculiX deck; None: the matrices show it) has elements that
    CalculiX expands into solids (module docstring)."""
    found = sorted(t for t in abaqus_types(deck) if t.startswith(EXPANDED_TYPES)) if deck and deck.is_file() else []
    if deck is None or found:
        what = f"{', '.join(found)} elements" if found else "shell or beam elements (the .dof lists nodes twice)"
        raise InputError(f"{path}: CalculiX expands {what} into solids with nodes the deck does not hold, so its "
                         "matrices cannot be mapped onto the model; write them with Nastran (PARAM,EXTOUT,DMIGPCH "
                         "punch, --matrices .pch) or Abaqus (*MATRIX GENERATE, --matrices .mtx), 6 DOFs per node")


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
    blocks = list(text_blocks(path, "iir", f"CalculiX {what}"))
    if not blocks:
        raise InputError(f"{path}: empty {what}; run ccx again with *FREQUENCY, SOLVER=MATRIXSTORAGE")
    ints = np.concatenate([b[0] for b in blocks]) - 1
    vals = np.concatenate([b[1][:, 0] for b in blocks])
    del blocks
    rows, cols = ints[:, 0], ints[:, 1]
    top = int(ints.max()) + 1
    if ints.min() < 0 or top > n:
        raise InputError(f"{path}: equation number {top} beyond the {n} DOF of the .dof file; the "
                         ".sti/.mas/.dof files come from different runs: run ccx again")
    return symmetric_matrix(rows, cols, vals, n, path, what)


def read_eigenvalues(path) -> np.ndarray:
    """CalculiX's own eigenvalues (rad/s)^2 from a ``jobname.eig`` file (layout: module docstring)."""
    path = Path(path)
    with open(path, "rb") as f:
        data = f.read(4 * ITG_BYTES)
        nev = int(np.frombuffer(data[3 * ITG_BYTES:], dtype=np.int32)[0]) if len(data) == 4 * ITG_BYTES else 0
        data += f.read(max(nev, 0) * DOUBLE_BYTES)
    header = np.frombuffer(data[:3 * ITG_BYTES], dtype=np.int32) if len(data) >= 3 * ITG_BYTES else None
    if header is None or header[0] != 0 or header[1] not in (0, 1) or header[2] != 0:
        raise InputError(f"{path}: not the .eig file of a plain CalculiX *FREQUENCY, STORAGE=YES run "
                         "(cyclic symmetry and perturbed steps are not read); run ccx again")
    start = 4 * ITG_BYTES
    if nev < 1 or len(data) < start + nev * DOUBLE_BYTES:
        raise InputError(f"{path}: truncated .eig file ({len(data)} bytes, {nev} eigenvalues announced); "
                         "run ccx again")
    return np.frombuffer(data[start:start + nev * DOUBLE_BYTES], dtype=np.float64).copy()


#: keywords that remove or add equations: the .eig structure cannot be rebuilt from the elements alone
EQUATION_KEYWORDS = ("*BOUNDARY", "*EQUATION", "*MPC", "*RIGID BODY", "*COUPLING", "*TIE", "*SPRING", "*MASS",
                     "*DASHPOT", "*CYCLIC")


def read_eig(path) -> FEMatrices:
    """K, M, DOF map and eigenvalues of a STORAGE=YES ``jobname.eig``, the sparsity structure rebuilt
    from ``jobname.inp`` beside it (module docstring)."""
    path = Path(path)
    deck = path.with_suffix(".inp")
    if not deck.is_file():
        raise InputError(f"{path}: the .eig file needs its deck {deck} beside it (CalculiX rebuilds the matrix "
                         "structure from the elements, so does sidprep); copy the deck there")
    text = deck.read_text(errors="replace").upper()
    found = [k for k in EQUATION_KEYWORDS if f"\n{k}" in "\n" + text]
    if found:
        raise InputError(f"{path}: the deck {deck.name} has {', '.join(found)}, which change CalculiX's equations; "
                         "write the matrices with *FREQUENCY, SOLVER=MATRIXSTORAGE and give --matrices jobname.sti")
    elements = deck_elements(deck)
    nodes = np.unique(np.concatenate([e.ravel() for e in elements]))
    cols, rows = lower_structure(elements, nodes)
    neq, nzs = 3 * len(nodes), len(rows)
    eigenvalues = read_eigenvalues(path)
    nev = len(eigenvalues)
    start = 4 * ITG_BYTES + nev * DOUBLE_BYTES
    size = path.stat().st_size
    expected = start + DOUBLE_BYTES * (2 * (neq + nzs) + nev * neq)
    if size != expected:
        raise InputError(f"{path}: {size} bytes, but {nev} eigenvalues and the {neq} equations / {nzs} matrix "
                         f"entries of {deck.name} need {expected}; the file is truncated or from another deck: "
                         "run ccx again (or use *FREQUENCY, SOLVER=MATRIXSTORAGE)")
    raw = np.memmap(path, dtype=np.float64, mode="r", offset=start, shape=(2 * (neq + nzs),))
    starts = np.searchsorted(cols, np.arange(neq))       # the diagonal first in each column: sorted rows
    i, j = np.insert(rows, starts, np.arange(neq)), np.insert(cols, starts, np.arange(neq))
    matrices = [mirrored(i, j, np.insert(raw[k * (neq + nzs) + neq:(k + 1) * (neq + nzs)], starts,
                                          raw[k * (neq + nzs):k * (neq + nzs) + neq]), neq) for k in range(2)]
    del raw
    dofs = np.column_stack([np.repeat(nodes, 3), np.tile([1, 2, 3], len(nodes))])
    return FEMatrices(matrices[0], matrices[1], dofs, str(path), EIG_FORMAT_VERSION, eigenvalues)


def lower_structure(elements, nodes) -> tuple[np.ndarray, np.ndarray]:
    """(columns, rows) of CalculiX's strict lower triangle (src/mastruct.f): equations 3 r + c for the
    rank r of a node in ``nodes`` (sorted node numbers), every DOF pair of nodes sharing an element,
    column by column, rows increasing; ``elements``: list of (ne, k) node-number arrays."""
    a, b = [], []
    for e in elements:
        r = np.searchsorted(nodes, e)
        a.append(np.repeat(r, r.shape[1], axis=1).ravel())
        b.append(np.tile(r, (1, r.shape[1])).ravel())
    a, b = np.concatenate(a), np.concatenate(b)
    keep = a <= b
    graph = sp.csr_matrix((np.ones(int(keep.sum()), np.int8), (a[keep], b[keep])), shape=(len(nodes),) * 2)
    graph.sum_duplicates()                                # node b >= a of each node a, sorted
    return lower_dofs(graph.indptr.astype(np.int64), graph.indices.astype(np.int64))


def tet_deck(mesh, path, material, step: str = "*FREQUENCY, SOLVER=MATRIXSTORAGE\n10") -> None:
    """Write a CalculiX deck of a tetrahedral FEMesh (SI): its nodes with their numbers, C3D4/C3D10
    elements (Abaqus node order = sidprep's), its node sets, ``material`` (sidprep.fe.material) and
    one step (default: write the matrices).  Coordinates with 13 significant digits: ccx truncates
    fields longer than 20 characters."""
    lines = ["*NODE, NSET=NALL"]
    lines += [f"{i}, {x:.12e}, {y:.12e}, {z:.12e}" for i, (x, y, z) in zip(mesh.node_ids, mesh.points)]
    lines.append(f"*ELEMENT, TYPE={'C3D10' if mesh.order == 2 else 'C3D4'}, ELSET=EALL")
    lines += [f"{e}, " + ", ".join(map(str, row)) for e, row in enumerate(mesh.node_ids[mesh.cells], 1)]
    for name, nodes in mesh.node_sets.items():
        ids = mesh.node_ids[nodes]
        lines += [f"*NSET, NSET={name}"] + [", ".join(map(str, ids[s:s + 12])) for s in range(0, len(ids), 12)]
    lines += ["*MATERIAL, NAME=M", "*ELASTIC", f"{material.E:.12g}, {material.nu:.12g}", "*DENSITY",
              f"{material.rho:.12g}", "*SOLID SECTION, ELSET=EALL, MATERIAL=M", "*STEP", step, "*END STEP"]
    Path(path).write_text("\n".join(lines) + "\n")
