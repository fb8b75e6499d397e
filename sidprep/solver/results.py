"""Results files of a simulation (HDF5), their reader, CSV export and PNG plots of signals.

The data are a ``Result`` (defined here; built by sidprep/solver/postprocess.py).  HDF5 layout (SI; each dataset carries
its unit in the attribute ``units``)::

    /                      attrs: format="sidprep-results", format_version, units="SI",
                                  created_utc, sidprep_version
    /time                  (nt,)           s
    /bodies/<name>/        attrs: kind ("flexible" | "rigid"), source (SID / OBJ path)
        position           (nt, 3)         m      r_O, inertial components
        rotation           (nt, 3, 3)      1      A (body -> inertial components)
        velocity           (nt, 3)         m/s    v_O, inertial components
        omega              (nt, 3)         rad/s  body-frame (K) components
        q, qd              (nt, nq)        1, 1/s modal coordinates and rates
        acceleration       (nt, 6 + nq)           [dv_O/dt, omega_dot, q_ddot]
    /markers/<name>/position (nt, 3)       m      inertial
    /joints/<name>/        attrs: kind, markers (JSON list: marker 1, marker 2); force, torque (nt, 3) reaction on body 2, inertial;
                           force_local, torque_local (marker-1 components); coordinate, rate,
                           effort (nt,) joint angle/slide, its rate, driver effort
    /energy/<kind>         (nt,)           J      kinetic, strain, gravity, ..., total
    /constraint_error      (nt,)                  max |g|
    /effects               attrs: json (EffectsReport.as_dict()), text (the printed report)
    /stats                 attrs: json (RunStatistics.as_dict(), sidprep/solver/statistics.py)
    /scene                 attrs: path, sha256, text (the scene file as read)

Signal names for plots and CSV: see ``signal_names``.
"""

from __future__ import annotations

import csv
import datetime
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping

import numpy as np

from sidprep import __version__
from sidprep.errors import InputError
from sidprep.sid.io.atomic import atomic_hdf5, atomic_path
from sidprep.sid.io.hdf5 import open_hdf5
from sidprep.solver.effects import EffectEntry, EffectsReport
from sidprep.solver.statistics import RunStatistics


@dataclass
class BodyHistory:
    """Time series of one body; arrays have leading dimension nt (output samples).

    position (nt, 3) r_O, m; rotation (nt, 3, 3) A (body -> inertial); velocity (nt, 3) v_O,
    m/s inertial; omega (nt, 3) rad/s body components; q, qd (nt, nq); acceleration
    (nt, 6 + nq) du/dt = [dv_O/dt, omega_dot, q_ddot].
    """

    name: str
    position: np.ndarray
    rotation: np.ndarray
    velocity: np.ndarray
    omega: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    acceleration: np.ndarray


@dataclass
class JointHistory:
    """Reaction of one joint / driver on body 2 at marker 2.

    force, torque (nt, 3), N / N m, inertial components; force_local, torque_local (nt, 3) in
    marker-1 components; coordinate, rate (nt,) joint angle (rad) or slide (m) and its rate
    (NaN for joints without a coordinate); effort (nt,) driver torque/force along z1 (drivers);
    markers: the names of marker 1 and marker 2 (of the driven joint for a driver).
    """

    name: str
    kind: str
    force: np.ndarray
    torque: np.ndarray
    force_local: np.ndarray
    torque_local: np.ndarray
    coordinate: np.ndarray
    rate: np.ndarray
    effort: np.ndarray
    markers: tuple[str, ...] = ()


@dataclass
class Result:
    """Everything a simulation produced (sidprep/solver/results.py writes it to files).

    t (nt,) s; bodies {name: BodyHistory}; joints {name: JointHistory} (joints and drivers);
    markers {name: (nt, 3)} inertial marker positions; energy {kinetic, strain, gravity,
    spring, dissipated, external, total} (nt,) J (total = kinetic + strain + gravity + spring
    + dissipated - external: constant up to integration error); constraint_error (nt,) max |g|;
    effects: EffectsReport; stats: the run's RunStatistics (sidprep/solver/statistics.py; None before a run).
    """

    t: np.ndarray
    bodies: dict
    joints: dict
    markers: dict
    energy: dict
    constraint_error: np.ndarray
    effects: EffectsReport
    stats: RunStatistics | None = None


FORMAT = "sidprep-results"
FORMAT_VERSION = 1

