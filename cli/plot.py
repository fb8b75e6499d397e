"""``sidprep plot RESULTS.h5 [SIGNALS...] [-o OUT.png]``: plot signals of an existing results file."""

from __future__ import annotations


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "plot", help="plot signals of a results file of sidprep simulate (PNG); no signal: list them",
        description="Plot the named signals of a results file (one panel per unit, against time) into a PNG, "
                    "without re-running the simulation. Without signals, list the file's signal names.")
    p.add_argument("results", metavar="RESULTS.h5", help="results file of sidprep simulate")
    p.add_argument("signals", nargs="*", metavar="SIGNAL",
                   help="e.g. hinge.coordinate bar.q.1 energy.total (none: list the names)")
    p.add_argument("-o", "--output", metavar="OUT.png", help="image to write (default ./<RESULTS stem>.png)")
    p.set_defaults(func=run)


def run(args) -> int:
    import sys
    from pathlib import Path

    from sidprep.cli.options import default_output
    from sidprep.errors import InputError
    from sidprep.solver.results import plot_signals, read_results, signal_names

    out = default_output(args.results, ".png", args.output)
    if args.signals and out.suffix.lower() != ".png":
        raise InputError(f"{out}: plot writes PNG images; name the output OUT.png")
    results = read_results(args.results)
    if not args.signals:
        print("\n".join(signal_names(results.result)))
        print(f"{args.results}: give one or more of these signals to plot them: "
              f"sidprep plot {args.results} SIGNAL...", file=sys.stderr)
        return 0
    scene = results.scene.get("path")
    title = Path(args.results).name + (f" ({scene})" if scene else "")
    print(f"wrote {plot_signals(results.result, list(args.signals), out, title=title)}")
    return 0
