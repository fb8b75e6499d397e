"""``sidprep beam``: the SID of an analytical Euler-Bernoulli beam (sidprep.reduction.beam)."""

from __future__ import annotations

from sidprep.cli.options import add_json, add_material, add_output, add_quiet, add_sid_files

#: the kinds of eigenform a count (--modes N) chooses from, lowest frequencies first
COUNTED_KINDS = ("xz", "xy", "torsion", "axial")


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "beam", help="SID of an analytical Euler-Bernoulli beam (closed-form eigenforms, with stiffening)",
        description="Write the SID (.sid.h5, .SID_FEM) of a straight homogeneous beam along x "
                    "from x = 0 (body frame) to x = L, from closed-form eigenforms. Lengths in m, SI units.")
    p.add_argument("--length", type=float, required=True, help="beam length L, m")
    p.add_argument("--section", required=True,
                   help="profile:dims in m, e.g. rectangle:b,h  circle:d  tube:D,d  rectangular_tube:b,h,t  "
                        "I:b,h,tw,tf  T:b,h,tw,tf  U:b,h,tw,tf  general:A,Iy,Iz,J (Iy: bending in xz)")
    add_material(p)
    p.add_argument("--bc", default="free-free",
                   help="free-free | clamped-free | pinned-pinned | pinned-free | clamped-pinned | clamped-clamped")
    p.add_argument("--modes", required=True, metavar="N|KIND:RANGE,...",
                   help="eigenmodes kept: a count N (the N lowest of all kinds), or per kind, e.g. "
                        "xz:1-7,xy:1-2,torsion:1,axial:1")
    p.add_argument("--damping", default="0", help="modal damping ratio, one for all or one per mode (comma list)")
    p.add_argument("--frames", default="", help="extra frames at relative positions xsi, e.g. 0.5,0.75")
    add_output(p, "OUT.sid.h5", "./beam.sid.h5")
    add_sid_files(p)
    add_json(p)
    add_quiet(p)
    p.set_defaults(func=run)


def lowest_forms(table: dict, count: int) -> str:
    """The --modes spec of the ``count`` lowest-frequency eigenforms of the beam ``table`` (all kinds)."""
    from sidprep.reduction.beam import beam_options_from_table, eigenforms

    every = ",".join(f"{kind}:1-{count}" for kind in COUNTED_KINDS)
    forms = sorted(eigenforms(beam_options_from_table({**table, "modes": every}, "sidprep beam")),
                   key=lambda f: f.omega)[:count]
    return ",".join(f"{f.kind}:{f.ordinal}" for f in forms)


def run(args) -> int:
    import json

    from sidprep.errors import InputError
    from sidprep.jobs.output import write_beam_files
    from sidprep.reduction.beam import beam_options_from_table

    table = {k: getattr(args, k) for k in ("length", "section", "material", "E", "nu", "rho", "bc", "modes",
                                           "damping", "frames") if getattr(args, k) not in (None, "")}
    if not any(k in table for k in ("material", "E", "nu", "rho")):
        table["material"] = "steel"
    if args.modes.strip().isdigit():
        if not 1 <= int(args.modes) <= 50:
            raise InputError(f"--modes {args.modes}: give a count from 1 to 50, or kinds, e.g. xz:1-3")
        table["modes"] = lowest_forms(table, int(args.modes))
    options = beam_options_from_table(table, "sidprep beam")
    summary = write_beam_files(options, args.output or "beam.sid.h5", sid_fem=args.sid_fem is not False,
                               obj=args.obj is not False)
    if args.json:
        print(json.dumps(summary, indent=2))
    elif args.quiet:
        print("\n".join(summary["files"].values()))
    else:
        print(f"wrote {', '.join(summary['files'].values())}: mass {summary['mass_kg']:.6g} kg")
        for label in summary["labels"]:
            print(f"  {label}")
    return 0
