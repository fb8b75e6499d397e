#!/usr/bin/env python3
"""Run the two-link manipulator and draw the paper's figures (Figs. 5-14 of Kisu Lee's paper).

    python examples/two_link_manipulator/run.py [--t-end 2] [--out DIR]

Writes DIR/two_link.results.h5 (sidprep/solver/results.py format), DIR/two_link.csv and
DIR/two_link_figures.png; prints the energy error and the CPU time.
"""

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))   # the repository's solver package

from sidprep.solver.absolute_nodal.run import simulate_absolute_nodal  # noqa: E402
from sidprep.solver.absolute_nodal.scene import load_absolute_nodal_scene  # noqa: E402
from sidprep.solver.results import BodySource, write_csv, write_results  # noqa: E402
from sidprep.tables import read_toml_text  # noqa: E402

HERE = Path(__file__).resolve().parent


def figures(result, path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = result.t
    panels = [
        ("relative rotation of beam 1 (Fig. 5) [rad]", result.joints["pin"].coordinate),
        ("relative rotation of beam 2, phi2 - phi1 (Fig. 6) [rad]", result.joints["elbow"].coordinate),
        ("X of beam 2's tip (Fig. 7) [m]", result.markers["tip"][:, 0]),
        ("Y of beam 2's tip (Fig. 8) [m]", result.markers["tip"][:, 1]),
        ("flexural displacement -theta_n L, beam 1 (Fig. 9) [m]", result.bodies["link1"].q[:, 0]),
        ("flexural slope theta_n - theta_1, beam 1 (Fig. 10) [rad]", result.bodies["link1"].q[:, 1]),
        ("flexural displacement, beam 2 (Fig. 11) [m]", result.bodies["link2"].q[:, 0]),
        ("flexural slope, beam 2 (Fig. 12) [rad]", result.bodies["link2"].q[:, 1]),
    ]
    fig, axes = plt.subplots(5, 2, figsize=(11, 13), sharex=True)
    for ax, (label, y) in zip(axes.ravel(), panels):
        ax.plot(t, y)
        ax.set_title(label, fontsize="small")
        ax.grid(True, alpha=0.3)
    e = result.energy
    for ax in axes[4]:
        for kind in ("kinetic", "gravity", "strain"):
            ax.plot(t, e[kind], label=kind)
        ax.grid(True, alpha=0.3)
        ax.set_xlabel("time [s]")
    axes[4, 0].set_title("energies (Fig. 13) [J]", fontsize="small")
    axes[4, 0].legend(fontsize="small")
    axes[4, 1].set_ylim(-0.5, 2.0)
    axes[4, 1].set_title("energies, detail (Fig. 14) [J]", fontsize="small")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--t-end", type=float, default=None, help="end time [s] (default: the scene's)")
    p.add_argument("--out", type=Path, default=Path("."), help="output folder")
    args = p.parse_args(argv)
    scene_path = HERE / "scene.toml"
    root, text = read_toml_text(scene_path, "scene file")
    scene = load_absolute_nodal_scene(root, scene_path, t_end=args.t_end)
    result = simulate_absolute_nodal(scene.model, scene.t_end, scene.settings)
    args.out.mkdir(parents=True, exist_ok=True)
    write_results(result, args.out / "two_link.results.h5", scene={"path": str(scene_path), "text": text},
                  bodies={b.name: BodySource("absolute_nodal", str(scene_path)) for b in scene.model.beams})
    write_csv(result, list(scene.output.signals), args.out / "two_link.csv")
    figures(result, args.out / "two_link_figures.png")
    total = result.energy["total"]
    drift = np.max(np.abs(total - total[0])) / abs(total[0])
    print(f"t_end {result.t[-1]:g} s, {result.stats.steps} RK4 steps, CPU {result.stats.cpu_time:.3f} s; "
          f"E0 = {total[0]:.6f} J, max |E - E0| / E0 = {drift:.2e}")
    for name, (x, unit) in {"phi1": (result.joints["pin"].coordinate, "rad"),
                            "phi2 - phi1": (result.joints["elbow"].coordinate, "rad"),
                            "tip x": (result.markers["tip"][:, 0], "m"),
                            "tip y": (result.markers["tip"][:, 1], "m")}.items():
        times = [s for s in (0.5, 1.0) if s < result.t[-1]] + [result.t[-1]]
        i = np.minimum(np.searchsorted(result.t, np.array(times) - 1e-9), len(result.t) - 1)
        print(f"  {name:12s} at t = " + ", ".join(f"{s:g}" for s in times) + " s: "
              + ", ".join(f"{x[k]:+.6f}" for k in i) + f" {unit}")


if __name__ == "__main__":
    main()
