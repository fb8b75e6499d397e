"""``sidprep stress RESULTS.h5``: stresses of a flexible body over a simulation (hot spots, history at
a point, CSV and fatigue hand-off)."""

from __future__ import annotations

from sidprep.cli.options import add_csv, add_json, add_output, add_quiet


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "stress", help="stress of a flexible body over a simulation: hot spots, history at a point, fatigue",
        description="sigma(t) = sum_k sigma_k q_k(t) from the modal coordinates of a results file and the modal "
                    "stresses of the body's SID (`sidprep reduce --stress`). Prints the hot spots (largest von "
                    "Mises stress over the run: node, position in the body frame, time, value) and, with --at, "
                    "the history at the surface node nearest to a point. --json: node, position, time, von_mises "
                    "and sigma_xx ... sigma_zx per sample (Pa).")
    p.add_argument("results", metavar="RESULTS.h5", help="results file of sidprep simulate")
    p.add_argument("--body", metavar="NAME", help="flexible body (default: the only one)")
    p.add_argument("--at", metavar="X,Y,Z", help="point in the body's SID frame (m): history at the nearest node")
    p.add_argument("--hot-spots", type=int, default=None, metavar="N", help="number of hot spots (default 5)")
    p.add_argument("--principal", action="store_true", help="also the principal stresses of the histories")
    add_json(p)
    add_csv(p)
    p.add_argument("--envelope", action="store_true",
                   help="also write the largest von Mises stress of every node as CSV (<output stem>.envelope.csv)")
    add_output(p, "OUT.csv", "./<RESULTS stem>.stress.csv: the histories at the hot spots and --at, with --csv")
    add_quiet(p)
    p.add_argument("--sn", metavar="C=VALUE,m=VALUE",
                   help="Basquin S-N curve N = C dsigma^-m (stress range in Pa): rainflow count (ASTM E1049) of the "
                        "signed abs-max principal stress and Palmgren-Miner damage at each hot spot")
    p.set_defaults(func=run)


def parse_point(text: str):
    """"X,Y,Z" -> three floats (m); InputError otherwise."""
    from sidprep.errors import InputError

    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if len(values) != 3:
        raise InputError(f"--at {text}: give three numbers X,Y,Z (m, in the body's SID frame)")
    return values


def csv_outputs(args) -> dict:
    """{"csv": histories, "envelope": envelope} paths asked for: -o or ./<results stem>.stress.csv, and
    <that stem>.envelope.csv; InputError for an -o that is not a .csv file."""
    from pathlib import Path

    from sidprep.cli.options import default_output
    from sidprep.errors import InputError

    out = default_output(args.results, ".stress.csv", args.output)
    if out.suffix.lower() != ".csv":
        raise InputError(f"-o {out}: stress writes CSV tables; name the output OUT.csv")
    if args.output and not (args.csv or args.envelope):
        raise InputError(f"-o {out}: add --csv (the histories) or --envelope (every node's largest stress)")
    stem = out.name[:-len(".stress.csv")] if out.name.endswith(".stress.csv") else Path(out.name).stem
    wanted = {"csv": out, "envelope": out.with_name(stem + ".envelope.csv")}
    return {k: v for k, v in wanted.items() if getattr(args, k)}


def run(args) -> int:
    import json

    from sidprep.errors import InputError
    from sidprep.solver.fatigue import parse_basquin
    from sidprep.solver.stress import DEFAULT_HOT_SPOTS, stress_report

    at = parse_point(args.at) if args.at else None
    wanted = csv_outputs(args)
    curve = parse_basquin(args.sn) if args.sn else None
    count = DEFAULT_HOT_SPOTS if args.hot_spots is None else args.hot_spots
    if count < 1:
        raise InputError(f"--hot-spots {count}: must be >= 1")
    report = stress_report(args.results, args.body, at=at, hot_spots=count, principal=args.principal, curve=curve,
                           histories_csv=wanted.get("csv"), envelope_csv=wanted.get("envelope"))
    rec, fatigue = report.recovery, report.fatigue
    files = {kind: str(path) for kind, path in report.files.items()}
    if args.json:
        out = {"body": rec.body, "sid": rec.sid, "samples": int(len(rec.time)),
               "hot_spots": [s.as_dict() for s in rec.hot_spots], "files": files, "unit": "Pa",
               "fatigue": {str(k): v.as_dict() for k, v in fatigue.items()}}
        if rec.history is not None:
            out.update(rec.history.as_dict(rec.time))
        print(json.dumps(out, allow_nan=False))
        return 0
    if args.quiet:
        for path in files.values():
            print(path)
        return 0
    print(f"body {rec.body} ({rec.sid}): {len(rec.node_ids)} stress nodes, {len(rec.time)} samples, "
          f"t = {rec.time[0]:g} .. {rec.time[-1]:g} s")
    print("hot spots (largest von Mises stress over the run):")
    print(f"  {'node':>8}  {'x [m]':>9} {'y [m]':>9} {'z [m]':>9}  {'time [s]':>9}  {'von Mises [MPa]':>15}"
          + ("  damage" if curve else ""))
    for s in rec.hot_spots:
        extra = f"  {fatigue[s.node].damage:.3g}" if curve else ""
        print(f"  {s.node:>8}  {s.position[0]:9.5f} {s.position[1]:9.5f} {s.position[2]:9.5f}  {s.time:9.5f}  "
              f"{s.von_mises / 1e6:15.3f}{extra}")
    if rec.history is not None:
        h = rec.history
        k = int(h.von_mises.argmax())
        print(f"at node {h.node} ({', '.join(f'{v:.5f}' for v in h.position)} m, {1e3 * h.distance:.2f} mm from the "
              f"point): von Mises max {h.von_mises[k] / 1e6:.3f} MPa at {rec.time[k]:g} s, "
              f"mean {h.von_mises.mean() / 1e6:.3f} MPa"
              + (f", damage {fatigue[h.node].damage:.3g}" if curve else ""))
    if curve:
        print(f"fatigue: rainflow (ASTM E1049-85) of the signed abs-max principal stress, Basquin N = {curve.C:.4g} "
              f"dsigma^-{curve.m:g}, Palmgren-Miner damage per run (1/damage runs to failure)")
    for kind, path in files.items():
        print(f"wrote {path}")
    return 0
