#!/usr/bin/env python3
"""Midspan deflection of the beam under the moving force against the closed-form modal series
(Fryba, "Vibration of solids and structures under moving loads", 1972, ch. 1: the undamped
simply supported Euler-Bernoulli beam); writes analysis.png.

    sidprep simulate scene.toml --csv     # moving_force.csv
    python analyse.py                     # the README's numbers

The series: mode j, phi_j = sqrt(2 / (mu L)) sin(j pi x / L), omega_j = (j pi / L)^2 sqrt(EI / mu);
while the force -P is on the beam (t <= L / c) eta_j = -P phi_j-amplitude / (omega_j^2 - Omega_j^2)
(sin(Omega_j t) - Omega_j / omega_j sin(omega_j t)) with Omega_j = j pi c / L, afterwards free
vibration from the state at the exit.
"""

from __future__ import annotations

import csv
import sys

import numpy as np

#: the scene's beam and load (SI)
L, B, E, RHO, P, SPEED = 15.0, 0.1, 2.1e11, 7850.0, 981.0, 10.0
EI, MU = E * B**4 / 12, RHO * B * B


def midspan_series(t, speed=SPEED, modes=201):
    """Closed-form midspan deflection w(L/2, t), m (module doc), over ``modes`` modes."""
    t = np.asarray(t, float)
    exit_time = L / speed
    w = np.zeros_like(t)
    for j in range(1, modes + 1):
        omega = (j * np.pi / L) ** 2 * np.sqrt(EI / MU)
        forced = j * np.pi * speed / L
        amp = -P * np.sqrt(2 / (MU * L)) / (omega**2 - forced**2)

        def eta(x):
            return amp * (np.sin(forced * x) - forced / omega * np.sin(omega * x))

        def eta_dot(x):
            return amp * forced * (np.cos(forced * x) - np.cos(omega * x))

        te = exit_time
        after = eta(te) * np.cos(omega * (t - te)) + eta_dot(te) / omega * np.sin(omega * (t - te))
        w += np.where(t <= te, eta(t), after) * np.sqrt(2 / (MU * L)) * np.sin(j * np.pi / 2)
    return w


def read(path):
    with open(path) as f:
        rows = list(csv.reader(f))
    head, data = [h.split(" [")[0] for h in rows[0]], np.array(rows[1:], dtype=float)
    return {h: data[:, i] for i, h in enumerate(head)}


def main(path="moving_force.csv", plot=True) -> dict:
    s = read(path)
    t, z = s["time"], s["midspan.position.z"]
    ref = midspan_series(t)
    on = t <= L / SPEED
    out = {"peak_m": float(np.abs(z).max()), "peak_closed_form_m": float(np.abs(ref).max()),
           "static_PL3_48EI_m": P * L**3 / (48 * EI),
           "error_on_beam": float(np.abs(z - ref)[on].max() / np.abs(ref).max()),
           "error_after_exit": float(np.abs(z - ref)[~on].max() / np.abs(ref).max()) if (~on).any() else 0.0}
    if plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(7, 3.5))
        ax.plot(t, z * 1e3, label="sidprep (10 modes, path marker)")
        ax.plot(t, ref * 1e3, "k--", lw=0.8, label="closed-form series (201 modes)")
        ax.axvline(L / SPEED, color="grey", lw=0.5)
        ax.set_xlabel("time [s]  (the force leaves at 1.5 s)")
        ax.set_ylabel("midspan deflection [mm]")
        ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig("analysis.png", dpi=100)
    return out


if __name__ == "__main__":
    for key, value in main(*sys.argv[1:2]).items():
        print(f"{key:22s} {value:.6g}")
