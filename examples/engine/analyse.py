#!/usr/bin/env python3
"""The engine's numbers (README.md): energy balance, flexible against rigid rod, axial shortening
against the static value F/k of the SID, modal amplitudes and the frequencies they oscillate at
against the mechanism's linearised eigenfrequencies, CPU time; writes analysis.png.

    python analyse.py              # runs scene.toml and scene_rigid.toml (about 10 s)
    python analyse.py --t-end 0.2  # a shorter run
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import sidprep
from sidprep.solver.linear import mechanism_modes
from sidprep.solver.scene import load_scene, simulate

HERE = Path(__file__).resolve().parent
#: spectra: frequencies below this are the crank-speed harmonics (forced, quasi-static), Hz
FREE_VIBRATION_HZ = 150.0


def axial_stiffness(sid_path) -> tuple[float, float]:
    """(k N/m, l0 m): the SID's static stiffness against equal and opposite forces on its two
    nodes along the line between them (Ke q = Phi^T f, self-equilibrated, no inertia relief),
    and the undeformed distance of the nodes."""
    body = sidprep.read_sid(sid_path)
    big, small = body.nodes[0], body.nodes[1]
    axis = (small.origin.M0 - big.origin.M0).ravel()
    l0 = float(np.linalg.norm(axis))
    axis /= l0
    phi_big, phi_small = big.phi.M0, small.phi.M0                      # (3, nq)
    force_q = phi_big.T @ axis - phi_small.T @ axis                      # unit compression
    q = np.linalg.solve(body.Ke.M0, force_q)
    shortening = -axis @ ((phi_small - phi_big) @ q)
    return 1.0 / shortening, l0


def energy_balance(result) -> float:
    """max over time |kinetic + strain + gravity + dissipated - work of the loads - E(0)| / work."""
    e = result.energy
    balance = e["kinetic"] + e["strain"] + e["gravity"] + e["spring"] + e["dissipated"] - e["external"]
    return float(np.max(np.abs(balance - balance[0])) / e["external"][-1])


def rod_axial(result) -> tuple[np.ndarray, np.ndarray]:
    """(shortening m, compressive force N) of the rod over time: the change of the eye distance
    and the mean of the two joint reactions' components along the rod."""
    big, small = result.markers["big_end"], result.markers["small_end"]
    axis = small - big
    length = np.linalg.norm(axis, axis=1)
    axis /= length[:, None]
    on_piston = result.joints["piston_pin_joint"].force       # rod -> piston, at the small end
    on_rod = result.joints["crank_pin_joint"].force           # crank -> rod, at the big end
    compression = 0.5 * (np.sum(on_piston * axis, axis=1) + np.sum(on_rod * axis, axis=1))
    return length, compression


