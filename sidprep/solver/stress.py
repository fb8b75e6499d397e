"""Stress histories of a simulated flexible body: sigma(t) = sum_k sigma_k q_k(t) (``sidprep stress``).

The results file names each flexible body's SID (``/bodies/<name>`` attr ``source``) and holds its
modal coordinates q (nt, nq); the SID's modal stresses (``sidprep reduce --stress``, the HDF5 group
``/stress``) turn them into stresses at its nodes.  The von Mises stress of every node at every
sample comes from one matrix product per block of samples with the deviator of the modal
stresses, sigma_v(t) = |W S q(t)| (W = sidprep.sid.stress.DEVIATOR_ROWS, S the (6 ns, nq) stress
modes): the envelope (largest over the run at every node) and the hot spots follow without
holding every tensor; the full tensors are formed only at the nodes asked for.

Only the SID side of sidprep is imported (the solver never imports the FE side); an analytical
Beam declared in the scene gets its stress modes from sidprep.reduction.beam (numpy only).
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sidprep.errors import InputError
from sidprep.reduction.beam import BEAM_TABLE_KEYS, beam_options_from_table, beam_sid
from sidprep.sid.io import read_sid
from sidprep.sid.io.atomic import atomic_path
from sidprep.sid.stress import DEVIATOR_ROWS, STRESS_ORDER, StressModes, principal_stresses, von_mises
from sidprep.solver.fatigue import miner_damage, signed_abs_max_principal
from sidprep.solver.results import read_results
from sidprep.tables import parse_toml


#: hot spots reported by default
DEFAULT_HOT_SPOTS = 5
#: two hot spots lie at least this fraction of the body's size (bounding-box diagonal) apart
HOT_SPOT_SEPARATION = 0.05
#: samples per matrix product (bounds the temporaries to SAMPLE_BLOCK x 5 ns doubles)
SAMPLE_BLOCK = 512
#: precision of the envelope's matrix products (von_mises_envelope)
ENVELOPE_DTYPE = np.float32
#: a point given with --at must lie within this many node spacings (median distance between
#: neighbouring stress nodes) of the nearest one
AT_DISTANCE_SPACINGS = 3.0


@dataclass(frozen=True)
class HotSpot:
    """The largest von Mises stress of a node over the run: node id, position (3,) m in the body
    frame, time s, von_mises Pa."""

    node: int
    position: np.ndarray
    time: float
    von_mises: float

    def as_dict(self) -> dict:
        return {"node": self.node, "position": self.position.tolist(), "time": self.time,
                "von_mises": self.von_mises}


@dataclass(frozen=True)
class NodeHistory:
    """Stress history at one node: node id; position (3,) m; distance (m) from the point asked
    for; sigma (nt, 6) Pa in STRESS_ORDER; von_mises (nt,) Pa; principal (nt, 3) Pa largest first
    or None."""

    node: int
    position: np.ndarray
    distance: float
    sigma: np.ndarray
    von_mises: np.ndarray
    principal: np.ndarray | None = None

    def as_dict(self, time: np.ndarray) -> dict:
        """JSON-ready: node, position (m), time (s), von_mises (Pa per sample), the six components."""
        out = {"node": self.node, "position": self.position.tolist(), "distance": self.distance,
               "time": time.tolist(), "von_mises": self.von_mises.tolist(),
               **{f"sigma_{c}": self.sigma[:, i].tolist() for i, c in enumerate(STRESS_ORDER)}, "unit": "Pa"}
        if self.principal is not None:
            out.update({f"sigma_{i + 1}": self.principal[:, i].tolist() for i in range(3)})
        return out


@dataclass(frozen=True)
class StressRecovery:
    """What ``recover_stress`` returns for one body.

    body, sid (path of the SID file, or "analytical Beam of the scene"); time (nt,) s; node_ids (ns,), points (ns, 3) m of the stress
    nodes; envelope (ns,) largest von Mises over the run, Pa, at envelope_time (ns,) s;
    hot_spots : HotSpot tuple, largest first; hot_spot_histories : NodeHistory per hot spot;
    history : NodeHistory at the node nearest to ``at``, or None.
    """

    body: str
    sid: str
    time: np.ndarray
    node_ids: np.ndarray
    points: np.ndarray
    envelope: np.ndarray
    envelope_time: np.ndarray
    hot_spots: tuple
    hot_spot_histories: tuple
    history: NodeHistory | None = None


def sid_path(source: str, results_path: Path) -> Path:
    """The SID file a results file names: the absolute path the run recorded; else (a moved folder,
    or a path recorded relative to the run's folder) relative to the results file's folder, the
    file of that name beside it, and last relative to the current folder - so that a file of the
    same name in the current folder never stands in for the run's own."""
    source_path = Path(source)
    beside = (results_path.parent / source, results_path.parent / source_path.name)
    for candidate in ((source_path,) if source_path.is_absolute() else ()) + beside + (source_path,):
        if candidate.is_file():
            return candidate
    raise InputError(f"{results_path}: the SID file {source} of the body is not found; run `sidprep stress` "
                     "from the folder of the simulation or next to the SID file")


def beam_stress_modes(scene_text: str, body: str, results_path: Path) -> StressModes:
    """The stress modes of an analytical Beam declared inline in the run's scene (kept in the results
    file): its SID rebuilt from the scene's [bodies.NAME] table (sidprep.reduction.beam)."""

    table = parse_toml(scene_text, f"{results_path} (its scene)").get("bodies", {}).get(body, {})
    beam = {key: value for key, value in table.items() if key in BEAM_TABLE_KEYS}
    return beam_sid(beam_options_from_table(beam, f"{results_path}: scene [bodies.{body}]")).stress


def body_stress_modes(results_path: Path, rf, body: str | None) -> tuple[str, str, StressModes]:
    """(body name, its SID path or "analytical Beam of the scene", its StressModes) of the body asked
    for (or the only flexible body)."""
    bodies = dict(rf.bodies)
    beams = [n for n, b in bodies.items() if b.kind == "beam"]
    flexible = [n for n, b in bodies.items() if b.kind == "flexible" and b.source] + beams
    if body is None:
        if len(flexible) != 1:
            raise InputError(f"{results_path}: {len(flexible)} flexible bodies (SID file or Beam) "
                             f"({', '.join(flexible) or 'none'}); choose one with --body NAME")
        body = flexible[0]
    if body not in bodies:
        raise InputError(f"{results_path}: no body {body!r}; bodies: {', '.join(bodies) or 'none'}")
    if body not in flexible:
        raise InputError(f"{results_path}: body {body!r} is {bodies[body].kind or 'not flexible'} with no SID "
                         f"file, so it has no stress modes; choose one of: {', '.join(flexible) or 'none'}")
    if body in beams:
        return body, "analytical Beam of the scene", beam_stress_modes(rf.scene.get("text", ""), body, results_path)
    path = sid_path(bodies[body].source, results_path)
    sid = read_sid(path, physical="error")         # non-finite modal stresses included
    if sid.stress is None:
        raise InputError(f"{path}: the SID of body {body!r} has no modal stresses; reduce it again with "
                         "`sidprep reduce MESH --stress` and re-run the simulation")
    return body, str(path), sid.stress


def von_mises_envelope(stress: StressModes, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Largest von Mises stress over all samples at every node, and the sample where it occurs:
    q (nt, nq) -> (envelope (ns,) Pa, sample index (ns,)).

    One matrix product per SAMPLE_BLOCK samples with the deviatoric stress modes D = W S, laid out
    (5, ns, nq) so that each deviator component is a contiguous block; in single precision
    (ENVELOPE_DTYPE: relative error ~1e-6, far below the modal truncation; the hot spots' values
    and histories are then recomputed in double precision at their nodes).
    """
    ns = stress.n_nodes
    D = np.einsum("rc,sck->rsk", DEVIATOR_ROWS, stress.modes).reshape(5 * ns, -1).astype(ENVELOPE_DTYPE)
    qs = np.asarray(q, dtype=ENVELOPE_DTYPE)
    envelope = np.full(ns, -1.0, dtype=ENVELOPE_DTYPE)
    where = np.zeros(ns, dtype=np.int64)
    for start in range(0, qs.shape[0], SAMPLE_BLOCK):
        d = (qs[start:start + SAMPLE_BLOCK] @ D.T).reshape(-1, 5, ns)
        np.square(d, out=d)
        vm2 = d.sum(axis=1)
        k = np.argmax(vm2, axis=0)
        peak = vm2[k, np.arange(ns)]
        better = peak > envelope
        envelope[better], where[better] = peak[better], start + k[better]
    return np.sqrt(np.maximum(envelope, 0.0)).astype(float), where


def hot_spot_nodes(envelope: np.ndarray, points: np.ndarray, count: int) -> list[int]:
    """Rows of the ``count`` largest envelope values, each HOT_SPOT_SEPARATION x the body size away
    from the ones before (so that one notch is not reported as its neighbouring nodes)."""
    radius = HOT_SPOT_SEPARATION * float(np.linalg.norm(np.ptp(points, axis=0)))
    chosen: list[int] = []
    for i in np.argsort(envelope)[::-1]:
        if all(np.linalg.norm(points[i] - points[j]) >= radius for j in chosen):
            chosen.append(int(i))
            if len(chosen) == count:
                break
    return chosen


def node_history(stress: StressModes, q: np.ndarray, row: int, distance: float = 0.0,
                 principal: bool = False) -> NodeHistory:
    """The stress history at row ``row`` of the stress nodes."""
    sigma = stress.at(q, [row])[:, 0, :]
    return NodeHistory(int(stress.node_ids[row]), stress.points[row], distance, sigma, von_mises(sigma),
                       principal_stresses(sigma) if principal else None)


def nearest_node(stress: StressModes, at, body: str) -> tuple[int, float]:
    """(row, distance m) of the stress node nearest to the point ``at`` (body frame, m); InputError
    when it lies more than AT_DISTANCE_SPACINGS node spacings from every node."""
    from scipy.spatial import cKDTree  # deferred: 0.15 s import

    tree = cKDTree(stress.points)
    distance, row = tree.query(np.asarray(at, dtype=float))
    spacing = float(np.median(tree.query(stress.points, k=2)[0][:, 1]))
    if distance > AT_DISTANCE_SPACINGS * spacing:
        raise InputError(f"--at {','.join(f'{v:g}' for v in at)}: {distance:.4g} m from the nearest {stress.scope} "
                         f"node of body {body!r} (node spacing {spacing:.3g} m); give a point on the body's "
                         f"surface in its SID frame, m (bounding box {np.round(stress.points.min(axis=0), 4).tolist()} "
                         f"to {np.round(stress.points.max(axis=0), 4).tolist()})")
    return int(row), float(distance)


def recover_stress(results, body: str | None = None, *, at=None, hot_spots: int = DEFAULT_HOT_SPOTS,
                   principal: bool = False) -> StressRecovery:
    """Stress of a flexible body over a simulation: envelope, hot spots and their histories, and
    the history at the node nearest to ``at``.

    Parameters
    ----------
    results : path of a results file (``sidprep simulate``)
    body : name of a flexible body (None: the only one)
    at : (3,) point in the body's SID frame, m, or None
    hot_spots : number of hot spots (largest von Mises over the run, HOT_SPOT_SEPARATION apart)
    principal : also the principal stresses of the histories

    Returns
    -------
    StressRecovery
    """
    if at is not None and (len(at) != 3 or not np.all(np.isfinite(np.asarray(at, dtype=float)))):
        raise InputError(f"--at {','.join(map(str, at))}: give three finite coordinates X,Y,Z (m, body frame)")
    path = Path(results)
    rf = read_results(path)
    name, sid_file, stress = body_stress_modes(path, rf, body)
    history_at = None if at is None else nearest_node(stress, at, name)
    q = np.asarray(rf.result.bodies[name].q, dtype=float)
    if q.shape[1] != stress.modes.shape[2]:
        raise InputError(f"{sid_file}: {stress.modes.shape[2]} stress modes but the results hold {q.shape[1]} "
                         f"modal coordinates for body {name!r}; re-run the simulation with this SID")
    envelope, where = von_mises_envelope(stress, q)
    t = np.asarray(rf.result.t, dtype=float)
    rows = hot_spot_nodes(envelope, stress.points, hot_spots)
    histories = tuple(node_history(stress, q, r, principal=principal) for r in rows)
    spots = tuple(HotSpot(h.node, h.position, float(t[np.argmax(h.von_mises)]), float(h.von_mises.max()))
                  for h in histories)
    history = None if history_at is None else node_history(stress, q, *history_at, principal=principal)
    return StressRecovery(name, str(sid_file), t, stress.node_ids, stress.points, envelope, t[where],
                          spots, histories, history)


def _history_columns(history: NodeHistory) -> list[tuple[str, np.ndarray]]:
    cols = [(f"node{history.node}.von_mises [Pa]", history.von_mises)]
    cols += [(f"node{history.node}.sigma_{c} [Pa]", history.sigma[:, i]) for i, c in enumerate(STRESS_ORDER)]
    if history.principal is not None:
        cols += [(f"node{history.node}.sigma_{i + 1} [Pa]", history.principal[:, i]) for i in range(3)]
    return cols


def write_histories_csv(recovery: StressRecovery, path) -> Path:
    """CSV of the stress histories at the hot spots (and at the --at node): ``time [s]`` and per
    node its von Mises stress, the six components (and the principal stresses), Pa."""


    histories = list(recovery.hot_spot_histories) + ([recovery.history] if recovery.history is not None else [])
    columns = [c for h in histories for c in _history_columns(h)]
    path = Path(path)
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["time [s]"] + [name for name, _ in columns])
        data = np.column_stack([recovery.time] + [values for _, values in columns])
        w.writerows(data.tolist())
    return path


def write_envelope_csv(recovery: StressRecovery, path) -> Path:
    """CSV of the envelope: node, x, y, z (m, body frame), largest von Mises over the run (Pa), its time (s)."""


    path = Path(path)
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["node", "x [m]", "y [m]", "z [m]", "von_mises_max [Pa]", "time [s]"])
        for node, p, v, t in zip(recovery.node_ids, recovery.points, recovery.envelope, recovery.envelope_time):
            w.writerow([int(node), *map(float, p), float(v), float(t)])
    return path


@dataclass(frozen=True)
class StressReport:
    """``sidprep stress`` in one call: the StressRecovery, the Palmgren-Miner damage per node of
    the histories ({node id: sidprep.solver.fatigue.FatigueDamage}, with an S-N curve) and the CSV
    files written ({"csv", "envelope"}: Path)."""

    recovery: StressRecovery
    fatigue: dict
    files: dict
    curve: object = None


def stress_report(results, body: str | None = None, *, at=None, hot_spots: int = DEFAULT_HOT_SPOTS,
                  principal: bool = False, curve=None, histories_csv=None, envelope_csv=None) -> StressReport:
    """``recover_stress`` plus the fatigue hand-off and the files: with ``curve`` (a Basquin S-N
    curve, sidprep.solver.fatigue) the rainflow count (ASTM E1049-85) of each history's signed
    abs-max principal stress and its Palmgren-Miner damage; ``histories_csv`` / ``envelope_csv``:
    paths of the CSV tables to write (write_histories_csv, write_envelope_csv)."""
    rec = recover_stress(results, body, at=at, hot_spots=hot_spots, principal=principal or curve is not None)
    fatigue = {}
    if curve is not None:
        for h in rec.hot_spot_histories + ((rec.history,) if rec.history else ()):
            fatigue[h.node] = miner_damage(signed_abs_max_principal(h.principal), curve)
    files = {}
    if histories_csv:
        files["csv"] = write_histories_csv(rec, histories_csv)
    if envelope_csv:
        files["envelope"] = write_envelope_csv(rec, envelope_csv)
    return StressReport(rec, fatigue, files, curve)
