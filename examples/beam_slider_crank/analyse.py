"""Slider motion vs the rigid slider-crank formula, elastic coordinates; writes slider_crank.png.

Run after `sidprep simulate scene.toml --csv`."""

import csv
import sys

import numpy as np

R, L = 1.0, 2.0                      # crank and conrod length, m
OMEGA, THETA0 = 1.5, np.pi / 2       # crank speed rad/s, initial angle rad
X0 = np.sqrt(L ** 2 - R ** 2)        # slider position at t = 0 (the prismatic joint's origin), m


def read(path):
    with open(path) as f:
        rows = list(csv.reader(f))
    head = [h.split(" [")[0] for h in rows[0]]
    data = np.array(rows[1:], dtype=float)
    return {h: data[:, i] for i, h in enumerate(head)}


def rigid_slider(t):
    """Slider displacement from its t = 0 position for rigid links, m."""
    th = THETA0 + OMEGA * t
    return R * np.cos(th) + np.sqrt(L ** 2 - (R * np.sin(th)) ** 2) - X0


def main(path="beam_slider_crank.csv"):
    s = read(path)
    t, x = s["time"], s["slider_joint.coordinate"]
    dev = x - rigid_slider(t)
    print(f"slider stroke {np.ptp(x):.4f} m (rigid {np.ptp(rigid_slider(t)):.4f} m); "
          f"max |x - x_rigid| = {np.abs(dev).max() * 1e3:.2f} mm")
    print(f"max |q| crank {np.abs(s['crank.q.1']).max():.3e}, conrod {np.abs(s['conrod.q.1']).max():.3e}")
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, axes = plt.subplots(3, 1, figsize=(7, 6), sharex=True)
        axes[0].plot(t, x, label="simulated")
        axes[0].plot(t, rigid_slider(t), "k--", lw=0.8, label="rigid links")
        axes[0].set_ylabel("slider [m]")
        axes[0].legend(fontsize=8)
        axes[1].plot(t, dev * 1e3)
        axes[1].set_ylabel("x - x_rigid [mm]")
        axes[2].plot(t, s["crank.q.1"], label="crank q1 (3.9 Hz)")
        axes[2].plot(t, s["conrod.q.1"], label="conrod q1 (1.0 Hz)")
        axes[2].set_ylabel("modal coordinate")
        axes[2].set_xlabel("time [s]")
        axes[2].legend(fontsize=8)
        fig.tight_layout()
        fig.savefig("slider_crank.png", dpi=100)
    except ImportError:
        pass
    return dev


if __name__ == "__main__":
    main(*sys.argv[1:])
