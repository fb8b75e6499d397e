#!/usr/bin/env python3
"""The robotic portal's numbers (README.md): beam deformation, the positioning error of robot r1's
tool point, the static check at the end of a dwell against the clamped-clamped beam's closed
form, model size and CPU; writes portal.png.

    python analyse.py              # runs scene.toml (24 s, ~3 s CPU)
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.interpolate import PPoly

from sidprep.solver.scene import load_scene, simulate

HERE = Path(__file__).resolve().parent
#: steel, the scene's box girder (make_scene.py) and robot mass
E, RHO, A, IY, L, G, MASS = 2.1e11, 7850.0, 0.07, 1.6e-2, 30.0, 9.81, 1500.0


def clamped_deflection(x, a, force):
    """Deflection (m, downward positive) at x of a clamped-clamped beam under a point force at a
    (Roark: the influence function of the fixed-fixed beam), x, a in m, force in N."""
    x, a = np.minimum(x, a), np.maximum(x, a)     # Maxwell: symmetric in x and a
    b = L - a
    return force * b**2 * x**2 * (3 * a * L - 3 * a * x - b * x) / (6 * E * IY * L**3)


def self_weight_deflection(x):
    """Deflection (m) of the clamped-clamped beam under its own weight: mu g x^2 (L - x)^2 / 24 EI."""
    return RHO * A * G * x**2 * (L - x) ** 2 / (24 * E * IY)


def main(t_end=None, plot=True, folder=HERE) -> dict:
    scene = load_scene(Path(folder) / "scene.toml")
    r = simulate(scene, t_end=t_end)
    bodies = {b.name: b for b in scene.system.bodies}
    deformation = {}
    for name in ("runway_a", "runway_b", "cross"):
        path = bodies[name].sid.paths["axis"]
        w = np.einsum("scq,tq->tsc", path.phi, r.bodies[name].q)           # (nt, ns, 3) axis displacement
        deformation[name] = float(np.linalg.norm(w, axis=2).max())
    markers = {m.name: m for b in scene.system.bodies for m in b.markers}
    motion = markers["r1"].motion
    s1 = PPoly(motion.c, motion.x)(r.t)
    guide = np.stack([s1, np.zeros_like(s1), np.full_like(s1, 7.0)], axis=1)   # on the undeformed axis
    tool = bodies["r1_carriage"].position0 + markers["r1_tool"].position       # as placed in the scene
    error = r.markers["r1_tool"] - (guide + tool - guide[0])
    # static check: end of the first dwell (r1 at 20 m, r2 at 12 m on runway_a, at rest 1.9 s)
    k = int(np.argmin(np.abs(r.t - 8.9)))
    s2 = PPoly(markers["r2"].motion.c, markers["r2"].motion.x)(r.t[k])

    def static(x):  # the closed-form deflection (m, z up) of runway_a under both robots at rest
        return -(clamped_deflection(x, s1[k], MASS * G) + clamped_deflection(x, s2, MASS * G)
                 + self_weight_deflection(x))

    slope = (static(s1[k] + 1e-3) - static(s1[k] - 1e-3)) / 2e-3
    lever = 7.0 - tool[2]                                   # the tool below the guide point, m
    out = {"beam_deformation_mm": {k_: v * 1e3 for k_, v in deformation.items()},
           "r1_tool_error_mm_max": float(np.linalg.norm(error, axis=1).max() * 1e3),
           "r1_tool_error_x_mm_max": float(np.abs(error[:, 0]).max() * 1e3),
           "r1_tool_error_at_dwell_mm": [float(v * 1e3) for v in error[k]],
           "r1_dwell_deflection_mm": float((r.markers["r1"][k, 2] - 7.0) * 1e3),
           "r1_dwell_closed_form_mm": float(static(s1[k]) * 1e3),
           "r1_tool_x_closed_form_mm": float(lever * slope * 1e3),
           "coordinates": r.stats.n_coordinates, "constraints": r.stats.n_constraints,
           "states": 2 * (r.stats.n_coordinates - r.stats.n_constraints),
           "cpu_s": r.stats.cpu_integration, "steps": r.stats.steps}
    if plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
        for name in ("r1", "r2", "r3", "r4"):
            ax[0].plot(r.t, r.markers[name][:, 0], label=name)
        ax[0].set_ylabel("robot position x [m]")
        ax[0].legend(fontsize=8, ncol=4)
        for c, label in enumerate("xyz"):
            ax[1].plot(r.t, error[:, c] * 1e3, label=label)
        ax[1].set_ylabel("r1 tool point error [mm]")
        ax[1].legend(fontsize=8, ncol=3)
        ax[1].set_xlabel("time [s]")
        fig.tight_layout()
        fig.savefig(HERE / "portal.png", dpi=100)
    return out


if __name__ == "__main__":
    for key, value in main().items():
        print(f"{key:30s} {value}")