XYZ = ("x", "y", "z")
#: per-body signals: Result.bodies[name].<attr> -> unit (vectors have components x, y, z)
BODY_VECTORS = {"position": "m", "velocity": "m/s", "omega": "rad/s"}
BODY_MODAL = {"q": "1", "qd": "1/s"}
#: per-joint signals: vectors (x, y, z) and scalars
JOINT_VECTORS = {"force": "N", "torque": "N m", "force_local": "N", "torque_local": "N m"}
JOINT_SCALARS = {"coordinate": "rad|m", "rate": "rad/s|m/s", "effort": "N m|N"}
#: joint kind -> its coordinate (angle: first unit above, slide: second)
_COORDINATE_KIND = {"revolute": "angle", "cylindrical": "angle", "prismatic": "slide"}
_BODY_ARRAYS = ("position", "rotation", "velocity", "omega", "q", "qd", "acceleration")
_BODY_UNITS = {"position": "m", "rotation": "1", "velocity": "m/s", "omega": "rad/s", "q": "1", "qd": "1/s",
               "acceleration": "m/s^2, rad/s^2, 1/s^2"}
_JOINT_UNITS = {**JOINT_VECTORS, **JOINT_SCALARS}


@dataclass(frozen=True)
class BodySource:
    """Where a body of a scene comes from (results provenance; attrs ``kind``, ``source`` of the
    file's ``bodies/<name>`` group).

    kind : "flexible" (a SID file), "beam" (an analytical beam of the scene), "rigid",
    "absolute_nodal", or "" when not known; source : the SID or OBJ path, "" without one.
    """

    kind: str = ""
    source: str = ""


@dataclass(frozen=True)
class ResultsFile:
    """A results file read back: the solver ``Result`` plus where it came from.

    scene : {"path", "sha256", "text"} of the scene file; bodies : {name: BodySource}.
    """

    result: Result
    scene: Mapping[str, str] = field(default_factory=dict)
    bodies: Mapping[str, BodySource] = field(default_factory=dict)


# ---------------------------------------------------------------------------------------------
# energy summary


def energy_summary(result: Result) -> dict:
    """Initial and final total energy (J) and the largest drift of it, relative to the energy scale.

    The scale is max(|E_total(0)|, the largest range max_t - min_t of any energy term), so that
    a body released from rest with E_total(0) = 0 still gets a meaningful relative drift.
    """
    total = np.asarray(result.energy["total"])
    ranges = [float(np.ptp(e)) for kind, e in result.energy.items() if kind != "total" and len(e)]
    scale = max([abs(total[0]), *ranges, 1e-300])
    return {
        "initial": float(total[0]),
        "final": float(total[-1]),
        "max_rel_drift": float(np.max(np.abs(total - total[0])) / scale),
    }


# ---------------------------------------------------------------------------------------------
# signals


def signal_names(result: Result) -> list[str]:
    """Every plottable signal name of ``result``: ``<body>.position.x``, ``<body>.q.3`` (1-based
    mode), ``<marker>.position.z``, ``<joint>.force.y``, ``<joint>.coordinate``, ``energy.total``."""
    names = []
    for name, b in result.bodies.items():
        names += [f"{name}.{qty}.{c}" for qty in BODY_VECTORS for c in XYZ]
        names += [f"{name}.{qty}.{k + 1}" for qty in BODY_MODAL for k in range(b.q.shape[1])]
    names += [f"{name}.position.{c}" for name in result.markers for c in XYZ]
    for name in result.joints:
        names += [f"{name}.{qty}.{c}" for qty in JOINT_VECTORS for c in XYZ]
        names += [f"{name}.{qty}" for qty in JOINT_SCALARS]
    names += [f"energy.{kind}" for kind in result.energy]
    return names


def default_signals(result: Result) -> list[str]:
    """What ``sidprep plot FILE`` draws when no signal is named: the kinetic and total energy, each
    body's position component that moves most and its largest modal coordinate, and each joint's
    coordinate that moves."""
    names = ["energy.kinetic", "energy.total"]
    for name, b in result.bodies.items():
        if len(b.position):
            names.append(f"{name}.position.{XYZ[int(np.ptp(b.position, axis=0).argmax())]}")
        if b.q.size:
            names.append(f"{name}.q.{int(np.abs(b.q).max(axis=0).argmax()) + 1}")
    for name, j in result.joints.items():
        if len(j.coordinate) and np.ptp(j.coordinate) > 0:          # NaN: a joint without a coordinate
            names.append(f"{name}.coordinate")
    return names


