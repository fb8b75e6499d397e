"""Isotropic linear-elastic materials and unit systems (SI inside sidprep).

A :class:`Material` always holds SI values (Pa, kg/m^3).  Input given in another unit system
(``--units mm-t-s``: mm, tonne, s, N, MPa, t/mm^3 - the usual Abaqus/Nastran "mm" system) is
converted once, in :func:`material_from_options`.

Built-in materials (nominal room-temperature values; a real part should use its data sheet):

=============  ========  =====  ===========  ==========================================
name           E (GPa)   nu     rho (kg/m3)  source
=============  ========  =====  ===========  ==========================================
steel          210       0.30   7850         EN 1993-1-1 3.2.6 (E, nu); EN 1991-1-1 A (rho)
aluminium      70        0.30   2700         EN 1999-1-1 3.2.5 (wrought alloys)
titanium       113.8     0.342  4430         Ti-6Al-4V, ASM Aerospace Specification Metals data sheet
cast_iron      110       0.26   7200         grey EN-GJL-250, EN 1561 annex (E 103-118 GPa: mid value)
ductile_iron   169       0.275  7100         EN-GJS-400-15, EN 1563 annex
=============  ========  =====  ===========  ==========================================
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from sidprep.errors import InputError

#: admissible Poisson ratio of an isotropic solid (open interval, strict positive definiteness)
NU_RANGE = (-1.0, 0.5)
#: bar wave speed sqrt(E/rho) of real solids lies in this range (m/s); outside it the
#: input almost surely mixes unit systems (e.g. MPa given with --units si)
WAVE_SPEED_RANGE_M_S = (10.0, 3.0e4)


@dataclass(frozen=True)
class Material:
    """Isotropic linear-elastic material in SI units.

    Attributes
    ----------
    E : float
        Young's modulus, Pa.
    nu : float
        Poisson's ratio, -.
    rho : float
        Density, kg/m^3.
    name : str
        Label stored in outputs.
    """

    E: float
    nu: float
    rho: float
    name: str = "user"

    @property
    def lame(self) -> tuple[float, float]:
        """Lame parameters (lambda, mu) in Pa."""
        lam = self.E * self.nu / ((1.0 + self.nu) * (1.0 - 2.0 * self.nu))
        mu = self.E / (2.0 * (1.0 + self.nu))
        return lam, mu

    def as_dict(self) -> dict:
        """JSON-ready description with units."""
        return {"name": self.name, "E_Pa": self.E, "nu": self.nu, "rho_kg_m3": self.rho}


@dataclass(frozen=True)
class UnitSystem:
    """Factors that convert a consistent unit system to SI (value_SI = value * factor)."""

    name: str
    length_to_m: float
    mass_to_kg: float
    stress_to_pa: float
    density_to_kg_m3: float
    force_to_n: float = 1.0


UNIT_SYSTEMS = {
    "si": UnitSystem("si", length_to_m=1.0, mass_to_kg=1.0, stress_to_pa=1.0, density_to_kg_m3=1.0),
    # mm, tonne, s -> force N, stress MPa, density t/mm^3 = 1e3 kg / 1e-9 m^3
    "mm-t-s": UnitSystem("mm-t-s", length_to_m=1e-3, mass_to_kg=1e3, stress_to_pa=1e6,
                         density_to_kg_m3=1e12),
}

BUILTIN = {
    m.name: m
    for m in (
        Material(210e9, 0.30, 7850.0, "steel"),
        Material(70e9, 0.30, 2700.0, "aluminium"),
        Material(113.8e9, 0.342, 4430.0, "titanium"),
        Material(110e9, 0.26, 7200.0, "cast_iron"),
        Material(169e9, 0.275, 7100.0, "ductile_iron"),
    )
}
_ALIASES = {"aluminum": "aluminium", "ti6al4v": "titanium", "grey_cast_iron": "cast_iron",
            "gray_cast_iron": "cast_iron", "nodular_iron": "ductile_iron"}


def unit_system(name: str) -> UnitSystem:
    """The unit system called ``name`` ("si" or "mm-t-s"); InputError otherwise."""
    try:
        return UNIT_SYSTEMS[name.lower()]
    except KeyError:
        raise InputError(f"--units {name}: unknown unit system; use one of {', '.join(UNIT_SYSTEMS)}") from None


def check_material(m: Material) -> Material:
    """Return ``m`` if it is a physical isotropic material, else raise InputError."""
    for key, value in (("E", m.E), ("nu", m.nu), ("rho", m.rho)):
        if not math.isfinite(value):
            raise InputError(f"material {m.name}: {key} = {value} is not a finite number; give a real value")
    if m.E <= 0.0:
        raise InputError(f"material {m.name}: E = {m.E:g} Pa must be > 0")
    if m.rho <= 0.0:
        raise InputError(f"material {m.name}: rho = {m.rho:g} kg/m^3 must be > 0")
    if not NU_RANGE[0] < m.nu < NU_RANGE[1]:
        raise InputError(f"material {m.name}: nu = {m.nu:g} must lie in ({NU_RANGE[0]:g}, {NU_RANGE[1]:g}); "
                         "nu = 0.5 (incompressible) is not supported by displacement elements")
    c = math.sqrt(m.E / m.rho)
    lo, hi = WAVE_SPEED_RANGE_M_S
    if not lo <= c <= hi:
        raise InputError(f"material {m.name}: E = {m.E:g} Pa and rho = {m.rho:g} kg/m^3 give a wave speed "
                         f"sqrt(E/rho) = {c:.3g} m/s, outside the {lo:g}-{hi:g} m/s of real solids; "
                         "check --units (si: Pa, kg/m^3; mm-t-s: MPa, t/mm^3)")
    return m


def builtin_material(name: str) -> Material:
    """A built-in material by (case-insensitive) name, see the module table."""
    key = name.strip().lower().replace("-", "_").replace(" ", "_")
    key = _ALIASES.get(key, key)
    if key not in BUILTIN:
        raise InputError(f"--material {name}: unknown material; use one of {', '.join(BUILTIN)} "
                         "or give --E --nu --rho")
    return BUILTIN[key]


def material_from_options(E: float | None = None, nu: float | None = None, rho: float | None = None,
                          name: str | None = None, units: str = "si") -> Material:
    """The material selected by command-line style options, in SI.

    Either ``name`` (a built-in material) or all of ``E``, ``nu``, ``rho`` (in ``units``) must be
    given, not both and not neither: a silently assumed default material would give a wrong mass
    without any warning, so sidprep (like Abaqus and CalculiX) requires one.

    Parameters
    ----------
    E, nu, rho : float or None
        Young's modulus (stress unit of ``units``), Poisson's ratio, density (density unit).
    name : str or None
        Built-in material name, or the label of a user material given by E, nu, rho.
    units : str
        "si" or "mm-t-s".
    """
    us = unit_system(units)
    given = {k: v for k, v in (("E", E), ("nu", nu), ("rho", rho)) if v is not None}
    if not given:
        if name is None:
            raise InputError("no material given; use --material NAME "
                             f"({', '.join(BUILTIN)}) or --E --nu --rho")
        return builtin_material(name)
    if name is not None and name.strip().lower().replace("-", "_") in set(BUILTIN) | set(_ALIASES):
        raise InputError(f"--material {name} and --{'/--'.join(given)} both given; "
                         "use either a built-in material or --E --nu --rho")
    missing = [k for k in ("E", "nu", "rho") if k not in given]
    if missing:
        raise InputError(f"material: --{' and --'.join(missing)} missing; give all of --E --nu --rho "
                         "(or --material NAME)")
    return check_material(Material(E=float(E) * us.stress_to_pa, nu=float(nu),
                                   rho=float(rho) * us.density_to_kg_m3, name=name or "user"))
