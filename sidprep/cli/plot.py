"""``sidprep plot RESULTS.h5 [SIGNALS...] [-o OUT.png]``: plot signals of an existing results file."""

from __future__ import annotations

from sidprep.cli.options import add_output, add_quiet


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "plot", help="plot signals of a results file of sidprep simulate (PNG); no signal: a default figure",
        description="Plot the named signals of a results file (one panel per unit, against time) into a PNG, "
                    "without re-running the simulation. Without signals: the energy and each body's main "
                    "coordinates (its position component that moves most, its largest modal coordinate) and "
                    "each joint's coordinate, and the list of the file's signal names on stderr.")
    p.add_argument("results", metavar="RESULTS.h5", help="results file of sidprep simulate")
    p.add_argument("signals", nargs="*", metavar="SIGNAL",
                   help="e.g. hinge.coordinate bar.q.1 energy.total (none: the default figure)")
    add_output(p, "OUT.png", "./<RESULTS stem>.png")
    add_quiet(p)
    p.set_defaults(func=run)


def run(args) -> int:
    import sys

    from sidprep.cli.options import default_output
    from sidprep.solver.results import plot_results

    plot = plot_results(args.results, args.signals, default_output(args.results, ".png", args.output))
    if not args.signals and not args.quiet:
        print(f"{args.results}: signals (plot any of them: sidprep plot {args.results} SIGNAL...):\n  "
              + "\n  ".join(plot.available), file=sys.stderr)
    print(plot.path if args.quiet else f"wrote {plot.path}")
    return 0
