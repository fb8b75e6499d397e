#!/usr/bin/env python3
"""The sliding mass of Hartweg and Heckmann 2012 section 2.3: its x and z accelerations (the seed: peaks near
20 m/s^2, a periodic x acceleration as it slides to and fro in the sag), the period of the
sliding, the energy balance; writes analysis.png.

    python analyse.py              # runs scene.toml (60 s, ~2 s CPU)
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sidprep.solver.scene import load_scene, simulate

HERE = Path(__file__).resolve().parent


def crossings(t, x, level):
    """Times at which x(t) crosses ``level`` upwards (linear interpolation)."""
    i = np.flatnonzero((x[:-1] < level) & (x[1:] >= level))
    return t[i] + (level - x[i]) / (x[i + 1] - x[i]) * (t[i + 1] - t[i])


def main(t_end=None, plot=True, folder=HERE) -> dict:
    r = simulate(load_scene(Path(folder) / "scene.toml"), t_end=t_end)
    acc = r.bodies["mass"].acceleration[:, :3]
    x = r.bodies["mass"].position[:, 0]
    up = crossings(r.t, x, 7.5)                      # passing midspan towards +x
    e = r.energy
    scale = max(np.ptp(e["kinetic"]), np.ptp(e["gravity"]), np.ptp(e["strain"]))
    out = {"peak_az": float(np.abs(acc[:, 2]).max()), "peak_ax": float(np.abs(acc[:, 0]).max()),
           "x_range_m": (float(x.min()), float(x.max())),
           "sliding_period_s": float(np.median(np.diff(up))) if up.size > 1 else float("nan"),
           "energy_drift": float(np.max(np.abs(e["total"] - e["total"][0])) / scale),
           "dissipated_J": float(e["dissipated"][-1]), "cpu_s": r.stats.cpu_integration}
    if plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(3, 1, figsize=(8, 7), sharex=True)
        ax[0].plot(r.t, acc[:, 0], lw=0.6)
        ax[0].set_ylabel("a_x [m/s^2]")
        ax[1].plot(r.t, acc[:, 2], lw=0.6)
        ax[1].set_ylabel("a_z [m/s^2]")
        ax[2].plot(r.t, x, lw=0.8)
        ax[2].set_ylabel("mass x [m]")
        ax[2].set_xlabel("time [s]")
        fig.tight_layout()
        fig.savefig(HERE / "analysis.png", dpi=100)
    return out


if __name__ == "__main__":
    for key, value in main().items():
        print(f"{key:18s} {value}")
