#!/usr/bin/env python3
"""The flexible slider crank's energy bookkeeping and kinematics (README.md); writes
analysis.png.

    python analyse.py              # runs scene.toml (10 s simulated, ~2.5 CPU-s of integration)
    python analyse.py --t-end 2
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from sidprep.solver.scene import load_scene, simulate

HERE = Path(__file__).resolve().parent
#: crank radius and conrod length between the pins, m (the scene's geometry)
CRANK, CONROD = 0.25, 1.0


def rigid_slider(theta, r=CRANK, l=CONROD):
    """Slider position of the rigid mechanism, m: x = r cos(theta) + sqrt(l^2 - r^2 sin^2(theta))."""
    return r * np.cos(theta) + np.sqrt(l**2 - (r * np.sin(theta)) ** 2)


def friction_loss(result, mu=0.3):
    """Coulomb work from the recorded reactions, J: integral of mu |N| |v| over time, N the
    guide's reaction across its axis (x); the solver's own account is energy.dissipated."""
    force = result.joints["slider_joint"].force
    normal = np.hypot(force[:, 1], force[:, 2])
    power = mu * normal * np.abs(result.joints["slider_joint"].rate)
    return float(np.sum(0.5 * (power[1:] + power[:-1]) * np.diff(result.t)))


def damping_loss(result, folder=HERE) -> float:
    """Modal damping work from the recorded modal rates, J: sum over the links of the integral of
    qd^T De qd (De from their SID files)."""
    import sidprep

    total = 0.0
    for name in ("crank", "conrod"):
        de = sidprep.read_sid(Path(folder) / f"{name}.sid.h5").De.M0
        qd = result.bodies[name].qd
        power = np.einsum("ti,ij,tj->t", qd, de, qd)
        total += float(np.sum(0.5 * (power[1:] + power[:-1]) * np.diff(result.t)))
    return total


def bookkeeping(result) -> dict:
    """Motor work against kinetic + gravity + strain + losses (J) at the end, and the closure
    error max over time |balance(t) - balance(0)| / motor work."""
    e = result.energy
    balance = e["kinetic"] + e["gravity"] + e["strain"] + e["spring"] + e["dissipated"] - e["external"]
    end = {k: float(e[k][-1] - e[k][0]) for k in ("external", "kinetic", "gravity", "strain", "dissipated")}
    end["closure"] = float(np.max(np.abs(balance - balance[0])) / abs(e["external"][-1]))
    return end


def main(t_end=None, plot=True, folder=HERE) -> dict:
    """The README's numbers (a dict) for the scene in ``folder``."""
    r = simulate(load_scene(Path(folder) / "scene.toml"), t_end=t_end)
    x = r.joints["slider_joint"].coordinate + r.markers["guide"][:, 0]
    deviation = x - rigid_slider(r.joints["crank_joint"].coordinate)
    out = {**bookkeeping(r),
           "friction_from_reactions": friction_loss(r),
           "damping_from_modal_rates": damping_loss(r, folder),
           "slider_deviation_m": float(np.max(np.abs(deviation))),
           "conrod_q_max": float(np.max(np.abs(r.bodies["conrod"].q))),
           "crank_q_max": float(np.max(np.abs(r.bodies["crank"].q))),
           "cpu_s": r.stats.cpu_integration, "steps": r.stats.steps,
           "warnings": r.effects.warnings}
    if plot:
        write_plot(r, deviation)
    return out


def write_plot(r, deviation):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    e = r.energy
    fig, ax = plt.subplots(3, 1, figsize=(8, 8), sharex=True)
    for key in ("external", "kinetic", "gravity", "dissipated"):
        ax[0].plot(r.t, e[key], label="motor work" if key == "external" else key)
    ax[0].set_ylabel("energy [J]")
    ax[0].legend(fontsize=8)
    ax[1].plot(r.t, deviation * 1e6)
    ax[1].set_ylabel("slider - rigid mechanism [um]")
    ax[2].plot(r.t, r.bodies["conrod"].q[:, 0], lw=0.7, label="conrod q1")
    ax[2].plot(r.t, r.bodies["crank"].q[:, 1], lw=0.7, label="crank q2")
    ax[2].set_ylabel("modal coordinate [1]")
    ax[2].set_xlabel("time [s]")
    ax[2].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(HERE / "analysis.png", dpi=100)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--t-end", type=float, default=None)
    for key, value in main(parser.parse_args().t_end).items():
        print(f"{key:26s} {value}")
