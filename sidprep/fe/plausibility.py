"""Unit plausibility: warn when size, mass or first frequency cannot belong to a machine part.

A mesh drawn in millimetres and run as SI is 1000x too large and 1e9x too heavy, yet internally
consistent (its frequencies are those of a 1000x larger part), so every FE check passes. These
rules catch it from the numbers an engineer would look at first (issue 14 item 3).
"""

from __future__ import annotations

import numpy as np

from sidprep.fe.material import Material

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
