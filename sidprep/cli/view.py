"""``sidprep view``: one self-contained HTML page showing a SID body and its modes."""

from __future__ import annotations

from sidprep.cli.options import add_output, add_quiet


def register(subparsers) -> None:
    p = subparsers.add_parser("view", help="HTML page of a SID body: surface, nodes, frame, animated modes",
                              description="Write one self-contained HTML page (opens offline) showing the "
                                          "body's surface, interface nodes and frame, each mode animated on "
                                          "demand, and its mass, CM, inertia and checks.")
    p.add_argument("sid", metavar="BODY", help="SID file (.sid.h5 or .SID_FEM)")
    p.add_argument("--surface", metavar="SURFACE.obj", help="surface to animate (body frame, SID units); "
                   "default: the SID's surface modes, else the convex hull of its nodes")
    add_output(p, "PAGE.html", "./<BODY stem>.html")
    add_quiet(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from sidprep.cli.options import default_output
    from sidprep.view.modes import write_mode_page

    path = write_mode_page(args.sid, default_output(args.sid, ".html", args.output), args.surface)
    print(path if args.quiet else f"wrote {path}")
    return 0
