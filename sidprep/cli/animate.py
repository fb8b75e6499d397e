"""``sidprep animate``: the simulated mechanism as a self-contained HTML page or a movie."""

from __future__ import annotations

from sidprep.cli.options import add_output, add_quiet

MOVIE_SUFFIXES = (".html", ".mp4", ".gif")


def register(subparsers) -> None:
    p = subparsers.add_parser("animate", help="HTML page (or .mp4/.gif movie) of a simulated mechanism",
                              description="Animate a results file of `sidprep simulate`: flexible bodies' "
                                          "deformed surfaces coloured by displacement, rigid bodies from "
                                          "their OBJ, a time slider, real or exaggerated deformation, colour by displacement or von Mises stress.")
    p.add_argument("results", metavar="RESULTS.h5", help="results file of sidprep simulate")
    add_output(p, "OUT.html|.mp4|.gif", "./<RESULTS stem>.html")
    p.add_argument("--real", action="store_true", help="movies: true deformation (default exaggerated)")
    p.add_argument("--colour", choices=("displacement", "stress"), default="displacement",
                   help="colour the surfaces by |u| (m) or by the von Mises stress (MPa; the SID needs modal "
                        "stresses, `sidprep reduce --stress`); the page has a switch, this is its start")
    add_quiet(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from sidprep.cli.options import default_output
    from sidprep.errors import InputError
    from sidprep.view.mechanism import write_mechanism_page
    from sidprep.view.movie import write_mechanism_movie

    out = default_output(args.results, ".html", args.output)
    if out.suffix.lower() not in MOVIE_SUFFIXES:
        raise InputError(f"{out}: unknown output type; use .html, .mp4 or .gif")
    if out.suffix.lower() == ".html":
        path = write_mechanism_page(args.results, out, colour=args.colour)
    else:
        path = write_mechanism_movie(args.results, out, exaggerated=not args.real, colour=args.colour)
    print(path if args.quiet else f"wrote {path}")
    return 0