def _lookup(result: Result, parts: list[str]) -> tuple[np.ndarray, str]:
    """Signal values and unit from the split name; KeyError / ValueError / IndexError if unknown."""
    if parts[0] == "energy" and len(parts) == 2:
        return np.asarray(result.energy[parts[1]]), "J"
    entity, qty, *comp = parts
    if entity in result.bodies and len(comp) == 1:
        b = result.bodies[entity]
        if qty in BODY_MODAL and int(comp[0]) >= 1:
            return getattr(b, qty)[:, int(comp[0]) - 1], BODY_MODAL[qty]
        return getattr(b, qty)[:, XYZ.index(comp[0])], BODY_VECTORS[qty]
    if entity in result.markers and qty == "position" and len(comp) == 1:
        return result.markers[entity][:, XYZ.index(comp[0])], "m"
    if entity in result.joints:
        j = result.joints[entity]
        if qty in JOINT_SCALARS and not comp:
            rad_or_m = JOINT_SCALARS[qty].split("|")
            unit = {"angle": rad_or_m[0], "slide": rad_or_m[1]}.get(_COORDINATE_KIND.get(j.kind), JOINT_SCALARS[qty])
            return getattr(j, qty), unit
        if qty in JOINT_VECTORS and len(comp) == 1:
            return getattr(j, qty)[:, XYZ.index(comp[0])], JOINT_VECTORS[qty]
    raise KeyError(".".join(parts))


def signal(result: Result, name: str) -> tuple[np.ndarray, str]:
    """Values (nt,) and unit of the signal ``name``; InputError naming valid choices if unknown."""
    try:
        return _lookup(result, name.split("."))
    except (KeyError, ValueError, IndexError, AttributeError):
        examples = ", ".join(signal_names(result)[:4])
        raise InputError(f"unknown signal {name!r}; use <body|marker|joint>.<quantity>[.<x|y|z|mode number>] "
                         f"or energy.<kind>, e.g. {examples}") from None


# ---------------------------------------------------------------------------------------------
# HDF5


def json_safe(value):
    """Strict JSON: numpy scalars -> Python numbers, NaN / infinity -> null."""
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    if hasattr(value, "item") and not isinstance(value, (str, bytes)):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def _put(group, name: str, data, units: str) -> None:
    group.create_dataset(name, data=np.asarray(data, dtype=np.float64))
    group[name].attrs["units"] = units


