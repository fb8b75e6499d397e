"""Results of a simulation: the data model, the HDF5 file, CSV export and PNG plots.

HDF5 layout (every dataset SI, its unit in the attribute ``units``)::

    /                      attrs: format="sidprep-results", format_version, units="SI", created_utc,
                                  sidprep_version
    /time                  (nt,)            s
    /bodies/<name>/        attrs: kind ("flexible" | "rigid"), source (SID / OBJ path or "")
        position           (nt, 3)          m      r_O, inertial components
        rotation           (nt, 3, 3)       1      A (body -> inertial components)
        velocity           (nt, 3)          m/s    inertial velocity of O, inertial components
        angular_velocity   (nt, 3)          rad/s  omega, body-frame (K) components
        q, qd              (nt, nq)         1, 1/s modal coordinates and their rates
    /markers/<name>/position  (nt, 3)       m      marker point, inertial components
    /joints/<name>/force   (nt, 3)          N      reaction force on the first body of the joint
    /joints/<name>/torque  (nt, 3)          N m    reaction torque on the first body (inertial)
    /energy/<kind>         (nt,)            J      kinetic, potential, elastic, total, ...
    /effects, /stats       attrs: ``json`` (the effects report; solver statistics)
    /scene                 attrs: path, sha256, text (the scene file as read)

The signal names used by plots and CSV are ``<body>.position.x``, ``<body>.q.3`` (1-based mode),
``<marker>.position.z``, ``<joint>.force.y``, ``energy.total`` ... (see ``signal_names``).
"""

from __future__ import annotations

import csv
import datetime
import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping

import numpy as np

from sidprep.errors import InputError
from sidprep.io.atomic import atomic_path

FORMAT = "sidprep-results"
FORMAT_VERSION = 1

#: unit and component names of each per-entity quantity
VECTOR_QUANTITIES = {
    "position": "m",
    "velocity": "m/s",
    "angular_velocity": "rad/s",
    "force": "N",
    "torque": "N m",
}
MODAL_QUANTITIES = {"q": "1", "qd": "1/s"}
XYZ = ("x", "y", "z")


@dataclass(frozen=True)
class BodyTrack:
    """Time history of one body at the output times (nt of them).

    position (nt, 3) m; rotation (nt, 3, 3); velocity (nt, 3) m/s inertial; angular_velocity
    (nt, 3) rad/s in K; q, qd (nt, nq) (nq = 0 for a rigid body); kind "flexible" | "rigid";
    source: the SID or OBJ file the body came from ("" if none).
    """

    kind: str
    position: np.ndarray
    rotation: np.ndarray
    velocity: np.ndarray
    angular_velocity: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    source: str = ""


@dataclass(frozen=True)
class Results:
    """Everything a run produced.

    time (nt,) s; bodies {name: BodyTrack}; markers {name: (nt, 3) m};
    joints {name: {"force": (nt, 3) N, "torque": (nt, 3) N m}}; energy {kind: (nt,) J};
    effects {"included": [...], "left_out": [...], "warnings": [...]}; stats (JSON-able dict:
    steps, cpu_s, integrator, ...); scene {"path", "sha256", "text"}.
    """

    time: np.ndarray
    bodies: Mapping[str, BodyTrack]
    markers: Mapping[str, np.ndarray] = field(default_factory=dict)
    joints: Mapping[str, Mapping[str, np.ndarray]] = field(default_factory=dict)
    energy: Mapping[str, np.ndarray] = field(default_factory=dict)
    effects: Mapping[str, list] = field(default_factory=dict)
    stats: Mapping[str, object] = field(default_factory=dict)
    scene: Mapping[str, str] = field(default_factory=dict)


# ---------------------------------------------------------------------------------------------
# energy summary


def energy_summary(results: Results) -> dict:
    """Initial and final total energy (J) and the largest drift of it, relative to the energy scale.

    The scale is max(|E_total(0)|, max_t E_kinetic), so that a body released from rest with
    E_total(0) = 0 still gets a meaningful relative drift.
    """
    total = np.asarray(results.energy["total"])
    scale = max(abs(total[0]), float(np.max(results.energy.get("kinetic", 0.0))), 1e-300)
    return {
        "initial": float(total[0]),
        "final": float(total[-1]),
        "max_rel_drift": float(np.max(np.abs(total - total[0])) / scale),
    }


# ---------------------------------------------------------------------------------------------
# signals


def signal_names(results: Results) -> list[str]:
    """Every plottable signal name of ``results`` (see the module docstring)."""
    names = []
    for name, b in results.bodies.items():
        for qty in ("position", "velocity", "angular_velocity"):
            names += [f"{name}.{qty}.{c}" for c in XYZ]
        for qty in MODAL_QUANTITIES:
            names += [f"{name}.{qty}.{k + 1}" for k in range(b.q.shape[1])]
    for name in results.markers:
        names += [f"{name}.position.{c}" for c in XYZ]
    for name, j in results.joints.items():
        for qty in j:
            names += [f"{name}.{qty}.{c}" for c in XYZ]
    names += [f"energy.{kind}" for kind in results.energy]
    return names


