"""``sidprep info FILE [--json]``: what a SID file (.sid.h5 or .SID_FEM) contains."""

from __future__ import annotations


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "info", help="summary of a SID file (.sid.h5 or .SID_FEM): mass, CM, inertia, modes, nodes, checks",
        description="Print the rigid-body data, the modal coordinates, the nodes and the model checks of a "
                    "SID file; --json gives the same as one JSON object.")
    p.add_argument("file", metavar="FILE", help=".sid.h5 or .SID_FEM file")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    p.set_defaults(func=run)


def body_summary(sid, checks: dict) -> dict:
    """JSON-ready summary of a SID: mass, CM, inertia about O and about the CM, modes, nodes."""
    import numpy as np

    from sidprep.sid import inertia_matrix

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
        "checks": checks,
    }


def format_table(summary: dict) -> str:
    """Human-readable form of ``body_summary``."""
    from sidprep.checks import format_checks

    def row(v):
        return "  ".join(f"{x: .6e}" for x in v)

    lines = [f"mass            {summary['mass_kg']:.6g} kg   (units {summary['units']})",
             f"centre of mass  {row(summary['center_of_mass'])} m",
             "inertia about the frame origin, kg m^2:"]
    lines += [f"    {row(r)}" for r in summary["inertia"]["about_origin"]]
    lines.append("inertia about the centre of mass, kg m^2:")
    lines += [f"    {row(r)}" for r in summary["inertia"]["about_center_of_mass"]]
    lines.append(f"modes           {summary['n_modes']}")
    for k, (f, kind, label) in enumerate(zip(summary["frequencies_hz"], summary["mode_kinds"],
                                             summary["labels"])):
        freq = "      -     " if f is None else f"{f:12.4f}"
        lines.append(f"  {k + 1:4d}  {freq} Hz  {kind:<10s} {label}")
    lines.append(f"nodes           {len(summary['nodes'])}")
    for n in summary["nodes"]:
        lines.append(f"  {n['id']:>8d}  {row(n['position'])} m  {n['name']}")
    if summary["geometric_stiffness"]:
        lines.append(f"stiffening parts (raw): {', '.join(summary['geometric_stiffness'])}")
    if summary["sid_fem_dialect"]:
        d = summary["sid_fem_dialect"]
        lines.append(f"SID_FEM dialect: {d['name']} (m1 {d['m1_index_order']}, J {d['J']}, "
                     f"Gr {d['Gr_layout']}, Ge {d['Ge_layout']})")
    lines.append("checks:")
    lines.append(format_checks(summary["checks"]))
    return "\n".join(lines)


def strict_json(value):
    """``value`` with numpy types as Python numbers and non-finite floats as None (valid JSON)."""
    import math

    import numpy as np

    if isinstance(value, dict):
        return {str(k): strict_json(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [strict_json(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def run(args) -> int:
    import json

    from sidprep.checks import sid_checks
    from sidprep.io import read_sid

    sid = read_sid(args.file)
    summary = body_summary(sid, sid_checks(sid))
    if args.json:
        print(json.dumps(strict_json(summary), indent=1, allow_nan=False))
    else:
        print(format_table(summary))
    return 0
