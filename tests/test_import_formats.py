"""Matrix files of Abaqus (.mtx) and Nastran (DMIG punch), and the checks on bad matrix input.

Format references: the Abaqus Keywords Reference (*MATRIX OUTPUT, FORMAT=MATRIX INPUT: "node, DOF,
node, DOF, value" per line, one triangle) and the Nastran Quick Reference Guide (DMIG, small and
large field).  The hand-written samples below follow those pages; the bar's K and M written in each
format must reduce to the SID of sidprep's own assembly of the same mesh (the same numbers)."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

from sidprep.errors import InputError
from sidprep.fe.assemble import mass_matrix, stiffness_matrix
from sidprep.fe.material import builtin_material, unit_system
from sidprep.fe.matrices import read_matrices
from sidprep.fe.matrices.onto_model import imported_model
from sidprep.fe.mesh import read_mesh
from sidprep.jobs.options import ReduceOptions
from sidprep.jobs.reduce import reduce

ROOT = Path(__file__).resolve().parents[1]
BAR = ROOT / "data" / "meshes" / "bar.msh"
#: the same K and M through a file of 17 significant digits: round-off only
SAME_NUMBERS_RTOL = 1e-9
#: through a large-field DMIG punch: 10 significant digits per entry (16-character field); K's rows sum to
#: ~0 (rigid modes), so the frequencies keep ~7 digits (measured 3e-7)
DMIG_DIGITS_RTOL = 2e-6


@pytest.fixture(scope="module")
def bar():
    mesh = read_mesh(BAR)
    steel = builtin_material("steel")
    return mesh, stiffness_matrix(mesh, steel).tocoo(), mass_matrix(mesh, steel).tocoo()


def node_dof(mesh, i):
    return mesh.node_ids[i // 3], i % 3 + 1


def write_mtx(path: Path, mesh, A, triangle="upper", fmt="{:.17g}"):
    """An Abaqus matrix-input file of A (coo, DOF 3 i + c) with the mesh's node numbers."""
    keep = A.row <= A.col if triangle == "upper" else np.ones(A.nnz, bool)
    n_r, c_r = node_dof(mesh, A.row[keep])
    n_c, c_c = node_dof(mesh, A.col[keep])
    lines = ["** ASSEMBLED MATRIX (written by the test, Abaqus FORMAT=MATRIX INPUT)"]
    lines += [f"{a},{b}, {c},{d}, " + fmt.format(v) for a, b, c, d, v in zip(n_r, c_r, n_c, c_c, A.data[keep])]
    path.write_text("\n".join(lines) + "\n")


def write_dmig(path: Path, mesh, matrices: dict):
    """A large-field DMIG punch (lower triangle, D exponents) of {name: coo matrix}."""
    lines = ["$ DMIG punch written by the test (PARAM,EXTOUT,DMIGPCH layout)"]
    for name, A in matrices.items():
        lines.append(f"DMIG*   {name:<16s}{0:>16d}{6:>16d}{2:>16d}")
        lines.append(f"*       {0:>16d}{'':16s}{'':16s}{A.shape[1]:>16d}")
        C = sp.tril(A).tocsc()
        for j in range(C.shape[1]):
            gj, cj = node_dof(mesh, j)
            lines.append(f"DMIG*   {name:<16s}{gj:>16d}{cj:>16d}")
            for i, v in zip(C.indices[C.indptr[j]:C.indptr[j + 1]], C.data[C.indptr[j]:C.indptr[j + 1]]):
                gi, ci = node_dof(mesh, i)
                lines.append(f"*       {gi:>16d}{ci:>16d}{f'{v:.9E}'.replace('E', 'D'):>16s}")
    path.write_text("\n".join(lines) + "\n")


def test_hand_written_samples_of_both_formats(tmp_path):
    """Two nodes, a spring k = 1e3 N/m in x between them and 0.5 kg per node (QRG / Keywords pages)."""
    (tmp_path / "j_STIF1.mtx").write_text("** stiffness\n1,1, 1,1, 1.0e3\n1,1, 2,1, -1.0e3\n2,1, 2,1, 1.0e3\n")
    (tmp_path / "j_MASS1.mtx").write_text("1,1, 1,1, 0.5\n2,1, 2,1, 0.5\n")
    (tmp_path / "s.pch").write_text(
        "DMIG    KAAX    0       6       2       0                       2\n"
        "DMIG    KAAX    1       1               1       1       1.+3\n"
        "DMIG    KAAX    2       1               1       1       -1.+3           +\n"
        "+       2       1       1.0D+3\n"
        "DMIG,MAAX,0,6,2,0,,,2\n"
        "DMIG,MAAX,1,1,,1,1,0.5\n"
        "DMIG,MAAX,2,1,,2,1,0.5\n")
    for name in ("j_STIF1.mtx", "s.pch"):
        fe = read_matrices(tmp_path / name)
        np.testing.assert_array_equal(fe.dofs, [[1, 1], [2, 1]])
        np.testing.assert_array_equal(fe.K.toarray(), [[1e3, -1e3], [-1e3, 1e3]])
        np.testing.assert_array_equal(fe.M.toarray(), [[0.5, 0], [0, 0.5]])


