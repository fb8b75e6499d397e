"""sidprep reduce MODEL --matrices FILE with CalculiX's own matrices, run by the real ccx (Debian
calculix-ccx; .ci/run installs it): a C3D20 block sidprep cannot assemble, and the piston rod as a
C3D10 deck against sidprep's own assembly."""

import os
import shutil
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg as sla
from calculix_run import run_ccx

from sidprep.errors import InputError
from sidprep.fe.material import builtin_material
from sidprep.fe.matrices import read_matrices
from sidprep.fe.matrices.calculix import read_eigenvalues, tet_deck
from sidprep.fe.mesh import read_mesh
from sidprep.jobs.options import ReduceOptions
from sidprep.jobs.reduce import reduce
from sidprep.sid.model import inertia_matrix

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "import_calculix"
ROD = ROOT / "data" / "meshes" / "piston_rod.msh"
CCX = shutil.which("ccx")
pytestmark = pytest.mark.skipif(CCX is None, reason="CalculiX (ccx) is not installed: apt-get install calculix-ccx "
                                                    "(.ci/run does); these tests run the real code")

#: ccx's ARPACK eigenvalues vs a dense solve of the matrices it wrote (ARPACK's tolerance, 13-digit files)
CCX_EIGEN_RTOL = 1e-6
#: the SID's eigenfrequencies (3 elastic modes of interest, RBE3 ends: no added stiffness) vs ccx's
#: own free-free ones: Craig-Bampton truncation
SID_VS_CCX_RTOL = 2e-3
#: C3D20 (8 x 2 x 2) vs sidprep's tet10 (h = 12.5 mm) of the same block: discretisation of both
HEX_VS_TET_RTOL = 1e-2
#: piston rod, ccx's C3D10 matrices vs sidprep's assembly of the same mesh: mass to 1e-8;
#: frequencies to 1e-4 (CalculiX's C3D10 mass quadrature differs from the exact one by ~3e-5)
ROD_MASS_RTOL = 1e-8
ROD_FREQUENCY_RTOL = 1e-4


@pytest.fixture(scope="module")
def block(tmp_path_factory):
    """The example's C3D20 block run by ccx twice: matrices (block.sti/.mas/.dof) and ccx's own modes."""
    tmp = tmp_path_factory.mktemp("block")
    for name in ("block.inp", "block_eig.inp", "block_mesh.inp"):
        shutil.copy(EXAMPLE / name, tmp / name)
    run_ccx(tmp / "block.inp")
    run_ccx(tmp / "block_eig.inp")
    return tmp


def elastic(eigenvalues):
    lam = np.sort(eigenvalues)
    return lam[lam > 1e-6 * lam.max()]


def test_calculix_matrices_give_ccx_own_eigenvalues(block):
    fe = read_matrices(block / "block.sti")
    assert fe.K.shape == fe.M.shape == (len(fe.dofs),) * 2 and set(fe.dofs[:, 1]) == {1, 2, 3}
    lam = elastic(sla.eigh(fe.K.toarray(), fe.M.toarray(), eigvals_only=True))[:6]
    ccx = elastic(read_eigenvalues(block / "block_eig.eig"))[:6]
    np.testing.assert_allclose(lam, ccx, rtol=CCX_EIGEN_RTOL)
    # and the mass is rho V of the block (the consistent mass of any solid element)
    assert fe.M.sum() / 3 == pytest.approx(7850 * 0.2 * 0.05 * 0.05, rel=1e-12)


