"""Flap angle and modal amplitudes vs rotor speed; writes rotor.png.

Run after `sidprep simulate scene.toml --csv` (and scene_no_stiffening.toml --csv)."""

import csv
import sys

import numpy as np


def read(path):
    with open(path) as f:
        rows = list(csv.reader(f))
    head = [h.split(" [")[0] for h in rows[0]]
    data = np.array(rows[1:], dtype=float)
    return {h: data[:, i] for i, h in enumerate(head)}


def window_means(sig, centres, half=0.25):
    """Mean of every signal over [c - half, c + half]."""
    t = sig["time"]
    return {k: np.array([v[(t >= c - half) & (t <= c + half)].mean() for c in centres]) for k, v in sig.items()}


def main(files=("helicopter_rotor.csv", "scene_no_stiffening.csv")):
    centres = np.array([0.5, 2.0, 3.0, 4.0, 5.0, 7.5, 9.75])
    for path in files:
        try:
            m = window_means(read(path), centres)
        except FileNotFoundError:
            continue
        print(path)
        print("   t [s]  Omega [rad/s]  flap [rad]   lag [rad]     q1          q2          q8 (lag 1)")
        for k, c in enumerate(centres):
            print(f"  {c:5.2f}  {m['rotor.rate'][k]:12.3f}  {m['flap.coordinate'][k]:+.5f}  {m['lag.coordinate'][k]:+.6f}"
                  f"  {m['blade.q.1'][k]:+.3e}  {m['blade.q.2'][k]:+.3e}  {m['blade.q.8'][k]:+.3e}")
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, axes = plt.subplots(3, 1, figsize=(7, 7), sharex=True)
        for path in files:
            try:
                s = read(path)
            except FileNotFoundError:
                continue
            lab = path.replace(".csv", "")
            axes[0].plot(s["time"], s["flap.coordinate"], lw=0.8, label=lab)
            axes[1].plot(s["time"], s["blade.q.1"], lw=0.8, label=lab)
            axes[2].plot(s["time"], s["rotor.rate"], lw=0.8, label=lab)
        axes[0].set_ylabel("flap angle [rad]")
        axes[1].set_ylabel("q1 (7.9 Hz flap)")
        axes[2].set_ylabel("rotor speed [rad/s]")
        axes[2].set_xlabel("time [s]")
        axes[0].legend(fontsize=8)
        fig.tight_layout()
        fig.savefig("rotor.png", dpi=100)
    except ImportError:
        pass


if __name__ == "__main__":
    main(*(sys.argv[1:] and [tuple(sys.argv[1:])]))
