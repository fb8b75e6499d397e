"""Materials and unit systems: SI conversion and rejection of bad input."""

import math

import pytest

from sidprep.errors import InputError
from sidprep.fe.material import BUILTIN, Material, material_from_options, unit_system


def test_mm_t_s_input_equals_si_input():
    si = material_from_options(E=210e9, nu=0.3, rho=7850.0, units="si")
    mm = material_from_options(E=210000.0, nu=0.3, rho=7.85e-9, units="mm-t-s")
    assert math.isclose(si.E, mm.E, rel_tol=1e-15) and math.isclose(si.rho, mm.rho, rel_tol=1e-12)


def test_unit_system_factors_are_consistent():
    # force = mass * length / time^2 and stress = force / length^2 must hold in every system
    for name in ("si", "mm-t-s"):
        us = unit_system(name)
        assert math.isclose(us.force_to_n, us.mass_to_kg * us.length_to_m, rel_tol=1e-12)
        assert math.isclose(us.stress_to_pa, us.force_to_n / us.length_to_m**2, rel_tol=1e-12)
        assert math.isclose(us.density_to_kg_m3, us.mass_to_kg / us.length_to_m**3, rel_tol=1e-12)


def test_builtin_lookup_and_lame_parameters():
    steel = material_from_options(name="Steel")
    assert steel == BUILTIN["steel"]
    lam, mu = steel.lame
    # E = mu (3 lam + 2 mu) / (lam + mu), nu = lam / (2 (lam + mu))
    assert math.isclose(mu * (3 * lam + 2 * mu) / (lam + mu), steel.E, rel_tol=1e-14)
    assert math.isclose(lam / (2 * (lam + mu)), steel.nu, rel_tol=1e-14)
    assert material_from_options(name="aluminum").name == "aluminium"


@pytest.mark.parametrize("kwargs, fragment", [
    ({}, "no material"),
    ({"E": 210e9, "nu": 0.3}, "--rho missing"),
    ({"name": "steel", "E": 1e9}, "both given"),
    ({"name": "unobtainium"}, "unknown material"),
    ({"E": 210e9, "nu": 0.5, "rho": 7850}, "nu = 0.5"),
    ({"E": 210e9, "nu": -1.2, "rho": 7850}, "nu = -1.2"),
    ({"E": -1.0, "nu": 0.3, "rho": 7850}, "E = -1"),
    ({"E": 210e9, "nu": 0.3, "rho": 0.0}, "rho = 0"),
    ({"E": float("nan"), "nu": 0.3, "rho": 7850}, "finite"),
    ({"E": 210000.0, "nu": 0.3, "rho": 7850.0}, "check --units"),  # MPa given as SI
    ({"E": 210e9, "nu": 0.3, "rho": 7850, "units": "inch"}, "unknown unit system"),
])
def test_bad_material_input_is_one_line_input_error(kwargs, fragment):
    with pytest.raises(InputError) as exc:
        material_from_options(**kwargs)
    assert fragment in str(exc.value) and "\n" not in str(exc.value)


def test_material_is_frozen():
    with pytest.raises(AttributeError):
        Material(1e9, 0.3, 1000.0).E = 2.0
