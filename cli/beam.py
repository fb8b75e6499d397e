"""``sidprep beam``: the SID of an analytical Euler-Bernoulli beam (sidprep.reduction.beam)."""

from __future__ import annotations

from sidprep.cli.options import MaterialList


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "beam", help="SID of an analytical Euler-Bernoulli beam (closed-form eigenforms, with stiffening)",
        description="Write the SID (.sid.h5, optionally .SID_FEM) of a straight homogeneous beam along x "
                    "from x = 0 (body frame) to x = L, from closed-form eigenforms.")
    p.add_argument("--length", type=float, required=True, help="beam length L, m")
    p.add_argument("--section", required=True,
                   help="profile:dims in m, e.g. rectangle:b,h  circle:d  tube:D,d  rectangular_tube:b,h,t  "
                        "I:b,h,tw,tf  T:b,h,tw,tf  U:b,h,tw,tf  general:A,Iy,Iz,J (Iy: bending in xz)")
    p.add_argument("--material", action=MaterialList,
                   help="built-in material name (or label of --E --nu --rho); '--material list' prints them")
    p.add_argument("--E", type=float, help="Young's modulus, Pa")
    p.add_argument("--nu", type=float, help="Poisson's ratio")
    p.add_argument("--rho", type=float, help="density, kg/m^3")
    p.add_argument("--bc", default="free-free",
                   help="free-free | clamped-free | pinned-pinned | pinned-free | clamped-pinned | clamped-clamped")
    p.add_argument("--modes", required=True, help="eigenforms per kind, e.g. xz:1-7,xy:1-2,torsion:1,axial:1")
    p.add_argument("--damping", default="0", help="modal damping ratio, one for all or one per mode (comma list)")
    p.add_argument("--frames", default="", help="extra frames at relative positions xsi, e.g. 0.5,0.75")
    p.add_argument("--sid-fem", action="store_true", help="also write <stem>.SID_FEM")
    p.add_argument("-o", "--output", default="beam.sid.h5", help="output .sid.h5 file")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(func=run)


def run(args) -> int:
    import json

    from sidprep.jobs.output import write_beam_files
    from sidprep.reduction.beam import beam_options_from_table

    table = {k: getattr(args, k) for k in ("length", "section", "material", "E", "nu", "rho", "bc", "modes",
                                           "damping", "frames") if getattr(args, k) not in (None, "")}
    options = beam_options_from_table(table, "sidprep beam")
    summary = write_beam_files(options, args.output, sid_fem=args.sid_fem)
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        print(f"wrote {', '.join(summary['files'].values())}: mass {summary['mass_kg']:.6g} kg")
        for label in summary["labels"]:
            print(f"  {label}")
    return 0
