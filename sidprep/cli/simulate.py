"""``sidprep simulate SCENE``: parse the options, call ``sidprep.solver.simulate_scene`` (load, simulate, write
the results and the files asked for) and print its report."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from sidprep.cli.options import add_csv, add_json, add_output, add_quiet, process_setup
from sidprep.solver.integrators.settings import METHODS

def positive(text: str) -> float:
    """argparse type: a number > 0."""
    value = float(text)
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {text}")
    return value


def solver_overrides(args) -> dict:
    """The SolverSettings fields the command line sets (h, method, rtol, output_dt)."""
    given = {"h": args.step, "method": args.method, "rtol": args.rtol,
             "output_dt": None if args.rate is None else 1.0 / args.rate}
    return {key: value for key, value in given.items() if value is not None}


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "simulate", help="simulate a scene of flexible (SID) and rigid bodies",
        description="Simulate a TOML scene (docs/scenes.md): flexible bodies from SID files, rigid bodies, "
                    "joints, drivers and forces. Writes an HDF5 results file; optionally a PNG plot and a CSV of "
                    "the scene's [output] signals and a ParaView animation (.pvd + .vtu). Prints the effects "
                    "report: which FFR terms were included, which were left out and how large they were.")
    p.add_argument("scene", metavar="SCENE", help="scene file (.toml)")
    add_output(p, "RESULTS.h5", "./<scene name>.results.h5: [scene] name, else the folder of a scene.toml, else "
                                "the file's stem")
    p.add_argument("--t-end", type=float, metavar="T", help="end time in s (overrides [solver] t_end)")
    solver = p.add_argument_group("solver settings (override the scene's [solver] and [output] rate)")
    solver.add_argument("--step", type=positive, metavar="H", help="step size in s ([solver] step)")
    solver.add_argument("--method", choices=METHODS, help="integration method ([solver] method)")
    solver.add_argument("--rtol", type=positive, metavar="RTOL",
                        help="relative tolerance of the step-size control ([solver] rtol)")
    solver.add_argument("--rate", type=positive, metavar="HZ", help="output samples per second ([output] rate)")
    p.add_argument("--plot", action="store_true", help="write <results>.png of the [output] signals")
    add_csv(p)
    p.add_argument("--animate", action="store_true", help="write <results>.pvd + <results>_vtu/ for ParaView")
    add_json(p)
    p.add_argument("--list-signals", action="store_true",
                   help="print the signal names of the scene (for [output] signals) and exit without simulating")
    add_quiet(p)
    p.set_defaults(func=run, process_setup=process_setup)


def not_a_scene_hint(path: str) -> str:
    """What to do with a file that is not a scene: a SID is a body a scene names, a mesh is reduced first."""
    name = Path(path).name.lower()
    if name.endswith(".results.h5"):
        return f"it is a results file: plot it (sidprep plot {path} SIGNAL...) or animate it (sidprep animate {path})"
    if name.endswith((".sid.h5", ".sid_fem", ".h5")):
        return (f"a SID file is one body: write a scene that names it ([bodies.NAME] type = \"flexible\", "
                f"sid = \"{Path(path).name}\"; docs/scenes.md, e.g. examples/flexible_pendulum/scene.toml)")
    return f"write a scene (docs/scenes.md); a mesh is reduced first: sidprep reduce {path}"


def run(args) -> int:
    from sidprep.errors import WARNING_PREFIX, note_line
    from sidprep.solver.results import json_safe
    from sidprep.solver.simulate_scene import scene_signals, simulate_scene
    from sidprep.tables import require_toml

    require_toml(args.scene, "scene file", not_a_scene_hint(args.scene))
    if args.list_signals:
        print("\n".join(scene_signals(args.scene)))
        return 0
    run = simulate_scene(args.scene, args.output, t_end=args.t_end, plot=args.plot, csv=args.csv,
                         animate=args.animate, verbose=not args.quiet, **solver_overrides(args))
    s = run.summary()
    warning = s["energy"].get("warning")
    if not args.quiet:
        for note in run.notes:
            print(note_line(note), file=sys.stderr)
    else:                               # the report's warnings (an effect left out that matters) stay
        for line in run.result.effects.warnings:
            print(note_line(line), file=sys.stderr)
    if warning:
        print(note_line(WARNING_PREFIX + warning), file=sys.stderr)
    if args.json:
        if not args.quiet:
            print(run.result.effects.text(), file=sys.stderr)
        print(json.dumps(json_safe(s)))
    elif args.quiet:
        for path in s["outputs"].values():
            print(path)
    else:
        e = s["energy"]
        print(run.result.effects.text())
        print(f"{run.scene.title}: {s['steps']} steps to t = {s['t_end']:g} s in {s['cpu_s']:.2f} s CPU; "
              f"energy {e['initial']:.6g} -> {e['final']:.6g} J (balance error {e.get('balance_error', 0.0):.2e} "
              "of the energy exchanged)")
        for kind, path in s["outputs"].items():
            print(f"  {kind}: {path}")
    return 0
