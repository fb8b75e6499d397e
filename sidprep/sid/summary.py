"""What a SID file contains, as a summary (``sidprep info``, ``sidprep.sid_info``)."""

from __future__ import annotations

import math

import numpy as np

from sidprep.sid.check import Check
from sidprep.sid.checks import sid_checks
from sidprep.sid.io import read_sid
from sidprep.sid.model import inertia_matrix
from sidprep.sid.stress import STRESS_ORDER, von_mises


def sid_info(path) -> dict:
    """Read a SID file (.sid.h5 / .SID_FEM), run its model checks, return ``body_summary``."""
    sid = read_sid(path)
    return body_summary(sid, sid_checks(sid))


def check_sid(path) -> dict:
    """Read a SID file (.sid.h5 / .SID_FEM) as it is (its physical checks not enforced on reading)
    and re-run its model checks: {name: Check} (what ``sidprep check`` prints)."""
    return sid_checks(read_sid(path, physical="off"))


def body_summary(sid, checks: dict) -> dict:
    """Summary of a SID: mass, CM, inertia about O and about the CM, modes, nodes, and ``checks``
    ({name: Check}); :func:`strict_json` makes it JSON."""
    with np.errstate(all="ignore"):    # a damaged SID (NaN, inf, m = 0) is summarised as it is; checks flag it
        return _summary(sid, checks)


def _summary(sid, checks: dict) -> dict:
    c = sid.mdCM.M0[:, 0] / sid.mass if sid.mass else np.zeros(3)
    I_o = inertia_matrix(sid.J.M0[:, 0])
    I_cm = I_o - sid.mass * (c @ c * np.eye(3) - np.outer(c, c))     # parallel-axis theorem
    finite = lambda x: [float(v) if np.isfinite(v) else None for v in x]  # noqa: E731
    meta = sid.metadata if isinstance(sid.metadata, dict) else {}
    return {
        "mass_kg": float(sid.mass),
        "center_of_mass": finite(c),
        "inertia": {"about_origin": I_o.tolist(), "about_center_of_mass": I_cm.tolist(),
                    "unit": "kg m^2", "note": "products of inertia are negative integrals (Ixy = -int xy dm)"},
        "n_modes": sid.nq,
        "frequencies_hz": finite(np.asarray(sid.frequencies_hz, dtype=float)),
        "mode_kinds": list(sid.mode_kinds),
        "labels": list(sid.labels),
        "nodes": [{"id": n.node_id, "name": n.name, "position": finite(n.origin.M0[:, 0])}
                  for n in sid.nodes],
        "units": sid.units,
        "geometric_stiffness": sorted(sid.stiffening),
        "surface_triangles": 0 if sid.surface is None else int(len(sid.surface.triangles)),
        "sid_fem_dialect": meta.get("sid_fem_dialect"),
        "stress": stress_summary(sid.stress),
        "checks": checks,
    }


def stress_summary(stress) -> dict | None:
    """The modal stresses of a SID (None without): nodes, scope, component order, and per mode the
    largest von Mises stress over the nodes (Pa per unit q)."""
    if stress is None:
        return None

    return {"nodes": stress.n_nodes, "scope": stress.scope, "component_order": list(STRESS_ORDER),
            "unit": "Pa per unit modal coordinate", "method": stress.method,
            "max_von_mises_per_mode": von_mises(stress.modes.transpose(0, 2, 1)).max(axis=0).tolist()}


def strict_json(value):
    """``value`` with numpy types as Python numbers, checks as their dicts and non-finite floats as
    None (valid JSON)."""


    if isinstance(value, Check):
        value = value.as_dict()
    if isinstance(value, dict):
        return {str(k): strict_json(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [strict_json(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value