def signal(results: Results, name: str) -> tuple[np.ndarray, str]:
    """Values (nt,) and unit of the signal ``name``; InputError naming the valid choices if unknown."""
    parts = name.split(".")
    try:
        if parts[0] == "energy" and len(parts) == 2:
            return np.asarray(results.energy[parts[1]]), "J"
        entity, qty, comp = parts
        if entity in results.bodies:
            b = results.bodies[entity]
            if qty in MODAL_QUANTITIES:
                k = int(comp) - 1
                if not 0 <= k < b.q.shape[1]:
                    raise KeyError(name)
                return getattr(b, qty)[:, k], MODAL_QUANTITIES[qty]
            if qty in ("position", "velocity", "angular_velocity"):
                return getattr(b, qty)[:, XYZ.index(comp)], VECTOR_QUANTITIES[qty]
        if entity in results.markers and qty == "position":
            return results.markers[entity][:, XYZ.index(comp)], "m"
        if entity in results.joints and qty in results.joints[entity]:
            return results.joints[entity][qty][:, XYZ.index(comp)], VECTOR_QUANTITIES[qty]
    except (KeyError, ValueError):
        pass
    examples = ", ".join(signal_names(results)[:6])
    raise InputError(f"unknown signal {name!r}; use <body|marker|joint>.<quantity>.<x|y|z|mode number> "
                     f"or energy.<kind>, e.g. {examples}")


# ---------------------------------------------------------------------------------------------
# HDF5


def _put(group, name: str, data, units: str) -> None:
    group.create_dataset(name, data=np.asarray(data, dtype=np.float64))
    group[name].attrs["units"] = units


def write_results(results: Results, path: str | os.PathLike) -> Path:
    """Write ``results`` to the HDF5 file ``path`` atomically; returns the path."""
    import h5py

    from sidprep import __version__

    path = Path(path)
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
        f.attrs.update(format=FORMAT, format_version=FORMAT_VERSION, units="SI", sidprep_version=__version__,
                       created_utc=datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"))
        _put(f, "time", results.time, "s")
        for name, b in results.bodies.items():
            g = f.create_group(f"bodies/{name}")
            g.attrs.update(kind=b.kind, source=b.source)
            for qty, unit in (("position", "m"), ("rotation", "1"), ("velocity", "m/s"),
                              ("angular_velocity", "rad/s"), ("q", "1"), ("qd", "1/s")):
                _put(g, qty, getattr(b, qty), unit)
            g["angular_velocity"].attrs["frame"] = "body (K components)"
        for name, pos in results.markers.items():
            _put(f.create_group(f"markers/{name}"), "position", pos, "m")
        for name, reaction in results.joints.items():
            g = f.create_group(f"joints/{name}")
            for qty, values in reaction.items():
                _put(g, qty, values, VECTOR_QUANTITIES[qty])
        g = f.create_group("energy")
        for kind, values in results.energy.items():
            _put(g, kind, values, "J")
        f.create_group("effects").attrs["json"] = json.dumps(results.effects)
        f.create_group("stats").attrs["json"] = json.dumps(results.stats)
        g = f.create_group("scene")
        for key, value in results.scene.items():
            g.attrs[key] = str(value)
    return path


def read_results(path: str | os.PathLike) -> Results:
    """Read a results file written by ``write_results``."""
    import h5py

    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such results file; run `sidprep simulate SCENE -o {path}` first")
    with h5py.File(path, "r") as f:
        if f.attrs.get("format") != FORMAT:
            raise InputError(f"{path}: not a sidprep results file (no format={FORMAT!r} attribute); "
                             "pass the file written by `sidprep simulate`")
        bodies = {
            name: BodyTrack(kind=str(g.attrs["kind"]), source=str(g.attrs["source"]),
                            **{qty: g[qty][()] for qty in ("position", "rotation", "velocity",
                                                           "angular_velocity", "q", "qd")})
            for name, g in f.get("bodies", {}).items()
        }
        return Results(
            time=f["time"][()],
            bodies=bodies,
            markers={name: g["position"][()] for name, g in f.get("markers", {}).items()},
            joints={name: {qty: g[qty][()] for qty in g} for name, g in f.get("joints", {}).items()},
            energy={kind: d[()] for kind, d in f["energy"].items()},
            effects=json.loads(f["effects"].attrs["json"]),
            stats=json.loads(f["stats"].attrs["json"]),
            scene={key: str(v) for key, v in f["scene"].attrs.items()},
        )


# ---------------------------------------------------------------------------------------------
# CSV and plots


def write_csv(results: Results, names: list[str], path: str | os.PathLike) -> Path:
    """Write time and the chosen signals as CSV columns ``time [s], <name> [unit], ...``."""
    columns = [signal(results, n) for n in names]
    path = Path(path)
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["time [s]"] + [f"{n} [{unit}]" for n, (_, unit) in zip(names, columns)])
        for i, t in enumerate(results.time):
            w.writerow([repr(float(t))] + [repr(float(values[i])) for values, _ in columns])
    return path


def plot_signals(results: Results, names: list[str], path: str | os.PathLike) -> Path:
    """One PNG with a panel per unit (signals sharing a unit share a panel), against time."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels: dict[str, list[tuple[str, np.ndarray]]] = {}
    for n in names:
        values, unit = signal(results, n)
        panels.setdefault(unit, []).append((n, values))
    fig, axes = plt.subplots(len(panels), 1, sharex=True, squeeze=False,
                             figsize=(8.0, 2.6 * len(panels) + 0.6))
    for ax, (unit, curves) in zip(axes[:, 0], panels.items()):
        for n, values in curves:
            ax.plot(results.time, values, label=n)
        ax.set_ylabel(f"[{unit}]")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="small")
    axes[-1, 0].set_xlabel("time [s]")
    title = Path(results.scene.get("path", "")).name
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    plt.close(fig)
    return path
