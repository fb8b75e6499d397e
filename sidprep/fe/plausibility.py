"""Unit plausibility: warn when size, mass or first frequency cannot belong to a machine part, and
refuse imported models whose own numbers belong to another unit system than the one given.

A mesh drawn in millimetres and run as SI is 1000x too large and 1e9x too heavy, yet internally
consistent (its frequencies are those of a 1000x larger part), so every FE check passes. These
rules catch it from the numbers an engineer would look at first.  For K and M of another FE code
(:func:`check_model_units`) the numbers are the model's own: the mean density (the mass of M over
the volume of the elements, both in the file's units) and the deck's E and rho, which a wrong one
of sidprep's unit systems puts 1e6 - 1e12 away from any solid.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sidprep.errors import InputError
from sidprep.fe.material import UNIT_SYSTEMS, Material, UnitSystem
from sidprep.fe.topology import cell_volumes

#: largest bounding-box edge (m) of a machine part; beyond it the mesh was probably drawn in mm
MAX_PART_SIZE_M = 50.0
#: smallest bounding-box edge (m); below it a mesh in metres was probably scaled as mm
MIN_PART_SIZE_M = 1e-3
#: largest plausible mass (kg) of one flexible body (a 1000 t part is a ship section, not a part)
MAX_PART_MASS_KG = 1e6
#: band around the wave-speed estimate c/L (c = sqrt(E/rho), L = largest edge) that a first
#: elastic frequency lies in: bending of a slender part (thickness/L) is lower, no part is stiffer
#: than ~10 c/L; the lower factor is multiplied by the slenderness (smallest/largest edge)
FREQUENCY_BAND = (1e-2, 10.0)

#: density of a solid material (kg/m^3): foams (~30, with a margin) to osmium (22 590)
DENSITY_RANGE_KG_M3 = (1.0, 3e4)
#: mean density of a model (kg/m^3): the mass of M over the volume of its elements, point masses
#: included (up to 1e5 x steel's for heavy masses on light parts).  The wrong one of sidprep's unit
#: systems is off by 1e12 (steel in mm-t-s read as SI: 7.85e-9 kg/m^3; SI read as mm-t-s: 7.85e15)
MEAN_DENSITY_RANGE_KG_M3 = (1.0, 1e9)
#: Young's modulus of a solid (Pa): elastomers (1 MPa and up) to diamond (1.2 TPa).  Every engineering
#: solid's modulus in MPa is below 1e6 (steel 2.1e5), so a modulus in MPa read as Pa falls out
MODULUS_RANGE_PA = (1e6, 2e12)

_MM = "--units mm-t-s"


def unit_warnings(points_m: np.ndarray, material: Material, mass_kg: float,
                  first_elastic_hz: float | None = None) -> list[str]:
    """Warnings (one line each) when the model looks like the wrong unit system.

    Parameters
    ----------
    points_m : (n, 3) array, node coordinates as used (m)
    material : the material in SI units
    mass_kg : total mass of the FE model (kg)
    first_elastic_hz : lowest elastic eigenfrequency (Hz), when known

    Returns
    -------
    list of str, empty when size, mass and frequency are plausible.
    """
    edges = np.ptp(np.asarray(points_m, dtype=float), axis=0)
    L, t = float(edges.max()), float(max(edges.min(), 1e-300))
    out = []
    if L > MAX_PART_SIZE_M:
        out.append(f"bounding box {L:.3g} m is over {MAX_PART_SIZE_M:g} m for a machine part: if the "
                   f"mesh is drawn in millimetres, run with {_MM}")
    elif L < MIN_PART_SIZE_M:
        out.append(f"bounding box {L:.3g} m is under {MIN_PART_SIZE_M * 1e3:g} mm: if the mesh is drawn "
                   f"in metres, drop {_MM} (use --units si)")
    if mass_kg > MAX_PART_MASS_KG:
        out.append(f"mass {mass_kg:.3g} kg is over {MAX_PART_MASS_KG:.0e} kg for one part: if the mesh "
                   f"is drawn in millimetres, run with {_MM}")
    if first_elastic_hz is not None and first_elastic_hz > 0 and L > 0:
        estimate = np.sqrt(material.E / material.rho) / L
        low, high = FREQUENCY_BAND[0] * estimate * min(t / L, 1.0), FREQUENCY_BAND[1] * estimate
        if not low <= first_elastic_hz <= high:
            out.append(f"first elastic frequency {first_elastic_hz:.3g} Hz is far from the wave-speed "
                       f"estimate c/L = {estimate:.3g} Hz of {material.name} over {L:.3g} m: check the "
                       f"mesh and material units ({_MM} for a mesh in mm with E in MPa, rho in t/mm^3)")
    return out


def solid_unit_systems(mass: float, volume: float, moduli=(), densities=()) -> list[str]:
    """The unit systems (sidprep.fe.material.UNIT_SYSTEMS) in which a model's numbers are those of a solid.

    Parameters
    ----------
    mass : total mass in the model's own mass unit (0: unknown)
    volume : volume of its elements in its own length unit cubed (0: unknown)
    moduli, densities : Young's moduli and densities of its materials in its own units

    Returns
    -------
    list of the names whose SI values of the mean density, the densities and the moduli lie in
    MEAN_DENSITY_RANGE_KG_M3, DENSITY_RANGE_KG_M3 and MODULUS_RANGE_PA.
    """
    def within(values, bounds) -> bool:
        return all(bounds[0] <= v <= bounds[1] for v in values)

    def fits(u: UnitSystem) -> bool:
        mean = [mass * u.mass_to_kg / (volume * u.length_to_m ** 3)] if mass > 0 and volume > 0 else []
        return (within(mean, MEAN_DENSITY_RANGE_KG_M3)
                and within([d * u.density_to_kg_m3 for d in densities], DENSITY_RANGE_KG_M3)
                and within([e * u.stress_to_pa for e in moduli], MODULUS_RANGE_PA))
    return [name for name, u in UNIT_SYSTEMS.items() if fits(u)]


def check_model_units(source: str, units: UnitSystem, mass: float, volume: float, length: float,
                      moduli=(), densities=()) -> None:
    """InputError (one line naming --units and the system the numbers fit) unless the model's own
    numbers are those of a solid in ``units``.

    source : the file named in the message; mass, volume, moduli, densities : as in
    :func:`solid_unit_systems`, in the file's own units; length : the largest bounding-box edge
    in the file's length unit.
    """
    fitting = solid_unit_systems(mass, volume, moduli, densities)
    if units.name in fitting:
        return
    said = [f"a {mass * units.mass_to_kg:.3g} kg body {length * units.length_to_m:.3g} m long"] if mass > 0 else []
    if mass > 0 and volume > 0:
        said.append(f"mean density {mass * units.mass_to_kg / (volume * units.length_to_m ** 3):.3g} kg/m^3")
    said += [f"E = {e * units.stress_to_pa:.3g} Pa" for e in moduli[:1]]
    said += [f"rho = {d * units.density_to_kg_m3:.3g} kg/m^3" for d in densities[:1]]
    fix = (f"its numbers fit --units {fitting[0]}: run with --units {fitting[0]}" if fitting else
           f"its numbers fit none of {', '.join(UNIT_SYSTEMS)}: give K, M, coordinates and materials in one of "
           "them (si: m, kg, N, Pa; mm-t-s: mm, t, N, MPa) with --units")
    raise InputError(f"{source}: read with --units {units.name} it is {', '.join(said)}: not a solid part; {fix}")


def check_imported_units(mesh, M_file, units: UnitSystem, path) -> None:
    """:func:`check_model_units` for K and M imported onto ``mesh`` (FEMesh in metres; an ``.inp``
    MODEL also gives its materials' E and rho, a Nastran deck those of its MAT1 cards; shell and
    beam models have no element volume, so only these are checked): M_file (3n', 3n') the mass in
    the file's unit."""
    from sidprep.fe.matrices.deck_sections import deck_materials  # deferred: the decks' readers, imported K, M only
    from sidprep.fe.matrices.nastran_deck import is_nastran, nastran_materials  # deferred: as above (meshio)

    n = 3 * mesh.n_nodes
    mass = float(M_file[:n, :n].sum()) / 3.0
    volume = float(np.abs(cell_volumes(mesh.points, mesh.cells)).sum()) / units.length_to_m ** 3 if len(mesh.cells) else 0.0
    length = float(np.ptp(mesh.points, axis=0).max()) / units.length_to_m
    materials = deck_materials(mesh.source).values() if str(mesh.source).lower().endswith(".inp") else ()
    moduli, densities = [m.E for m in materials if m.E is not None], [m.rho for m in materials if m.rho is not None]
    if is_nastran(mesh.source) and Path(mesh.source).is_file():
        moduli, densities = nastran_materials(mesh.source)
    check_model_units(f"{path} with MODEL {mesh.source}", units, mass, volume, length, moduli, densities)