def revolution_speeds(t, angle) -> np.ndarray:
    """Mean crank speed (rad/s) of every whole revolution from the start: 2 pi over its duration."""
    turns = np.arange(1, int(abs(angle[-1] - angle[0]) // (2 * np.pi)) + 1)
    times = np.interp(angle[0] + np.sign(angle[-1] - angle[0]) * 2 * np.pi * turns, angle, t)
    return 2 * np.pi / np.diff(np.concatenate([[t[0]], times]))


def spectrum_peak(t, x, f_min=FREE_VIBRATION_HZ) -> float:
    """Frequency (Hz) of the largest spectral peak of x(t) above f_min (Hann window, cubic trend
    removed, zero-padded 16 times to read the peak between the bins)."""
    x = x - np.polyval(np.polyfit(t, x, 3), t)
    n = 16 * x.size
    spectrum = np.abs(np.fft.rfft(x * np.hanning(x.size), n))
    freq = np.fft.rfftfreq(n, t[1] - t[0])
    above = freq > f_min
    return float(freq[above][np.argmax(spectrum[above])])


def run(scene_file, t_end=None):
    scene = load_scene(scene_file)
    return scene, simulate(scene, t_end=t_end)


def main(t_end=None, plot=True, folder=HERE) -> dict:
    """The README's numbers (a dict) for the scenes in ``folder``, runs to ``t_end`` s."""
    folder = Path(folder)
    scene, flexible = run(folder / "scene.toml", t_end)
    _, rigid = run(folder / "scene_rigid.toml", t_end)
    modes = mechanism_modes(scene.system)
    k, l0 = axial_stiffness(folder / "piston_rod.sid.h5")
    length, compression = rod_axial(flexible)
    shortening = l0 - length
    peak = int(np.argmax(compression))
    w_flex, w_rigid = flexible.joints["crank_joint"].rate, rigid.joints["crank_joint"].rate
    rev_flex = revolution_speeds(flexible.t, flexible.joints["crank_joint"].coordinate)
    rev_rigid = revolution_speeds(rigid.t, rigid.joints["crank_joint"].coordinate)
    q = flexible.bodies["rod"].q
    largest = np.argsort(-np.max(np.abs(q), axis=0))[:3]
    t = flexible.t
    late = t > 0.2 * t[-1]
    elastic = modes.frequencies_hz[modes.frequencies_hz > FREE_VIBRATION_HZ]
    out = {
        "t_end": float(t[-1]),
        "crank_speed": (float(w_flex[0]), float(w_flex[-1])),
        "work": float(flexible.energy["external"][-1]),
        "energy_balance": energy_balance(flexible),
        "revolution_speeds": [round(float(w), 3) for w in rev_flex],
        "revolution_speeds_vs_rigid": float(np.max(np.abs(rev_flex - rev_rigid) / rev_rigid)),
        "final_speed_vs_rigid": float(abs(w_flex[-1] - w_rigid[-1]) / w_rigid[-1]),
        "instantaneous_speed_vs_rigid": float(np.max(np.abs(w_flex - w_rigid)) / np.max(np.abs(w_rigid))),
        "axial_stiffness": k,
        "peak_compression": float(compression[peak]),
        "shortening_at_peak": float(shortening[peak]),
        "static_shortening_at_peak": float(compression[peak] / k),
        "modal_amplitudes": {int(j + 1): float(np.max(np.abs(q[:, j]))) for j in largest},
        "oscillation_hz": {int(j + 1): spectrum_peak(t[late], q[late, j]) for j in largest},
        "mechanism_hz": [float(f) for f in elastic[:4]],
        "cpu_per_second": flexible.stats.cpu_integration / float(t[-1]),
        "rigid_cpu_per_second": rigid.stats.cpu_integration / float(t[-1]),
        "steps": flexible.stats.steps,
    }
    if plot:
        write_plot(flexible, rigid, q, largest, shortening, compression / k)
    return out


def write_plot(flexible, rigid, q, largest, shortening, static):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from gas_force import gas_force

    t = flexible.t
    fig, ax = plt.subplots(4, 1, figsize=(8, 9), sharex=True)
    ax[0].plot(t, gas_force(flexible.joints["crank_joint"].coordinate) / 1e3, lw=0.8)
    ax[0].set_ylabel("gas force [kN]")
    ax[1].plot(t, flexible.joints["crank_joint"].rate, label="flexible rod")
    ax[1].plot(t, rigid.joints["crank_joint"].rate, "--", label="rigid rod")
    ax[1].set_ylabel("crank speed [rad/s]")
    ax[1].legend(fontsize=8)
    for j in largest:
        ax[2].plot(t, q[:, j], lw=0.7, label=f"q{j + 1}")
    ax[2].set_ylabel("modal amplitude [1]")
    ax[2].legend(fontsize=8)
    ax[3].plot(t, shortening * 1e6, lw=0.8, label="eye distance change")
    ax[3].plot(t, static * 1e6, "--", lw=0.8, label="F / k (static, SID)")
    ax[3].set_ylabel("axial shortening [um]")
    ax[3].set_xlabel("time [s]")
    ax[3].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(HERE / "analysis.png", dpi=100)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--t-end", type=float, default=None)
    args = parser.parse_args()
    for key, value in main(args.t_end).items():
        print(f"{key:28s} {value}")