def write_results(result: Result, path: str | os.PathLike, *, scene: Mapping[str, str] | None = None,
                  bodies: Mapping[str, BodySource] | None = None) -> Path:
    """Write ``result`` (Result) to the HDF5 file ``path`` atomically.

    scene : {"path", "sha256", "text"} provenance; bodies : {name: BodySource}.
    """

    path = Path(path)
    bodies = bodies or {}
    with atomic_hdf5(path) as f:
        f.attrs.update(format=FORMAT, format_version=FORMAT_VERSION, units="SI", sidprep_version=__version__,
                       created_utc=datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"))
        _put(f, "time", result.t, "s")
        for name, b in result.bodies.items():
            g = f.create_group(f"bodies/{name}")
            source = bodies.get(name, BodySource())
            g.attrs.update(kind=source.kind, source=source.source)
            for qty in _BODY_ARRAYS:
                _put(g, qty, getattr(b, qty), _BODY_UNITS[qty])
            g["omega"].attrs["frame"] = "body (K components)"
        for name, pos in result.markers.items():
            _put(f.create_group(f"markers/{name}"), "position", pos, "m")
        for name, j in result.joints.items():
            g = f.create_group(f"joints/{name}")
            g.attrs["kind"] = j.kind
            g.attrs["markers"] = json.dumps(list(j.markers))
            for qty, unit in _JOINT_UNITS.items():
                _put(g, qty, getattr(j, qty), unit)
        g = f.create_group("energy")
        for kind, values in result.energy.items():
            _put(g, kind, values, "J")
        _put(f, "constraint_error", result.constraint_error, "m|rad")
        g = f.create_group("effects")
        g.attrs.update(json=json.dumps(json_safe(result.effects.as_dict())), text=result.effects.text())
        stats = {} if result.stats is None else result.stats.as_dict()
        f.create_group("stats").attrs["json"] = json.dumps(json_safe(stats))
        g = f.create_group("scene")
        for key, value in (scene or {}).items():
            g.attrs[key] = str(value)
    return path


def _effects_from_dict(d: Mapping) -> EffectsReport:
    nan = float("nan")
    return EffectsReport(
        bodies={b: tuple(EffectEntry(e["effect"], e["included"], e["available"], e["reason"],
                                     nan if e["estimate"] is None else e["estimate"], e["measure"])
                         for e in entries) for b, entries in d["bodies"].items()},
        notes=tuple(d["notes"]))


def _statistics_from_json(text: str) -> RunStatistics | None:
    stats = json.loads(text)
    return RunStatistics.from_dict(stats) if stats else None


def read_results(path: str | os.PathLike) -> ResultsFile:
    """Read a results file written by ``write_results``."""
    path = Path(path)
    with open_hdf5(path, "results file", f"run `sidprep simulate SCENE -o {path}` first") as f:
        if f.attrs.get("format") != FORMAT:
            raise InputError(f"{path}: not a sidprep results file (no format={FORMAT!r} attribute); "
                             "pass the file written by `sidprep simulate`")
        bodies = {name: BodyHistory(name, **{qty: g[qty][()] for qty in _BODY_ARRAYS})
                  for name, g in f.get("bodies", {}).items()}
        joints = {name: JointHistory(name, str(g.attrs["kind"]), **{qty: g[qty][()] for qty in _JOINT_UNITS},
                                     markers=tuple(json.loads(g.attrs.get("markers", "[]"))))
                  for name, g in f.get("joints", {}).items()}
        result = Result(
            t=f["time"][()], bodies=bodies, joints=joints,
            markers={name: g["position"][()] for name, g in f.get("markers", {}).items()},
            energy={kind: d[()] for kind, d in f["energy"].items()},
            constraint_error=f["constraint_error"][()],
            effects=_effects_from_dict(json.loads(f["effects"].attrs["json"])),
            stats=_statistics_from_json(f["stats"].attrs["json"]))
        return ResultsFile(result, scene={key: str(v) for key, v in f["scene"].attrs.items()},
                           bodies={name: BodySource(str(g.attrs["kind"]), str(g.attrs["source"]))
                                   for name, g in f.get("bodies", {}).items()})


# ---------------------------------------------------------------------------------------------
# CSV and plots


def write_csv(result: Result, names: list[str], path: str | os.PathLike) -> Path:
    """Write time and the chosen signals as CSV columns ``time [s], <name> [unit], ...``."""
    columns = [signal(result, n) for n in names]
    path = Path(path)
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["time [s]"] + [f"{n} [{unit}]" for n, (_, unit) in zip(names, columns)])
        for i, t in enumerate(result.t):
            w.writerow([repr(float(t))] + [repr(float(values[i])) for values, _ in columns])
    return path


def plot_signals(result: Result, names: list[str], path: str | os.PathLike, title: str = "") -> Path:
    """One PNG with a panel per unit (signals sharing a unit share a panel), against time."""
    import matplotlib  # deferred: 0.45 CPU-s of import (with pyplot), needed only for plots

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # deferred: see above

    panels: dict[str, list[tuple[str, np.ndarray]]] = {}
    for n in names:
        values, unit = signal(result, n)
        panels.setdefault(unit, []).append((n, values))
    fig, axes = plt.subplots(len(panels), 1, sharex=True, squeeze=False,
                             figsize=(8.0, 2.6 * len(panels) + 0.6))
    for ax, (unit, curves) in zip(axes[:, 0], panels.items()):
        for n, values in curves:
            ax.plot(result.t, values, label=n)
        ax.set_ylabel(f"[{unit}]")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="small")
    axes[-1, 0].set_xlabel("time [s]")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    plt.close(fig)
    return path


@dataclass(frozen=True)
class ResultsPlot:
    """A plot of a results file: path (the PNG written), signals (those plotted) and available
    (every signal name of the file, ``signal_names``)."""

    path: Path
    signals: tuple[str, ...]
    available: tuple[str, ...]


def plot_results(results_path: str | os.PathLike, signals: list[str], output: str | os.PathLike) -> ResultsPlot:
    """Plot the named signals of a results file (``default_signals`` when none are named) into the PNG
    ``output``, titled with the file's name and its scene (what ``sidprep plot`` runs)."""
    output = Path(output)
    if output.suffix.lower() != ".png":
        raise InputError(f"{output}: plot writes PNG images; name the output OUT.png")
    results = read_results(results_path)
    signals = list(signals) or default_signals(results.result)
    scene = results.scene.get("path")
    title = Path(results_path).name + (f" ({scene})" if scene else "")
    path = plot_signals(results.result, signals, output, title=title)
    return ResultsPlot(path, tuple(signals), tuple(signal_names(results.result)))
