"""The unit system of imported K and M (``reduce MODEL --matrices FILE [--units]``) checked from the model's
own numbers: the example's C3D20 steel block written by ccx once in SI and once in mm-t-s (the tests
skip without ccx, as tests/test_import_calculix.py)."""

import os
import subprocess
import sys
from pathlib import Path

import pytest
from calculix_run import needs_ccx, run_ccx

from sidprep.errors import InputError
from sidprep.fe.material import unit_system
from sidprep.fe.matrices.deck import read_model
from sidprep.fe.matrices.onto_model import imported_model
from sidprep.fe.plausibility import check_model_units, solid_unit_systems

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "import_calculix"
#: K and M of the mm-t-s deck converted to SI vs those of the SI deck: ccx writes 13 digits
SAME_MATRICES_RTOL = 1e-11
#: the example block: steel (7850 kg/m^3), 0.2 x 0.05 x 0.05 m
BLOCK_MASS_KG = 7850 * 0.2 * 0.05 * 0.05


def mm_t_s(si_mesh: str) -> str:
    """The *NODE lines of a deck in SI with coordinates in mm (everything else as it is)."""
    out, block = [], ""
    for line in si_mesh.splitlines():
        if line.startswith("*"):
            block = line.split(",")[0].upper()
        elif block == "*NODE":
            number, *x = line.split(",")
            line = f"{number}, " + ", ".join(f"{1e3 * float(v):.10g}" for v in x)
        out.append(line)
    return "\n".join(out) + "\n"


@pytest.fixture(scope="module")
def decks(tmp_path_factory):
    """si.inp (m, kg, N, Pa) and mm.inp (mm, t, N, MPa) of the example's block, with ccx's matrices."""
    tmp = tmp_path_factory.mktemp("units")
    si_mesh = (EXAMPLE / "block_mesh.inp").read_text()
    step = "*STEP\n*FREQUENCY, SOLVER=MATRIXSTORAGE\n12\n*END STEP\n"
    for name, mesh, E, rho in (("si", si_mesh, "210e9", "7850"), ("mm", mm_t_s(si_mesh), "210000", "7.85e-9")):
        (tmp / f"{name}_mesh.inp").write_text(mesh)
        (tmp / f"{name}.inp").write_text(f"*INCLUDE, INPUT={name}_mesh.inp\n*MATERIAL, NAME=STEEL\n*ELASTIC\n{E}, 0.3\n"
                                         f"*DENSITY\n{rho}\n*SOLID SECTION, ELSET=EALL, MATERIAL=STEEL\n{step}")
        run_ccx(tmp / f"{name}.inp")
    return tmp


@needs_ccx
def test_mm_t_s_deck_gives_the_si_decks_matrices(decks):
    si = imported_model(read_model(decks / "si.inp"), decks / "si.sti", unit_system("si"))
    mm = imported_model(read_model(decks / "mm.inp").scaled(1e-3), decks / "mm.sti", unit_system("mm-t-s"))
    for a, b in ((mm.K, si.K), (mm.M, si.M)):
        assert abs(a - b).max() <= SAME_MATRICES_RTOL * abs(b).max()
    assert si.M.sum() / 3 == pytest.approx(BLOCK_MASS_KG, rel=1e-12)


def reduce_cli(deck: Path, *options: str):
    out = deck.parent / f"{deck.stem}_out"
    done = subprocess.run([sys.executable, "-m", "sidprep.cli.main", "reduce", str(deck), "--matrices",
                           str(deck.with_suffix(".sti")), "--interface", "END_A", "--interface", "END_B",
                           "-o", str(out / "b.sid.h5"), "-q", *options],
                          capture_output=True, text=True, timeout=300, env={**os.environ, "PYTHONPATH": str(ROOT)},
                          check=False)
    return done, out


@needs_ccx
@pytest.mark.parametrize(("deck", "given", "fits"), [("si", ("--units", "mm-t-s"), "si"), ("mm", (), "mm-t-s")])
def test_wrong_unit_system_is_one_line_naming_the_right_one(decks, deck, given, fits):
    """SI numbers read as mm-t-s (a 3.9 t body 0.2 mm long) and mm-t-s numbers read as SI (a 3.9 g body
    200 m long): refused before the run, one line naming --units and the system the numbers fit."""
    done, out = reduce_cli(decks / f"{deck}.inp", *given)
    assert done.returncode == 2, done.stdout + done.stderr
    message = done.stderr.strip()
    assert len(message.splitlines()) == 1 and "Traceback" not in message
    assert f"run with --units {fits}" in message and "density" in message
    assert not out.exists() or not any(out.iterdir())


def test_numbers_of_no_unit_system_are_refused_with_the_systems_named():
    """A deck in mm, kg, s (force 1e-3 N, stress kPa: steel E = 2.1e8, rho = 7.85e-6) fits neither
    system: E 2.1e14 Pa and rho 7.85e6 kg/m^3 as mm-t-s, rho 7.85e-6 kg/m^3 as SI.  Its mass and
    volume alone (no material cards, e.g. a Nastran export) read as mm-t-s give a mean density of
    7.85e6 kg/m^3, which point masses on a light part can reach: accepted."""
    mass, volume = 3.925, 0.5e6                                 # kg and mm^3 of the steel block
    assert solid_unit_systems(mass, volume, [2.1e8], [7.85e-6]) == []
    assert solid_unit_systems(mass, volume) == ["mm-t-s"]
    assert solid_unit_systems(BLOCK_MASS_KG, 0.5e-3, [210e9], [7850.0]) == ["si"]
    assert solid_unit_systems(BLOCK_MASS_KG / 1e3, 0.5e6, [210e3], [7.85e-9]) == ["mm-t-s"]
    with pytest.raises(InputError, match="fit none of si, mm-t-s"):
        check_model_units("b.sti", unit_system("si"), mass, volume, 200.0, [2.1e8], [7.85e-6])
    # mass and density fit SI, the modulus is in MPa: refused, naming it
    with pytest.raises(InputError, match="E = 2.1e"):
        check_model_units("b.sti", unit_system("si"), BLOCK_MASS_KG, 0.5e-3, 0.2, [210e3])