@pytest.mark.parametrize("fmt", ["mtx", "pch"])
def test_bar_matrices_in_each_format_reduce_like_sidprep_assembly(bar, tmp_path, fmt):
    mesh, K, M = bar
    if fmt == "mtx":
        write_mtx(tmp_path / "bar_STIF1.mtx", mesh, K)
        write_mtx(tmp_path / "bar_MASS1.mtx", mesh, M, triangle="full")
        path = tmp_path / "bar_STIF1.mtx"
    else:
        path = tmp_path / "bar.pch"
        write_dmig(path, mesh, {"KAAX": K, "MAAX": M})
    options = ReduceOptions(modes=4, check_frequencies=False)
    own = reduce(BAR, options)
    imported = reduce(BAR, ReduceOptions(modes=4, check_frequencies=False, matrices=str(path)))
    assert imported.sid.mass == pytest.approx(own.sid.mass, rel=SAME_NUMBERS_RTOL)
    np.testing.assert_allclose(imported.sid.frequencies_hz, own.sid.frequencies_hz,
                               rtol=SAME_NUMBERS_RTOL if fmt == "mtx" else DMIG_DIGITS_RTOL)
    assert imported.checks["rigid_energy_ratio"] < (1e-13 if fmt == "mtx" else 1e-11)     # digits of the file


# ---------------------------------------------------------------------------------------------
# bad input: one line naming the file, the problem and the fix; exit 2 from the command line
# ---------------------------------------------------------------------------------------------

def bad_pair(tmp_path, mesh, K, M, **write):
    write_mtx(tmp_path / "b_STIF1.mtx", mesh, K, **write)
    write_mtx(tmp_path / "b_MASS1.mtx", mesh, M)
    return tmp_path / "b_STIF1.mtx"


def edited(A, i, j, value):
    B = A.tolil()
    B[i, j] = value
    return B.tocoo()


def test_bad_matrices_are_named_before_the_reduction(bar, tmp_path):
    mesh, K, M = bar
    si = unit_system("si")
    cases = {
        "not symmetric": (edited(K, 0, 1, K.tocsr()[0, 1] * 1.5), M, {"triangle": "full"}),
        "non-positive diagonal": (edited(K, 4, 4, -1.0), M, {}),
        "indefinite": (edited(edited(K, 0, 3, 1e3 * abs(K.data).max()), 3, 0, 1e3 * abs(K.data).max()), M, {}),
        "negative diagonal": (K, edited(M, 2, 2, -1e-3), {}),
        "rigid-body motions": (edited(K, 5, 5, K.tocsr()[5, 5] * 1.01), M, {}),
    }
    for problem, (k, m, write) in cases.items():
        path = bad_pair(tmp_path, mesh, k, m, **write)
        with pytest.raises(InputError, match=problem) as info:
            imported_model(mesh, path, si)
        assert str(path.parent / "b_") in str(info.value) and "\n" not in str(info.value), problem
    kept = [sp.coo_matrix((A.data[k], (A.row[k], A.col[k])), shape=A.shape)      # node 1's DOFs removed (SPC)
            for A in (K, M) for k in [(A.row >= 3) & (A.col >= 3)]]
    bad_pair(tmp_path, mesh, *kept)
    with pytest.raises(InputError, match="have no row .*SPC"):
        imported_model(mesh, tmp_path / "b_STIF1.mtx", si)


