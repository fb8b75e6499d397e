#!/usr/bin/env python3
"""The engine's simplified gas force over the crank angle (a four-stroke cycle, period 4 pi).

Ideal Otto cycle on the slider-crank kinematics of the scene (crank radius ``r``, rod length
``l`` between the eye centres, bore ``bore``, compression ratio ``eps``): intake and exhaust at
ambient pressure, polytropic compression ``p V^n = const`` from ``p0`` at bottom dead centre,
isochoric combustion at firing top dead centre (pressure ratio ``lam``, spread over the first
``burn`` rad after TDC), polytropic expansion. Gauge pressure times the bore area is the force
pushing the piston towards the crank.

Crank angle ``phi`` = the crank joint's coordinate, 0 = firing TDC: 0 .. pi expansion, pi .. 2 pi
exhaust, 2 pi .. 3 pi intake, 3 pi .. 4 pi compression.

    python gas_force.py        # prints the scene's [forces.gas.table] (x in rad, y in N)
"""

from __future__ import annotations

import numpy as np

#: engine geometry and cycle (SI): crank radius, rod length (eye centres), bore, compression
#: ratio, polytropic exponent, ambient pressure, combustion pressure ratio, burn angle
R, L, BORE, EPS, N_POLY, P0, LAM, BURN = 0.1, 0.42, 0.1, 9.0, 1.3, 1.0e5, 2.0, np.radians(10.0)


def piston_height(phi, r=R, l=L):
    """Piston pin above the crank axis (m) of the rigid slider crank, phi in rad."""
    return r * np.cos(phi) + np.sqrt(l**2 - (r * np.sin(phi)) ** 2)


def cylinder_volume(phi, r=R, l=L, bore=BORE, eps=EPS):
    """Gas volume (m^3): the clearance volume plus the swept volume above the piston."""
    area = np.pi * bore**2 / 4
    swept = area * 2 * r
    return swept / (eps - 1) + area * (piston_height(0.0, r, l) - piston_height(phi, r, l))


def gas_force(phi):
    """Gauge pressure times bore area (N, >= 0), phi in rad (any value; period 4 pi)."""
    phi = np.mod(phi, 4 * np.pi)
    v, v_bdc, v_tdc = cylinder_volume(phi), cylinder_volume(np.pi), cylinder_volume(0.0)
    p_compression = P0 * (v_bdc / v) ** N_POLY
    p_fired = LAM * P0 * (v_bdc / v_tdc) ** N_POLY * (v_tdc / v) ** N_POLY
    burned = np.clip(phi / BURN, 0.0, 1.0)
    p = np.where(phi < np.pi, p_compression + burned * (p_fired - p_compression),   # combustion, expansion
                 np.where(phi >= 3 * np.pi, p_compression, P0))                     # compression; gas exchange
    return (p - P0) * np.pi * BORE**2 / 4


def table(points_per_stroke: int = 36):
    """(x, y): crank angles (rad, 0 .. 4 pi) and forces (N), 5 deg steps, 1 deg around firing TDC."""
    coarse = np.linspace(0.0, 4 * np.pi, 4 * points_per_stroke + 1)
    fine = np.radians(np.arange(-30.0, 31.0, 1.0)) % (4 * np.pi)
    x = np.unique(np.concatenate([coarse, fine, [BURN]]))
    return x, gas_force(x)


def toml_lines(x, y, per_line: int = 10) -> str:
    """The [forces.gas.table] of the scene."""
    def array(a):
        rows = [", ".join(f"{v:.6g}" for v in a[i:i + per_line]) for i in range(0, len(a), per_line)]
        return "[\n    " + ",\n    ".join(rows) + ",\n]"
    return f"[forces.gas.table]\nperiod = {4 * np.pi!r}\nx = {array(x)}\ny = {array(y)}\n"


if __name__ == "__main__":
    print(toml_lines(*table()), end="")
