"""Clamped exports: K and M written with supported DOFs removed (CalculiX *BOUNDARY, Nastran SPC1 /
GRDSET) give a SID whose frame is attached at the supported nodes.

References: the Euler-Bernoulli cantilever (first bending frequency (beta_1 L)^2 / (2 pi L^2)
sqrt(E I / (rho A)), beta_1 L = 1.8751040687, e.g. Blevins, Formulas for Natural Frequency and
Mode Shape, 1979, table 8-1) and ccx's own eigenvalues of the clamped deck."""

import subprocess
import sys

import meshio
import numpy as np
import pytest
from calculix_run import needs_ccx
from hex_decks import RHO, E, end_sets, hex_bar, material, write_pair, write_punch

from sidprep.errors import InputError
from sidprep.fe.matrices import read_matrices
from sidprep.fe.matrices.calculix import read_eigenvalues
from sidprep.jobs.options import ReduceOptions
from sidprep.jobs.reduce import reduce

pytestmark = needs_ccx

#: the slender cantilever (m): L / h = 50, 20 x 1 x 1 C3D20
LENGTHS, DIVISIONS = np.array([1.0, 0.02, 0.02]), (20, 1, 1)
#: first root of 1 + cos(bL) cosh(bL) = 0 (clamped-free Euler-Bernoulli beam)
BETA1_L = 1.8751040687
#: the solid's first bending frequency vs Euler-Bernoulli: the 3D clamp also holds the root section's
#: Poisson contraction (stiffer), shear and the mesh (ccx's own: +5.6e-3 at L / h = 50)
EULER_BERNOULLI_RTOL = 1e-2
#: the SID vs ccx's own clamped eigenvalues: Craig-Bampton truncation at the free end's interface
#: (measured 1.1e-5)
SID_VS_CCX_RTOL = 1e-4
#: the same matrices through a 17-digit DMIG punch: round-off
DMIG_RTOL = 1e-9


@pytest.fixture(scope="module")
def cantilever(tmp_path_factory):
    """The bar clamped at x = 0 (*BOUNDARY, END_A, 1, 3), written by ccx (matrices and own modes)."""
    tmp = tmp_path_factory.mktemp("clamped")
    lines, ids, _ = hex_bar(LENGTHS, DIVISIONS, quadratic=True)
    write_pair(tmp, "beam", lines + end_sets(ids, 2 * DIVISIONS[0]) + material() + ["*BOUNDARY", "END_A, 1, 3"])
    return tmp


def euler_bernoulli_hz(lengths) -> float:
    L, h = lengths[0], lengths[1]
    return BETA1_L ** 2 / (2 * np.pi * L ** 2) * np.sqrt(E * h ** 2 / (12 * RHO))


def test_clamped_export_gives_the_cantilever_with_its_frame_at_the_clamp(cantilever):
    result = reduce(cantilever / "beam.inp", ReduceOptions(matrices=str(cantilever / "beam.sti"), modes=4))
    assert result.passed
    assert result.sid.metadata["frame"] == "END_A"
    assert [n.name for n in result.sid.nodes] == ["END_A", "END_B"]
    assert any("clamped at 8 nodes" in n and "frame is attached there" in n for n in result.notes)
    f = result.sid.frequencies_hz
    assert f[0] == pytest.approx(euler_bernoulli_hz(LENGTHS), rel=EULER_BERNOULLI_RTOL)
    assert f[1] == pytest.approx(f[0], rel=1e-6)                                  # square section
    ccx = np.sqrt(np.sort(read_eigenvalues(cantilever / "beam_eig.eig"))) / (2 * np.pi)
    np.testing.assert_allclose(f[:4], ccx[:4], rtol=SID_VS_CCX_RTOL)
    # the clamped nodes stay at the frame in every mode
    s = result.sid.surface
    assert np.abs(s.shapes[np.abs(s.points[:, 0]) < 1e-12]).max() == 0.0
    with pytest.raises(InputError, match="frame of a clamped export is its support"):
        reduce(cantilever / "beam.inp", ReduceOptions(matrices=str(cantilever / "beam.sti"), frame="END_B"))