def test_other_models_truncated_files_and_wrong_endings(bar, tmp_path):
    mesh, K, M = bar
    path = bad_pair(tmp_path, mesh, K, M)
    rod = read_mesh(ROOT / "data" / "meshes" / "piston_rod.msh")
    with pytest.raises(InputError, match="have no row|not in MODEL"):
        imported_model(rod, path, unit_system("si"))
    text = path.read_text()
    path.write_text(text[:len(text) // 2 - 7])                 # cut inside a line
    with pytest.raises(InputError, match="truncated"):
        read_matrices(path)
    with pytest.raises(InputError, match="matrices = .*none.sti: file not found"):
        read_matrices(tmp_path / "none.sti")
    (tmp_path / "b.txt").write_text("1 1 1.0\n")
    with pytest.raises(InputError, match="unknown matrix file ending '.txt'"):
        read_matrices(tmp_path / "b.txt")
    (tmp_path / "b.pch").write_text(text[:2000])               # an Abaqus file given the Nastran ending
    with pytest.raises(InputError, match="not a Nastran punch file"):
        read_matrices(tmp_path / "b.pch")


def test_stiffening_needs_sidprep_elements(bar, tmp_path):
    mesh, K, M = bar
    with pytest.raises(InputError, match="stiffening = true: the geometric stiffening needs sidprep's own elements"):
        reduce(BAR, ReduceOptions(stiffening=True, matrices=str(bad_pair(tmp_path, mesh, K, M))))


def test_command_line_exits_2_with_one_line(bar, tmp_path):
    mesh, K, M = bar
    path = bad_pair(tmp_path, mesh, K, edited(M, 2, 2, -1e-3))
    done = subprocess.run([sys.executable, "-m", "sidprep.cli.main", "reduce", str(BAR), "--matrices", str(path),
                           "-o", str(tmp_path / "x.sid.h5"), "-q"], capture_output=True, text=True, timeout=300)
    assert done.returncode == 2, done.stderr
    assert done.stderr.count("\n") == 1 and str(path) in done.stderr and "negative diagonal" in done.stderr
    assert not (tmp_path / "x.sid.h5").exists()


#: pymapdl-reader's documentation (examples, "Read a full file"): the first four frequencies of the
#: cantilever hex beam of the Ansys-written examples/file.full shipped with ansys-mapdl-reader, Hz
ANSYS_EXAMPLE_HZ = (1283.200, 1283.200, 5781.975, 6919.399)
#: the documentation prints them to 0.001 Hz
ANSYS_PRINTED_RTOL = 1e-6


def test_ansys_full_file_gives_the_documented_frequencies():
    examples = pytest.importorskip("ansys.mapdl.reader.examples",
                                   reason='ansys-mapdl-reader not installed (pip install "sidprep[ansys]")')
    import scipy.linalg as sla

    from sidprep.fe.matrices.ansys import full_matrices

    fe, constrained = full_matrices(examples.fullfile)
    keep = ~constrained
    lam = sla.eigh(fe.K[keep][:, keep].toarray(), fe.M[keep][:, keep].toarray(), eigvals_only=True)[:4]
    np.testing.assert_allclose(np.sqrt(lam) / (2 * np.pi), ANSYS_EXAMPLE_HZ, rtol=ANSYS_PRINTED_RTOL)
    with pytest.raises(InputError, match="63 DOFs are constrained by D commands"):
        read_matrices(examples.fullfile)


# ---------------------------------------------------------------------------------------------
# 6-DOF nodes: a beam stiffener (Euler-Bernoulli frame elements, rotations at its nodes) on the bar
# ---------------------------------------------------------------------------------------------
#: the stiffener: steel, area, second moments (y, z) and torsion constant (m^2, m^4); no torsion
#: stiffness (J = 0): the solid's nodes hold no rotation, so a twisting stiffener would be a mechanism;
#: its rx DOFs are written without stiffness (like a shell's drilling DOF)
STIFFENER = {"E": 210e9, "G": 210e9 / 2.6, "rho": 7850.0, "A": 4e-4, "I": 2e-8, "J": 0.0}
#: two reductions of the same physics (rotation nodes kept vs the massless rotations condensed out
#: exactly before): the same Craig-Bampton space, round-off of the 17-digit files only
ROTATION_RTOL = 1e-7


def frame_element(L: float) -> np.ndarray:
    """12 x 12 stiffness of an Euler-Bernoulli frame element along x: [u v w rx ry rz] at both ends."""
    s = STIFFENER
    K = np.zeros((12, 12))
    for i, j, k in ((0, 6, s["E"] * s["A"] / L), (3, 9, s["G"] * s["J"] / L)):
        K[np.ix_([i, j], [i, j])] += k * np.array([[1, -1], [-1, 1]])
    EI = s["E"] * s["I"]
    bend = EI / L ** 3 * np.array([[12, 6 * L, -12, 6 * L], [6 * L, 4 * L * L, -6 * L, 2 * L * L],
                                   [-12, -6 * L, 12, -6 * L], [6 * L, 2 * L * L, -6 * L, 4 * L * L]])
    K[np.ix_([1, 5, 7, 11], [1, 5, 7, 11])] += bend                        # v, rz (plane xy)
    flip = np.diag([1, -1, 1, -1])                                          # w, ry: ry = -dw/dx
    K[np.ix_([2, 4, 8, 10], [2, 4, 8, 10])] += flip @ bend @ flip           # w, ry (plane xz)
    return K


def stiffened_bar(mesh, K, M):
    """(K, M) over [3n translations, 3p rotations of the edge nodes] with frame elements along the
    bar's edge y = z = 0, and the edge's node rows (p,)."""
    edge = np.flatnonzero((np.abs(mesh.points[:, 1]) < 1e-9) & (np.abs(mesh.points[:, 2]) < 1e-9))
    edge = edge[np.argsort(mesh.points[edge, 0])]
    n, p = mesh.n_nodes, len(edge)
    rows, cols, vals, lumped = [], [], [], np.zeros(3 * n)
    for e, (a, b) in enumerate(zip(edge[:-1], edge[1:])):
        L = mesh.points[b, 0] - mesh.points[a, 0]
        dofs = np.r_[3 * a + np.arange(3), 3 * n + 3 * e + np.arange(3), 3 * b + np.arange(3),
                     3 * n + 3 * (e + 1) + np.arange(3)]
        rows.append(np.repeat(dofs, 12)), cols.append(np.tile(dofs, 12)), vals.append(frame_element(L).ravel())
        for node in (a, b):
            lumped[3 * node:3 * node + 3] += STIFFENER["rho"] * STIFFENER["A"] * L / 2
    size = 3 * (n + p)
    Kb = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(size, size))
    grow = sp.eye(size, 3 * n, format="csr")
    return (grow @ K.tocsr() @ grow.T + Kb).tocsr(), (grow @ (M.tocsr() + sp.diags(lumped)) @ grow.T).tocsr(), edge


def write_mtx6(path: Path, mesh, A, edge):
    """Abaqus .mtx of A over [translations, rotations of ``edge``] (upper triangle, DOFs 1-6)."""
    n = mesh.n_nodes
    A = sp.triu(A).tocoo()

    def node_and_dof(i):
        rot = i >= 3 * n
        node = np.where(rot, mesh.node_ids[edge[np.clip((i - 3 * n) // 3, 0, len(edge) - 1)]],
                        mesh.node_ids[np.minimum(i // 3, n - 1)])
        return node, i % 3 + 1 + 3 * rot

    (a, b), (c, d) = node_and_dof(A.row), node_and_dof(A.col)
    path.write_text("".join(f"{w},{x}, {y},{z}, {v:.17g}\n" for w, x, y, z, v in zip(a, b, c, d, A.data)))


def test_beam_rotations_reduce_like_their_exact_condensation(bar, tmp_path):
    """Rotation nodes kept as interior DOFs give the SID of the exactly condensed model (the rotations
    carry no mass, so K_tt - K_tr K_rr^-1 K_rt is exact), and the stiffener does change it."""
    import scipy.sparse.linalg as spla

    mesh, K, M = bar
    K6, M6, edge = stiffened_bar(mesh, K, M)
    t = 3 * mesh.n_nodes
    r = t + np.flatnonzero(K6.diagonal()[t:] > 0)                            # ry, rz (rx carries nothing)
    K_tt, K_tr, K_rr = K6[:t, :t], K6[:t][:, r], K6[r][:, r].tocsc()
    K_c = (K_tt - K_tr @ sp.csr_matrix(spla.spsolve(K_rr, K_tr.T.tocsc()))).tocoo()
    write_mtx6(tmp_path / "r_STIF1.mtx", mesh, K6, edge)
    write_mtx6(tmp_path / "r_MASS1.mtx", mesh, M6, edge)
    write_mtx(tmp_path / "c_STIF1.mtx", mesh, K_c)
    write_mtx(tmp_path / "c_MASS1.mtx", mesh, M6[:t, :t].tocoo())
    options = dict(interfaces=("fixed_end:rbe3", "free_end:rbe3"), modes=4)
    rotations = reduce(BAR, ReduceOptions(matrices=str(tmp_path / "r_STIF1.mtx"), **options))
    condensed = reduce(BAR, ReduceOptions(matrices=str(tmp_path / "c_STIF1.mtx"), **options))
    bare = reduce(BAR, ReduceOptions(**options, check_frequencies=False))
    assert rotations.passed and rotations.checks["rigid_energy_ratio"] < 1e-12
    assert rotations.sid.mass == pytest.approx(condensed.sid.mass, rel=1e-12)
    np.testing.assert_allclose(rotations.sid.frequencies_hz, condensed.sid.frequencies_hz, rtol=ROTATION_RTOL)
    assert np.abs(rotations.sid.frequencies_hz[:4] / bare.sid.frequencies_hz[:4] - 1).max() > 1e-2
    assert len(rotations.sid.surface.node_ids) == len(bare.sid.surface.node_ids)     # rotation nodes: no surface
    with pytest.raises(InputError, match="need at least one interface"):
        imported_model(mesh, tmp_path / "r_STIF1.mtx", unit_system("si"), n_interfaces=0)
