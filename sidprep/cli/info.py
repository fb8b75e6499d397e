"""``sidprep info FILE [--json]``: what a SID file (.sid.h5 or .SID_FEM) contains."""

from __future__ import annotations

from sidprep.cli.options import add_json, add_quiet


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "info", help="summary of a SID file (.sid.h5 or .SID_FEM): mass, CM, inertia, modes, nodes, checks",
        description="Print the rigid-body data, the modal coordinates, the nodes and the model checks of a "
                    "SID file; --json gives the same as one JSON object.")
    p.add_argument("file", metavar="FILE", help=".sid.h5 or .SID_FEM file")
    add_json(p)
    add_quiet(p)                      # the summary is the requested output: printed with -q too
    p.set_defaults(func=run)


def format_table(summary: dict) -> str:
    """Human-readable form of ``body_summary``."""
    from sidprep.sid.checks import format_checks
    from sidprep.errors import printable

    def row(v):
        return "  ".join(f"{float('nan') if x is None else x: .6e}" for x in v)

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
        lines.append(f"  {k + 1:4d}  {freq} Hz  {printable(kind):<10s} {printable(label)}")
    lines.append(f"nodes           {len(summary['nodes'])}")
    for n in summary["nodes"]:
        lines.append(f"  {n['id']:>8d}  {row(n['position'])} m  {printable(n['name'])}")
    if summary["geometric_stiffness"]:
        lines.append(f"stiffening parts (raw): {', '.join(summary['geometric_stiffness'])}")
    if summary["sid_fem_dialect"]:
        d = summary["sid_fem_dialect"]
        lines.append(f"SID_FEM dialect: {d['name']} (m1 {d['m1_index_order']}, J {d['J']}, "
                     f"Gr {d['Gr_layout']}, Ge {d['Ge_layout']})")
    if summary.get("stress"):
        st = summary["stress"]
        lines.append(f"modal stresses  {st['nodes']} {st['scope']} nodes, components {','.join(st['component_order'])}, "
                     f"max von Mises per mode {', '.join(f'{v:.3g}' for v in st['max_von_mises_per_mode'])} Pa/[q]")
    lines.append("checks:")
    lines.append(format_checks(summary["checks"]))
    return "\n".join(lines)


def run(args) -> int:
    import json

    from sidprep.sid.summary import sid_info, strict_json

    summary = sid_info(args.file)
    if args.json:
        print(json.dumps(strict_json(summary), indent=1, allow_nan=False))
    else:
        print(format_table(summary))
    return 0