def test_sid_of_c3d20_block_matches_ccx_and_a_tet10_mesh(block, tmp_path):
    options = ReduceOptions(matrices=str(block / "block.sti"), interfaces=("END_A:rbe3", "END_B:rbe3"), modes=3)
    result = reduce(block / "block.inp", options)
    assert result.passed and result.checks["rigid_energy_ratio"] < 1e-12
    assert result.sid.metadata["material"]["name"].startswith("none: K and M from")
    f_sid = result.sid.frequencies_hz[:3]
    f_ccx = np.sqrt(elastic(read_eigenvalues(block / "block_eig.eig"))[:3]) / (2 * np.pi)
    np.testing.assert_allclose(f_sid, f_ccx, rtol=SID_VS_CCX_RTOL)
    assert result.sid.mass == pytest.approx(7850 * 0.2 * 0.05 * 0.05, rel=1e-12)
    # mass, first moment and inertia of the box [0, a] x [0, b] x [0, c] about the origin, closed form
    # (C3D20's consistent mass integrates these quadratics exactly): C = int x x^T dm, I = tr(C) E - C
    a, m = np.array([0.2, 0.05, 0.05]), 7850 * 0.2 * 0.05 * 0.05
    C = m * np.outer(a, a) / 4
    C[np.diag_indices(3)] = m * a ** 2 / 3
    np.testing.assert_allclose(result.sid.mdCM.M0.ravel(), m * a / 2, rtol=1e-12)
    np.testing.assert_allclose(inertia_matrix(result.sid.J.M0), np.trace(C) * np.eye(3) - C, rtol=1e-12)
    # the SID keeps CalculiX's node numbers: its interface masters are numbered after the deck's nodes
    assert result.sid.nodes[0].node_id == read_matrices(block / "block.sti").dofs[:, 0].max() + 1
    tet = reduce(tet10_block(tmp_path / "block.msh"), ReduceOptions(interfaces=("END_A:rbe3", "END_B:rbe3"), modes=3))
    np.testing.assert_allclose(f_sid, tet.sid.frequencies_hz[:3], rtol=HEX_VS_TET_RTOL)


def tet10_block(path: Path) -> Path:
    """gmsh tet10 mesh (h = 12.5 mm) of the example's block with node sets END_A (x = 0), END_B (x = 0.2 m)."""
    import gmsh

    gmsh.initialize(readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("block")
        gmsh.model.occ.addBox(0, 0, 0, 0.2, 0.05, 0.05)
        gmsh.model.occ.synchronize()
        for name, x in (("END_A", 0.0), ("END_B", 0.2)):
            faces = gmsh.model.getEntitiesInBoundingBox(x - 1e-6, -1, -1, x + 1e-6, 1, 1, dim=2)
            gmsh.model.setPhysicalName(2, gmsh.model.addPhysicalGroup(2, [t for _, t in faces]), name)
        gmsh.model.setPhysicalName(3, gmsh.model.addPhysicalGroup(3, [1]), "block")
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.0125)
        gmsh.option.setNumber("Mesh.ElementOrder", 2)
        gmsh.model.mesh.generate(3)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()
    return path


def test_piston_rod_from_ccx_matrices_matches_sidprep_assembly(tmp_path):
    deck = tmp_path / "rod.inp"
    tet_deck(read_mesh(ROD), deck, builtin_material("steel"))
    run_ccx(deck)
    own = reduce(deck, ReduceOptions(modes=6, check_frequencies=False))
    imported = reduce(deck, ReduceOptions(modes=6, check_frequencies=False, matrices=str(deck.with_suffix(".sti"))))
    assert imported.sid.mass == pytest.approx(own.sid.mass, rel=ROD_MASS_RTOL)
    np.testing.assert_allclose(imported.sid.mdCM.M0, own.sid.mdCM.M0, rtol=ROD_MASS_RTOL,
                               atol=ROD_MASS_RTOL * np.abs(own.sid.mdCM.M0).max())
    eigen = np.array(own.sid.mode_kinds) == "eigen"
    np.testing.assert_allclose(imported.sid.frequencies_hz[eigen], own.sid.frequencies_hz[eigen],
                               rtol=ROD_FREQUENCY_RTOL)
    assert [n.name for n in imported.sid.nodes] == [n.name for n in own.sid.nodes]


#: K and M of the .eig (binary) vs MATRIXSTORAGE's 13-digit ASCII of the same run's deck
EIG_VS_STI_RTOL = 1e-12