def nastran_deck(path, deck, cards: list[str]):
    """The CalculiX deck's nodes and hexahedra as a Nastran bulk deck (meshio) with ``cards`` added."""
    m = meshio.read(deck, file_format="abaqus")
    meshio.write(path, meshio.Mesh(m.points, [(b.type, b.data) for b in m.cells]), file_format="nastran")
    text = path.read_text().replace("ENDDATA", "\n".join(cards) + "\nENDDATA")
    path.write_text(text)


def test_nastran_spc1_and_planar_grdset(cantilever, tmp_path):
    """SPC1 on the clamped grids gives the CalculiX route's SID; GRDSET 1256 (every grid without DOFs
    1 and 2: a planar export) is refused with one line that says why."""
    fe = read_matrices(cantilever / "beam.sti")
    write_punch(tmp_path / "beam.pch", fe)
    free = np.unique(fe.dofs[:, 0])                               # ccx wrote no DOF of the clamped nodes
    held = sorted(set(range(1, int(free.max()) + 1)) - set(free.tolist()))
    bdf = tmp_path / "beam.bdf"
    nastran_deck(bdf, cantilever / "beam.inp", ["SPC1,1,123," + ",".join(map(str, held))])
    nastran = reduce(bdf, ReduceOptions(matrices=str(tmp_path / "beam.pch"), modes=4))
    calculix = reduce(cantilever / "beam.inp", ReduceOptions(matrices=str(cantilever / "beam.sti"), modes=4,
                                                            interfaces=("END_A",)))
    assert nastran.sid.metadata["frame"] == "SPC"
    np.testing.assert_allclose(nastran.sid.frequencies_hz[:4], calculix.sid.frequencies_hz[:4], rtol=DMIG_RTOL)
    planar = tmp_path / "planar.bdf"
    nastran_deck(planar, cantilever / "beam.inp", ["GRDSET,,,,,,,1256"])
    write_punch(tmp_path / "planar.pch", fe, drop=(1, 2))
    done = subprocess.run([sys.executable, "-m", "sidprep.cli.main", "reduce", str(planar), "--matrices",
                           str(tmp_path / "planar.pch"), "-o", str(tmp_path / "p.sid.h5"), "-q"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert "every node of MODEL lacks DOF 1, 2" in done.stderr and "3D" in done.stderr
    assert not (tmp_path / "p.sid.h5").exists()


def test_rigid_body_clamp_and_pin(tmp_path):
    """A bar clamped through a *RIGID BODY on its end face (reference and rotation nodes supported):
    the frame is the reference node, the frequencies ccx's own; the reference node alone supported
    is a pin (ccx leaves the rotation free) and is refused."""
    lengths, divisions = np.array([0.2, 0.02, 0.02]), (10, 2, 2)
    lines, ids, _ = hex_bar(lengths, divisions)
    model = lines + ["*NODE", "9000, 0.0, 0.01, 0.01"] + end_sets(ids, divisions[0]) + material() + [
        "*RIGID BODY, NSET=END_A, REF NODE=9000, ROT NODE=9001", "*NODE", "9001, 0.0, 0.01, 0.01"]
    write_pair(tmp_path, "held", model + ["*BOUNDARY", "9000, 1, 3", "9001, 1, 3"])
    result = reduce(tmp_path / "held.inp", ReduceOptions(matrices=str(tmp_path / "held.sti"), modes=4))
    assert result.passed and result.sid.metadata["frame"] == "END_A"
    assert [n.name for n in result.sid.nodes] == ["END_A", "END_B"]
    np.testing.assert_allclose(result.sid.nodes[0].origin.M0.ravel(), [0, 0.01, 0.01], atol=1e-15)
    ccx = np.sqrt(np.sort(read_eigenvalues(tmp_path / "held_eig.eig"))) / (2 * np.pi)
    np.testing.assert_allclose(result.sid.frequencies_hz[:4], ccx[:4], rtol=SID_VS_CCX_RTOL)
    write_pair(tmp_path, "pin", model + ["*BOUNDARY", "9000, 1, 3"])
    with pytest.raises(InputError, match="a pin"):
        reduce(tmp_path / "pin.inp", ReduceOptions(matrices=str(tmp_path / "pin.sti"), modes=4))
