"""Matrices from which CalculiX eliminated dependent DOFs (*EQUATION, *RIGID BODY), run by the real
ccx: the dependent DOFs are recovered from the deck's equations (sidprep.fe.matrices.constraints).

References: the same bar with shared nodes instead of the glue (the same physics), ccx's own
eigenvalues of the rigid-body deck (``*FREQUENCY, STORAGE=YES``) and the closed-form mass
properties of the box (C3D8's consistent mass integrates the quadratics exactly)."""

import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest
from calculix_run import frd_block, needs_ccx
from hex_decks import (
    RHO,
    bdf,
    end_sets,
    hex_bar,
    material,
    node_set,
    write_pair,
    write_punch,
)

from sidprep.errors import InputError
from sidprep.fe.material import unit_system
from sidprep.fe.matrices import read_matrices
from sidprep.fe.matrices.calculix import read_eigenvalues
from sidprep.fe.matrices.deck import read_model
from sidprep.fe.matrices.onto_model import imported_model
from sidprep.jobs.options import ReduceOptions
from sidprep.jobs.reduce import reduce
from sidprep.sid.model import inertia_matrix

pytestmark = needs_ccx

#: the bar (m) and its hexahedra
LENGTHS, DIVISIONS = np.array([0.2, 0.02, 0.02]), (10, 2, 2)
#: glued vs shared nodes: the same K and M up to the glue's elimination (ccx's 13 digits), the same
#: Craig-Bampton space: round-off only
GLUE_RTOL = 1e-6
#: the SID's frequencies vs ccx's own free-free ones: Craig-Bampton truncation (one interface, 8
#: modes, cut-off factor 7; measured 3e-5 .. 8e-4)
SID_VS_CCX_RTOL = 2e-3
#: mass, first moment, inertia vs the box's closed form (exact integration, 13-digit files)
MASS_RTOL = 1e-12
#: 1 - MAC of the recovered end-face displacements against ccx's own mode shapes (.frd, 6 digits) for
#: the non-degenerate modes (torsion 8052 Hz, 12992 Hz; measured 1e-14)
FACE_MAC_TOL = 1e-6


def box_inertia(lengths, m):
    """Inertia tensor about the origin of a homogeneous box [0, a] x [0, b] x [0, c] of mass m."""
    C = m * np.outer(lengths, lengths) / 4
    C[np.diag_indices(3)] = m * lengths ** 2 / 3
    return np.trace(C) * np.eye(3) - C