def test_eig_matrices_equal_matrixstorage_ones(block, tmp_path):
    """The .eig holds K and M without their structure; rebuilt from the deck it gives the .sti's matrices."""
    sti, eig = read_matrices(block / "block.sti"), read_matrices(block / "block_eig.eig")
    np.testing.assert_array_equal(eig.dofs, sti.dofs)
    for a, b in ((eig.K, sti.K), (eig.M, sti.M)):
        assert abs(a - b).max() <= EIG_VS_STI_RTOL * abs(b).max()
    assert len(eig.eigenvalues) == 12
    cut = tmp_path / "block_eig.eig"
    cut.write_bytes((block / "block_eig.eig").read_bytes()[:-100])
    shutil.copy(block / "block_eig.inp", tmp_path)
    shutil.copy(block / "block_mesh.inp", tmp_path)
    with pytest.raises(InputError, match="truncated"):
        read_matrices(cut)
    held = tmp_path / "held.inp"
    held.write_text((block / "block_eig.inp").read_text().replace("*STEP", "*BOUNDARY\nEND_A, 1, 3\n*STEP"))
    (tmp_path / "held.eig").write_bytes((block / "block_eig.eig").read_bytes())
    with pytest.raises(InputError, match=r"\*BOUNDARY.*SOLVER=MATRIXSTORAGE"):
        read_matrices(tmp_path / "held.eig")


#: examples/import_calculix/README.md: CalculiX 2.20's own eigenfrequencies of the block (block_eig.dat, Hz)
CCX_BLOCK_HZ = (5592.104, 5592.105, 7419.773)
#: the README's SID frequencies (Hz, 0.01 Hz) and its tet10 SID frequencies (Hz)
SID_BLOCK_HZ = (5594.72, 5594.72, 7423.86)
TET10_BLOCK_HZ = (5592.13, 5592.17, 7387.52)
#: printed digits of the README
README_RTOL = 2e-6


def test_example_numbers(block, tmp_path):
    readme = (EXAMPLE / "README.md").read_text()
    for f in CCX_BLOCK_HZ + SID_BLOCK_HZ + TET10_BLOCK_HZ:
        assert f"{f:.2f}" in readme or f"{f:.3f}" in readme, f
    ccx = np.sqrt(elastic(read_eigenvalues(block / "block_eig.eig"))[:3]) / (2 * np.pi)
    np.testing.assert_allclose(ccx, CCX_BLOCK_HZ, rtol=README_RTOL)
    options = ReduceOptions(matrices=str(block / "block.sti"), interfaces=("END_A:rbe3", "END_B:rbe3"), modes=3)
    np.testing.assert_allclose(reduce(block / "block.inp", options).sid.frequencies_hz[:3], SID_BLOCK_HZ,
                               rtol=README_RTOL)
    tet = reduce(tet10_block(tmp_path / "b.msh"), ReduceOptions(interfaces=("END_A:rbe3", "END_B:rbe3"), modes=3))
    np.testing.assert_allclose(tet.sid.frequencies_hz[:3], TET10_BLOCK_HZ, rtol=README_RTOL)


def test_job_file_resolves_matrices_beside_it(block, tmp_path):
    from sidprep.jobs.jobfile import read_job

    job = tmp_path / "job.toml"
    job.write_text(f'mesh = "{block / "block.inp"}"\nmatrices = "{Path(os.path.relpath(block / "block.sti", tmp_path))}"\n')
    assert read_job(job).options.matrices == str((block / "block.sti").resolve())


def test_reduction_from_eig_reports_ccx_own_frequencies(block):
    """--matrices jobname.eig: the check table carries CalculiX's own frequencies beside the SID's."""
    options = ReduceOptions(matrices=str(block / "block_eig.eig"), interfaces=("END_A:rbe3", "END_B:rbe3"), modes=3)
    result = reduce(block / "block_eig.inp", options)
    np.testing.assert_allclose(result.checks["fe_code_frequencies_hz"], CCX_BLOCK_HZ, rtol=README_RTOL)
    assert result.passed and result.checks["fe_code_frequency_max_rel_error"] < SID_VS_CCX_RTOL
    np.testing.assert_allclose(result.sid.frequencies_hz[:3], SID_BLOCK_HZ, rtol=README_RTOL)
