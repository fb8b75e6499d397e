#!/usr/bin/env python3
"""The piston rod's stress in the engine (README.md, "Stress"): hot spot, the axial stress in the
shank at the firing peak against F / A, the in-plane bending there, and stress.png.

Reads the results of `sidprep simulate scene.toml` (engine.results.h5) and the rod's SID, which
must carry modal stresses (the scene's make line reduces with --stress).

    sidprep simulate scene.toml          # engine.results.h5
    python stress.py                     # the numbers below + stress.png
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

import sidprep

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from analyse import rod_axial  # noqa: E402  (this folder's script)

#: the shank's I-section (data/meshes/make_piston_rod.py defaults), m: depth in the plane of motion
#: (y), flange thickness (y), flange width (z), web thickness (z)
DEPTH, FLANGE_T, FLANGE_B, WEB_T = 0.021, 0.0035, 0.022, 0.003
#: the section where the shank stress is read: x (m, rod frame) and the half-width of the slice
MID_SHANK_X, SLICE = 0.21, 0.02
#: the crank angle of one engine cycle (4-stroke), rad
CYCLE = 4 * np.pi


def shank_section() -> tuple[float, float]:
    """(A m^2, I m^4 for in-plane bending about z) of the shank's I-section."""
    area = 2 * FLANGE_T * FLANGE_B + (DEPTH - 2 * FLANGE_T) * WEB_T
    inertia = (FLANGE_B * DEPTH ** 3 - (FLANGE_B - WEB_T) * (DEPTH - 2 * FLANGE_T) ** 3) / 12
    return area, inertia


def flange_faces(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Masks of the stress nodes on the outer flange faces y = +-DEPTH/2 at mid-shank."""
    near = np.abs(points[:, 0] - MID_SHANK_X) < SLICE
    return near & np.isclose(points[:, 1], DEPTH / 2), near & np.isclose(points[:, 1], -DEPTH / 2)


def main(folder=HERE, plot=True) -> dict:
    """The README's numbers (a dict) from folder/engine.results.h5 and folder/piston_rod.sid.h5."""
    folder = Path(folder)
    results = folder / "engine.results.h5"
    rec = sidprep.recover_stress(results, "rod", hot_spots=3)
    run = sidprep.solver.results.read_results(results).result
    stress = sidprep.read_sid(folder / "piston_rod.sid.h5").stress
    _, compression = rod_axial(run)
    peak = int(np.argmax(compression))
    area, inertia = shank_section()
    top, bottom = flange_faces(stress.points)
    sxx = stress.at(run.bodies["rod"].q)[:, :, 0]                    # (nt, ns) sigma_xx, Pa
    axial = 0.5 * (sxx[:, top].mean(axis=1) + sxx[:, bottom].mean(axis=1))
    bending = 0.5 * (sxx[:, top].mean(axis=1) - sxx[:, bottom].mean(axis=1))
    spot = rec.hot_spots[0]
    out = {
        "t_end": float(run.t[-1]),
        "hot_spot_node": spot.node,
        "hot_spot_position_mm": [round(1e3 * float(v), 2) for v in spot.position],
        "hot_spot_time": spot.time,
        "hot_spot_von_mises_MPa": spot.von_mises / 1e6,
        "firing_peak_time": float(run.t[peak]),
        "firing_peak_compression_N": float(compression[peak]),
        "shank_axial_stress_MPa": float(axial[peak] / 1e6),
        "F_over_A_MPa": float(-compression[peak] / area / 1e6),
        "shank_bending_stress_MPa": float(bending[peak] / 1e6),
        "shank_bending_moment_Nm": float(-bending[peak] * inertia / (DEPTH / 2)),
        "largest_shank_bending_MPa": float(np.max(np.abs(bending)) / 1e6),
    }
    if plot:
        write_plot(run, rec, axial, compression / area, folder / "stress.png")
    return out


def write_plot(run, rec, axial, f_over_a, path):
    """stress.png: the last full engine cycle over the crank angle, and the rod coloured by its
    largest von Mises stress of the run with the hot spot."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    angle = run.joints["crank_joint"].coordinate
    turned = np.abs(angle - angle[0])
    cycles = turned[-1] // CYCLE                                          # whole cycles run (short runs: all)
    last = (turned >= (cycles - 1) * CYCLE) & (turned < cycles * CYCLE) if cycles else np.ones(turned.size, bool)
    deg = np.degrees(turned[last] - turned[last][0])
    h = rec.hot_spot_histories[0]
    fig, ax = plt.subplots(2, 1, figsize=(8, 7.5))
    ax[0].plot(deg, h.von_mises[last] / 1e6, lw=0.9, label=f"von Mises at the hot spot (node {h.node})")
    ax[0].plot(deg, axial[last] / 1e6, lw=0.9, label="sigma_xx mid-shank (mean of the flange faces)")
    ax[0].plot(deg, -f_over_a[last] / 1e6, "--", lw=0.9, label="-F / A (joint forces, shank section)")
    ax[0].set_xlabel("crank angle from the start of the last full cycle (720 deg) [deg]")
    ax[0].set_ylabel("stress [MPa]")
    ax[0].legend(fontsize=8)
    ax[0].grid(alpha=0.3)
    order = np.argsort(rec.points[:, 2])                                # draw the top face last
    sc = ax[1].scatter(rec.points[order, 0] * 1e3, rec.points[order, 1] * 1e3, c=rec.envelope[order] / 1e6,
                       s=4, cmap="inferno")
    for i, s in enumerate(rec.hot_spots):
        ax[1].plot(s.position[0] * 1e3, s.position[1] * 1e3, "o", mfc="none", mec="c", ms=10)
        ax[1].annotate(f"{i + 1}: {s.von_mises / 1e6:.0f} MPa", (s.position[0] * 1e3, s.position[1] * 1e3),
                       xytext=(6, 6), textcoords="offset points", color="c", fontsize=8)
    ax[1].set_aspect("equal")
    ax[1].set_xlabel("x [mm] (rod frame)")
    ax[1].set_ylabel("y [mm]")
    ax[1].set_title("largest von Mises stress of the run at every surface node", fontsize=9)
    fig.colorbar(sc, ax=ax[1], label="MPa", orientation="horizontal", fraction=0.05, pad=0.25)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


if __name__ == "__main__":
    argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter).parse_args()
    for key, value in main().items():
        print(f"{key:28s} {value}")
