"""Bending amplitude at mid-span vs the static amplification 1/(1 - F/F_cr); writes buckling.png.

Run after `python -m sidprep.cli.main simulate scene.toml --csv` (and scene_no_stiffening.toml)."""

import csv
import math
import sys

import numpy as np

E, RHO, L, B = 2.1e11, 7850.0, 1.69, 0.0229          # steel, m
I = B ** 4 / 12
F_CR = math.pi ** 2 * E * I / L ** 2                  # Euler load, N (16.63 kN)
F_END, T_END = 16630.5, 10.0                          # the force table: F = F_END t / T_END
M0 = 1.0                                              # torque amplitude, N m
F1 = math.pi / (2 * L ** 2) * math.sqrt(E * I / (RHO * B * B))   # 18.80 Hz
#: mid-span deflection of a simply supported beam under an end moment M0 (w = M0 L^2 / 16 EI),
#: times the dynamic factor of the first mode at 1 Hz
A0 = M0 * L ** 2 / (16 * E * I) / (1 - (1.0 / F1) ** 2)


def read(path):
    with open(path) as f:
        rows = list(csv.reader(f))
    head, data = [h.split(" [")[0] for h in rows[0]], np.array(rows[1:], dtype=float)
    return {h: data[:, i] for i, h in enumerate(head)}


def amplitudes(sig, centres):
    """Half peak-to-peak of mid.position.z over the 1 s period centred at each time."""
    t, z = sig["time"], sig["mid.position.z"]
    return np.array([0.5 * np.ptp(z[(t >= c - 0.5) & (t < c + 0.5)]) for c in centres])


def main(files=("beam_buckling.csv", "scene_no_stiffening.csv")):
    centres = np.arange(1.5, 9.01, 1.0)
    ratio = F_END * centres / T_END / F_CR
    ref = A0 / (1 - ratio)
    out = {}
    for path in files:
        out[path] = amplitudes(read(path), centres)
    print(f"F_cr = {F_CR:.1f} N, f1 = {F1:.3f} Hz, A0 = {A0 * 1e6:.4f} um")
    print("t [s]  F/F_cr  reference [um]  " + "  ".join(f"{p} [um]" for p in files))
    for k, c in enumerate(centres):
        print(f"{c:5.1f}  {ratio[k]:6.3f}  {ref[k] * 1e6:14.4f}  " +
              "  ".join(f"{out[p][k] * 1e6:12.4f}" for p in files))
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(figsize=(7, 4))
        for p in files:
            s = read(p)
            ax.plot(s["time"], s["mid.position.z"] * 1e6, lw=0.7, label=p.replace(".csv", ""))
        ax.plot(centres, ref * 1e6, "k--", label="A0 / (1 - F/F_cr)")
        ax.plot(centres, -ref * 1e6, "k--")
        ax.set_xlabel("time [s]  (F = 1.663 kN/s * t)")
        ax.set_ylabel("mid-span deflection z [um]")
        ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig("buckling.png", dpi=110)
    except ImportError:
        pass
    return centres, ratio, ref, out


if __name__ == "__main__":
    main(*(sys.argv[1:2] and [tuple(sys.argv[1:])]))
