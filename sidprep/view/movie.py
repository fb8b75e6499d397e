"""A movie of a simulated mechanism (``sidprep animate -o run.gif`` or ``.mp4``): matplotlib's 3-D
axes, at most MAX_MOVIE_FRAMES frames, surfaces coloured by |u| (m) or by the von Mises stress (MPa).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sidprep.errors import InputError
from sidprep.sid.io.atomic import atomic_path
from sidprep.sid.surface import surface_motion, surface_von_mises
from sidprep.view.mechanism import exaggeration, mechanism_surfaces, shown_samples, stress_envelope_mpa
from sidprep.view.page import PA_PER_MPA

#: at most this many time samples go into a movie (every k-th output sample)
MAX_MOVIE_FRAMES = 60
#: tick marks per axis of the movie's 3-D axes (more overlap at the movie's size)
MOVIE_TICKS = 4


def write_mechanism_movie(results_path, out_path, exaggerated: bool = True, colour: str = "displacement") -> Path:
    """An .mp4 (needs ffmpeg) or .gif movie of the mechanism with matplotlib, at most
    MAX_MOVIE_FRAMES frames, surfaces coloured by |u| (m) or by the von Mises stress (``colour =
    "stress"``, MPa), with a colour bar."""
    import matplotlib  # deferred: 1.2 s import, plots only

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # deferred: 1.2 s import, plots only
    from matplotlib import animation
    from matplotlib.ticker import MaxNLocator  # deferred: with matplotlib
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # deferred: with matplotlib

    out_path = Path(out_path)
    suffix = out_path.suffix.lower()
    if suffix == ".mp4" and not animation.FFMpegWriter.isAvailable():
        raise InputError(f"{out_path}: writing .mp4 needs ffmpeg (apt-get install ffmpeg); write a .gif instead")
    rf, surfaces = mechanism_surfaces(results_path)
    result = rf.result
    keep = shown_samples(len(result.t), MAX_MOVIE_FRAMES)
    scale = exaggeration(result, surfaces, keep) if exaggerated else 1.0
    motion = {}
    for n, s in surfaces.items():
        x, u = surface_motion(s, result.bodies[n].position[keep], result.bodies[n].rotation[keep],
                              result.bodies[n].q[keep], scale)
        motion[n] = (x, np.linalg.norm(u, axis=2))
    cloud = np.vstack([x.reshape(-1, 3) for x, _ in motion.values()])
    if colour == "stress":
        values = {n: surface_von_mises(s, result.bodies[n].q[keep]) for n, s in surfaces.items()}
        values = {n: None if v is None else v / PA_PER_MPA for n, v in values.items()}
        if all(v is None for v in values.values()):
            raise InputError(f"{results_path}: no body's SID has modal stresses to colour by; reduce with "
                             "`sidprep reduce MESH --stress` and re-run the simulation, or colour by displacement")
        values = {n: np.zeros(motion[n][1].shape) if v is None else v for n, v in values.items()}
        label = "von Mises (MPa)"
    else:
        values, label = {n: u for n, (_, u) in motion.items()}, "|u| (m)"
    umax = max(float(v.max()) for v in values.values()) or 1.0
    if colour == "stress":      # the envelope of every sample, as on the page and in sidprep stress
        umax = stress_envelope_mpa(rf, Path(results_path), [n for n, s in surfaces.items() if s.stress is not None]) or umax
    fig = plt.figure(figsize=(6.6, 5), dpi=80)
    ax = fig.add_subplot(projection="3d")
    cmap = plt.get_cmap("viridis")
    fig.colorbar(plt.cm.ScalarMappable(matplotlib.colors.Normalize(0, umax), cmap), ax=ax, shrink=0.6, label=label)

    def draw(f):
        ax.cla()
        for name, s in surfaces.items():
            x, _ = motion[name]
            colours = cmap(values[name][f][s.triangles].mean(axis=1) / umax)
            ax.add_collection3d(Poly3DCollection(x[f][s.triangles], facecolors=colours, linewidths=0))
        for set_lim, a in ((ax.set_xlim, 0), (ax.set_ylim, 1), (ax.set_zlim, 2)):
            set_lim(cloud[:, a].min(), cloud[:, a].max())
        ax.set_box_aspect(np.ptp(cloud, axis=0) + 1e-12)
        for axis, label in ((ax.xaxis, "x (m)"), (ax.yaxis, "y (m)"), (ax.zaxis, "z (m)")):
            axis.set_major_locator(MaxNLocator(MOVIE_TICKS))
            axis.set_tick_params(labelsize=7)
            axis.set_label_text(label, fontsize=8)
        ax.set_title(f"t = {result.t[keep][f]:.3f} s, deformation x {scale:.3g}")

    movie = animation.FuncAnimation(fig, draw, frames=len(keep))
    dt = float(np.median(np.diff(result.t[keep]))) if len(keep) > 1 else 0.1
    fps = max(1, min(30, round(1.0 / dt)))
    writer = animation.PillowWriter(fps=fps) if suffix == ".gif" else animation.FFMpegWriter(fps=fps)
    with atomic_path(out_path) as tmp:
        movie.save(str(tmp) + suffix, writer=writer)
        Path(str(tmp) + suffix).replace(tmp)
    plt.close(fig)
    return out_path