def glued_decks(folder, tets=False):
    """The bar as two parts (x < 0.1 m and x > 0.1 m, their own nodes) glued face to face by
    *EQUATION, and the same bar with shared nodes; both written by ccx into ``folder``."""
    half = (DIVISIONS[0] // 2, *DIVISIONS[1:])
    a_lines, a_ids, _ = hex_bar(LENGTHS * [0.5, 1, 1], half, tets=tets)
    b_lines, b_ids, _ = hex_bar(LENGTHS * [0.5, 1, 1], half, x0=LENGTHS[0] / 2, first_node=1001, first_element=1001,
                                elset="EB", tets=tets)
    glue = ["*EQUATION"]
    for (i, j, k), node in b_ids.items():
        if i == 0:
            glue += [f"2\n{node}, {c}, 1.0, {a_ids[half[0], j, k]}, {c}, -1.0" for c in (1, 2, 3)]
    ends = (node_set("END_A", [v for (i, _, _), v in a_ids.items() if i == 0])
            + node_set("END_B", [v for (i, _, _), v in b_ids.items() if i == half[0]]))
    write_pair(folder, "glued", a_lines + b_lines + ends + glue + material(("EALL", "EB")))
    s_lines, s_ids, _ = hex_bar(LENGTHS, DIVISIONS, tets=tets)
    write_pair(folder, "shared", s_lines + end_sets(s_ids, DIVISIONS[0]) + material())
    return folder


@pytest.fixture(scope="module")
def glued(tmp_path_factory):
    return glued_decks(tmp_path_factory.mktemp("glued"))


def test_glued_parts_give_the_shared_node_model(glued):
    """Two *NODE blocks (one per part), 27 equations: the SID of the shared-node bar, and the glued
    faces are inside the body (not on the OBJ surface)."""
    options = dict(interfaces=("END_A:rbe3", "END_B:rbe3"), modes=6)
    shared = reduce(glued / "shared.inp", ReduceOptions(matrices=str(glued / "shared.sti"), **options))
    glue = reduce(glued / "glued.inp", ReduceOptions(matrices=str(glued / "glued.sti"), **options))
    assert glue.passed and glue.checks["rigid_energy_ratio"] < 1e-12
    np.testing.assert_allclose(glue.sid.frequencies_hz, shared.sid.frequencies_hz, rtol=GLUE_RTOL)
    assert glue.sid.mass == pytest.approx(shared.sid.mass, rel=MASS_RTOL)
    np.testing.assert_allclose(inertia_matrix(glue.sid.J.M0), inertia_matrix(shared.sid.J.M0), rtol=MASS_RTOL,
                               atol=MASS_RTOL * np.abs(inertia_matrix(shared.sid.J.M0)).max())
    assert len(glue.sid.surface.triangles) == len(shared.sid.surface.triangles)
    # the dependent nodes of part B (numbers from 1001) on the side faces follow their part-A
    # partners at the same place in every mode: their DOFs are recovered from the equations
    s = glue.sid.surface
    at_glue = np.flatnonzero(np.abs(s.points[:, 0] - LENGTHS[0] / 2) < 1e-12)
    a, b = at_glue[s.node_ids[at_glue] < 1001], at_glue[s.node_ids[at_glue] >= 1001]
    b = b[[int(np.argmin(np.linalg.norm(s.points[b] - s.points[i], axis=1))) for i in a]]
    assert len(a) == 8 and np.allclose(s.points[a], s.points[b])
    np.testing.assert_array_equal(s.shapes[b], s.shapes[a])
    assert any("27 constraint equations" in n for n in glue.notes)


def test_glued_tetrahedral_parts(tmp_path):
    """A C3D4 deck with *EQUATION (read as a sidprep mesh, which merges the glued faces' coincident
    nodes; the dependent nodes come back as nodes of the equations): the SID of the shared-node deck."""
    glued_decks(tmp_path, tets=True)
    options = {"interfaces": ("END_A:rbe3", "END_B:rbe3"), "modes": 6}
    shared = reduce(tmp_path / "shared.inp", ReduceOptions(matrices=str(tmp_path / "shared.sti"), **options))
    glue = reduce(tmp_path / "glued.inp", ReduceOptions(matrices=str(tmp_path / "glued.sti"), **options))
    np.testing.assert_allclose(glue.sid.frequencies_hz, shared.sid.frequencies_hz, rtol=GLUE_RTOL)
    assert glue.sid.mass == pytest.approx(shared.sid.mass, rel=MASS_RTOL)


@pytest.fixture(scope="module")
def rigid(tmp_path_factory):
    """The bar with a *RIGID BODY on its end face x = 0.2 m, its reference node in a *NODE block of
    its own at the face centre (ccx generates the rotation node)."""
    tmp = tmp_path_factory.mktemp("rigid")
    lines, ids, _ = hex_bar(LENGTHS, DIVISIONS)
    ref = ["*NODE", f"9000, {LENGTHS[0]:.12e}, {LENGTHS[1] / 2:.12e}, {LENGTHS[2] / 2:.12e}"]
    body = ["*RIGID BODY, NSET=END_B, REF NODE=9000"]
    write_pair(tmp, "rigid", lines + ref + end_sets(ids, DIVISIONS[0]) + material() + body)
    return tmp


def test_rigid_body_end_face_gives_ccx_frequencies_and_the_box_mass(rigid):
    """The reference node is the SID node of the interface named by the rigid body's node set; the
    face's mass, which ccx folded onto the reference and rotation nodes, is back on the face."""
    result = reduce(rigid / "rigid.inp", ReduceOptions(matrices=str(rigid / "rigid.sti"), interfaces=("END_B",),
                                                       modes=8, cutoff_factor=7))
    assert result.passed and result.checks["rigid_energy_ratio"] < 1e-12
    ccx = np.sort(read_eigenvalues(rigid / "rigid_eig.eig"))
    ccx_hz = np.sqrt(ccx[ccx > 1e-6 * ccx.max()]) / (2 * np.pi)
    np.testing.assert_allclose(result.sid.frequencies_hz[:6], ccx_hz[:6], rtol=SID_VS_CCX_RTOL)
    m = RHO * LENGTHS.prod()
    assert result.sid.mass == pytest.approx(m, rel=MASS_RTOL)
    np.testing.assert_allclose(result.sid.mdCM.M0.ravel(), m * LENGTHS / 2, rtol=MASS_RTOL)
    I = box_inertia(LENGTHS, m)
    np.testing.assert_allclose(inertia_matrix(result.sid.J.M0), I, atol=MASS_RTOL * np.abs(I).max())
    (node,) = result.sid.nodes
    assert node.name == "END_B"
    ref = np.array([0.2, 0.01, 0.01])
    np.testing.assert_allclose(node.origin.M0.ravel(), ref, atol=1e-15)
    # the face is rigid in every mode: its recovered displacements are u_ref + theta x (x - x_ref)
    s = result.sid.surface
    face = np.abs(s.points[:, 0] - LENGTHS[0]) < 1e-12
    u, theta = node.phi.M0.T, node.psi.M0.T                                  # (nq, 3)
    rigid_face = u[:, None, :] + np.cross(theta[:, None, :], (s.points[face] - ref)[None])     # (nq, k, 3)
    assert face.sum() == 9
    np.testing.assert_allclose(np.transpose(s.shapes[face], (2, 0, 1)), rigid_face, atol=1e-9 * np.abs(s.shapes).max())
    # ... and they are ccx's own: the face's displacements in ccx's mode shapes (modes 9 and 12 of the
    # 12, after 6 rigid ones: the torsion and the first non-degenerate one above it)
    for ccx_mode, sid_mode in ((8, 2), (11, 5)):
        shape = frd_block(rigid / "rigid_eig.frd", "DISP", ccx_mode)
        a = np.array([shape[n] for n in s.node_ids[face]]).ravel()
        b = s.shapes[face][:, :, sid_mode].ravel()
        assert 1 - (a @ b) ** 2 / ((a @ a) * (b @ b)) < FACE_MAC_TOL


def test_kinematic_coupling_on_element_faces_is_the_rigid_body(rigid, tmp_path):
    """*COUPLING + *KINEMATIC (DOFs 1-3) on an element-face *SURFACE of the end face: ccx writes the
    rigid body's matrices, and the SID is the *RIGID BODY one."""
    lines, ids, _ = hex_bar(LENGTHS, DIVISIONS)
    tip = [DIVISIONS[0] * (1 + j + DIVISIONS[1] * k) for j in range(DIVISIONS[1]) for k in range(DIVISIONS[2])]
    ref = ["*NODE", f"9000, {LENGTHS[0]:.12e}, {LENGTHS[1] / 2:.12e}, {LENGTHS[2] / 2:.12e}"]
    coupling = ["*ELSET, ELSET=ETIP", ", ".join(map(str, tip)), "*SURFACE, NAME=TIP", "ETIP, S4",
                "*COUPLING, REF NODE=9000, SURFACE=TIP, CONSTRAINT NAME=GRIP", "*KINEMATIC", "1, 3"]
    write_pair(tmp_path, "coupled", lines + ref + end_sets(ids, DIVISIONS[0]) + material() + coupling)
    options = {"modes": 8, "cutoff_factor": 7}
    body = reduce(rigid / "rigid.inp", ReduceOptions(matrices=str(rigid / "rigid.sti"), interfaces=("END_B",),
                                                     **options))
    coupled = reduce(tmp_path / "coupled.inp", ReduceOptions(matrices=str(tmp_path / "coupled.sti"),
                                                             interfaces=("GRIP",), **options))
    np.testing.assert_allclose(coupled.sid.frequencies_hz, body.sid.frequencies_hz, rtol=GLUE_RTOL)
    assert coupled.sid.mass == pytest.approx(body.sid.mass, rel=MASS_RTOL)
    assert any("rigid body GRIP (9 nodes)" in n for n in coupled.notes)


#: the same deck in mm-t-s and in SI: ccx's 13 digits
UNITS_RTOL = 1e-9


def test_rigid_body_deck_in_mm_t_s_gives_the_si_sid(rigid, tmp_path):
    """K and M of a rotation node scale differently from those of translations (N mm / rad, t mm^2):
    the same deck in mm, t, s (--units mm-t-s) gives the SI deck's SID."""
    lines, ids, _ = hex_bar(LENGTHS * 1e3, DIVISIONS)
    ref = ["*NODE", "9000, 200, 10, 10"]
    body = ["*RIGID BODY, NSET=END_B, REF NODE=9000"]
    write_pair(tmp_path, "mm", lines + ref + end_sets(ids, DIVISIONS[0]) + material(modulus=210e3, density=7.85e-9)
               + body)
    options = {"interfaces": ("END_B",), "modes": 8, "cutoff_factor": 7}
    si = reduce(rigid / "rigid.inp", ReduceOptions(matrices=str(rigid / "rigid.sti"), **options))
    mm = reduce(tmp_path / "mm.inp", ReduceOptions(matrices=str(tmp_path / "mm.sti"), units="mm-t-s", **options))
    np.testing.assert_allclose(mm.sid.frequencies_hz, si.sid.frequencies_hz, rtol=UNITS_RTOL)
    assert mm.sid.mass == pytest.approx(si.sid.mass, rel=UNITS_RTOL)
    np.testing.assert_allclose(inertia_matrix(mm.sid.J.M0), inertia_matrix(si.sid.J.M0), rtol=UNITS_RTOL,
                               atol=UNITS_RTOL * np.abs(inertia_matrix(si.sid.J.M0)).max())


#: the same matrices through a 17-digit DMIG punch and a Nastran deck: round-off
NASTRAN_RTOL = 1e-9


def test_nastran_mpc_and_rbe2_give_the_calculix_sids(glued, rigid, tmp_path):
    """The glue as MPC cards and the rigid end face as an RBE2 (its rotation on GN's DOFs 4-6), with
    ccx's matrices in a punch: the SIDs of the CalculiX decks."""
    half = (DIVISIONS[0] // 2, *DIVISIONS[1:])
    a_lines, a_ids, a_xyz = hex_bar(LENGTHS * [0.5, 1, 1], half)
    b_lines, b_ids, b_xyz = hex_bar(LENGTHS * [0.5, 1, 1], half, x0=LENGTHS[0] / 2, first_node=1001,
                                    first_element=1001)
    mpcs = [f"MPC,1,{node},{c},1.0,{a_ids[half[0], j, k]},{c},-1.0" for (i, j, k), node in b_ids.items() if i == 0
            for c in (1, 2, 3)]
    bdf(tmp_path / "glued.bdf", {**a_xyz, **b_xyz}, a_lines + b_lines, mpcs)
    write_punch(tmp_path / "glued.pch", read_matrices(glued / "glued.sti"))
    options = {"interfaces": ("END_A:rbe3", "END_B:rbe3"), "modes": 6}
    calculix = reduce(glued / "glued.inp", ReduceOptions(matrices=str(glued / "glued.sti"), **options))
    ends = {"END_A": [v for (i, _, _), v in a_ids.items() if i == 0], "END_B": [v for (i, _, _), v in b_ids.items()
                                                                             if i == half[0]]}
    mesh = read_model(tmp_path / "glued.bdf")
    rows = {name: np.flatnonzero(np.isin(mesh.node_ids, nodes)) for name, nodes in ends.items()}
    nastran = reduce(replace(mesh, node_sets=rows), ReduceOptions(matrices=str(tmp_path / "glued.pch"), **options))
    np.testing.assert_allclose(nastran.sid.frequencies_hz, calculix.sid.frequencies_hz, rtol=NASTRAN_RTOL)
    lines, ids, xyz = hex_bar(LENGTHS, DIVISIONS)
    face = [v for (i, _, _), v in ids.items() if i == DIVISIONS[0]]
    bdf(tmp_path / "rigid.bdf", xyz, lines, ["GRID,9000,,0.2,0.01,0.01", "RBE2,7,9000,123," + ",".join(map(str, face))])
    fe = read_matrices(rigid / "rigid.sti")
    renamed = fe.dofs.copy()
    renamed[fe.dofs[:, 0] == 9001] = np.column_stack([np.full(3, 9000), fe.dofs[fe.dofs[:, 0] == 9001, 1] + 3])
    write_punch(tmp_path / "rigid.pch", fe, renamed=renamed)
    options = {"modes": 8, "cutoff_factor": 7}
    calculix = reduce(rigid / "rigid.inp", ReduceOptions(matrices=str(rigid / "rigid.sti"), interfaces=("END_B",),
                                                         **options))
    nastran = reduce(tmp_path / "rigid.bdf", ReduceOptions(matrices=str(tmp_path / "rigid.pch"),
                                                           interfaces=("RBE2_7",), **options))
    np.testing.assert_allclose(nastran.sid.frequencies_hz, calculix.sid.frequencies_hz, rtol=NASTRAN_RTOL)
    assert nastran.sid.mass == pytest.approx(RHO * LENGTHS.prod(), rel=MASS_RTOL)
    np.testing.assert_allclose(nastran.sid.nodes[0].origin.M0.ravel(), [0.2, 0.01, 0.01], atol=1e-15)


# ---------------------------------------------------------------------------------------------
# bad input: one line naming the file, the problem and the fix; exit 2 and nothing written
# ---------------------------------------------------------------------------------------------

#: deck additions -> the problem the message names
BAD_DECKS = {
    "*EQUATION\n2\n99999, 1, 1.0, 1, 1, -1.0": "uses DOF 1 of node 99999, which the model does not have",
    "*EQUATION\n2\n1, 1, 1.0, 2, 1, -1.0\n2\n2, 1, 1.0, 1, 1, -1.0": "constraint equations are singular",
    "*EQUATION\n2\n1, 1, 0.0, 2, 1, 1.0": "zero coefficient on its dependent",
    "*EQUATION\n2\n1, 1, 1.0, 2, 1, -1.0\n2\n1, 1, 1.0, 3, 1, -1.0": "dependent DOF of 2 equations",
    "*MPC\nBEAM, 1, 2": r"\*MPC is not read by sidprep .* write linear constraints as \*EQUATION",
    "*COUPLING, REF NODE=1, SURFACE=S, CONSTRAINT NAME=C": r"\*COUPLING followed by \*MATERIAL: sidprep reads "
                                                          "kinematic couplings",
    "*COUPLING, REF NODE=1, SURFACE=S\n*DISTRIBUTING\n1, 3": r"\*DISTRIBUTING is not read",
    "*RIGID BODY, NSET=NOPE, REF NODE=1": "NSET=NOPE: no such node set",
}


def test_bad_constraints_are_one_line_errors(glued, tmp_path):
    text = (glued / "glued.inp").read_text()
    for k, (extra, problem) in enumerate(BAD_DECKS.items()):
        deck = tmp_path / f"bad{k}.inp"
        deck.write_text(text.replace("*MATERIAL", extra + "\n*MATERIAL"))
        with pytest.raises(InputError, match=problem) as info:
            imported_model(read_model(deck), glued / "glued.sti", unit_system("si"))
        assert str(deck) in str(info.value) and "\n" not in str(info.value), problem
    shared = tmp_path / "shared_as_glued.inp"                    # the deck's glue, the shared model's matrices
    shared.write_text(text)
    with pytest.raises(InputError, match="not in MODEL|no row"):
        imported_model(read_model(shared), glued / "shared.sti", unit_system("si"))
    done = subprocess.run([sys.executable, "-m", "sidprep.cli.main", "reduce", str(tmp_path / "bad1.inp"),
                           "--matrices", str(glued / "glued.sti"), "-o", str(tmp_path / "x.sid.h5"), "-q"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 2 and done.stderr.count("\n") == 1 and "singular" in done.stderr, done.stderr
    assert not (tmp_path / "x.sid.h5").exists()


def test_chained_equations_resolve_to_independent_dofs():
    """u0 = 2 u3 and u3 = u5 / 2 + u4 (u3 dependent, on the right of the first): u0 = u5 + 2 u4,
    u3 = u5 / 2 + u4, by hand."""
    from sidprep.fe.matrices.constraints import constraint_map

    c = constraint_map([(np.array([0, 3]), np.array([1.0, -2.0])), (np.array([3, 5, 4]), np.array([2.0, -1.0, -2.0]))],
                       6, "deck", str)
    np.testing.assert_array_equal(c.dependent, [0, 3])
    np.testing.assert_allclose(c.S[[0, 3]].toarray(), [[0, 0, 0, 0, 2, 1], [0, 0, 0, 0, 1, 0.5]], atol=1e-15)
