#!/usr/bin/env python3
"""Surfaces of the engine's rigid bodies for the animation (body-frame metres):
crank.obj (flywheel disc behind the rod, crank pin) and piston.obj (crown and skirt around the pin).

    python make_obj.py      # writes crank.obj and piston.obj (committed)
"""

import numpy as np
import trimesh


def cylinder(radius, z0, z1, centre=(0.0, 0.0), sections=48):
    """A cylinder along z from z0 to z1 (m) through (x, y) = centre."""
    c = trimesh.creation.cylinder(radius=radius, height=z1 - z0, sections=sections)
    c.apply_translation([centre[0], centre[1], 0.5 * (z0 + z1)])
    return c


def crank() -> trimesh.Trimesh:
    """Flywheel (radius 0.16 m, 30 mm thick, behind the rod) and the pin at (0, 0.1) (radius 30 mm)."""
    return trimesh.util.concatenate([cylinder(0.16, -0.06, -0.03), cylinder(0.03, -0.03, 0.013, (0.0, 0.1))])


def piston() -> trimesh.Trimesh:
    """Bore 0.1 m, 80 mm tall along y, pin 10 mm below the middle."""
    p = cylinder(0.05, -0.03, 0.05)
    p.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1.0, 0.0, 0.0]))  # z -> y
    return p


if __name__ == "__main__":
    crank().export("crank.obj")
    piston().export("piston.obj")
