"""``sidprep simulate SCENE``: run a TOML scene (docs/scenes.md), write results, plots, animation."""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

from sidprep.cli.options import process_setup
from sidprep.solver.integrators.settings import METHODS

#: signals plotted / exported when the scene's [output] names none
DEFAULT_SIGNALS = ("energy.kinetic", "energy.total")

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
    p.add_argument("-o", "--output", metavar="RESULTS.h5",
                   help="results file (default ./<scene stem>.results.h5); plot, CSV and animation go beside it")
    p.add_argument("--t-end", type=float, metavar="T", help="end time in s (overrides [solver] t_end)")
    solver = p.add_argument_group("solver settings (override the scene's [solver] and [output] rate)")
    solver.add_argument("--step", type=positive, metavar="H", help="step size in s ([solver] step)")
    solver.add_argument("--method", choices=METHODS, help="integration method ([solver] method)")
    solver.add_argument("--rtol", type=positive, metavar="RTOL",
                        help="relative tolerance of the step-size control ([solver] rtol)")
    solver.add_argument("--rate", type=positive, metavar="HZ", help="output samples per second ([output] rate)")
    p.add_argument("--plot", action="store_true", help="write <results>.png of the [output] signals")
    p.add_argument("--csv", action="store_true", help="write <results>.csv of the [output] signals")
    p.add_argument("--animate", action="store_true", help="write <results>.pvd + <results>_vtu/ for ParaView")
    p.add_argument("--json", action="store_true", help="print one JSON summary object on stdout")
    p.add_argument("--list-signals", action="store_true",
                   help="print the signal names of the scene (for [output] signals) and exit without simulating")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress lines on stderr")
    p.set_defaults(func=run, process_setup=process_setup)


def effects_summary(report) -> dict:
    """{"included": {body: [...]}, "left_out": {body: [...]}, "not_in_sid": {...}, "estimates": {body:
    {effect: {"value", "measure"}}}, "warnings": [...]}."""
    out = {"included": {}, "left_out": {}, "not_in_sid": {}, "estimates": report.estimates(),
           "warnings": list(report.warnings)}
    for body, entries in report.bodies.items():
        out["included"][body] = [e.effect for e in entries if e.included]
        out["left_out"][body] = [e.effect for e in entries if not e.included and e.available]
        out["not_in_sid"][body] = [e.effect for e in entries if not e.available]
    return out


def summary(scene, result, outputs: dict) -> dict:
    """The JSON summary of a run (see docs/scenes.md, "Output")."""
    from sidprep.solver.results import energy_summary

    stats = result.stats
    balance = stats.get("energy_balance", {})
    return {
        "scene": str(scene.path),
        "t_end": float(result.t[-1]),
        "steps": int(stats.get("steps", 0)),
        "cpu_s": float(stats.get("cpu_time", float("nan"))),
        "energy": {**energy_summary(result), **{k: balance[k] for k in ("balance_error", "tolerance", "warning")
                                                 if k in balance}},
        "effects": effects_summary(result.effects),
        "bodies": {name: {"position": b.position[-1].tolist(), "rotation": b.rotation[-1].tolist(),
                          "q": b.q[-1].tolist()} for name, b in result.bodies.items()},
        "max_constraint_error": float(result.constraint_error.max()) if len(result.constraint_error) else 0.0,
        "stats": stats,
        "outputs": outputs,
    }


def animation_surfaces(scene) -> dict:
    """{body name: Surface} of every body that has a shape (flexible: SID surface; rigid: OBJ)."""
    from sidprep.sid.io.obj import read_obj
    from sidprep.sid.surface import rigid_surface, sid_surface

    surfaces = {}
    for b in getattr(scene.system, "bodies", ()):          # absolute-nodal beams carry no surface
        src = scene.sources[b.name]
        if src["kind"] in ("flexible", "beam"):
            surfaces[b.name] = sid_surface(b.sid)
        elif src["source"]:
            surfaces[b.name] = rigid_surface(*read_obj(src["source"]), str(src["source"]))
    return surfaces


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
    from sidprep.progress import Phases, SimulationProgress
    from sidprep.tables import require_toml
    from sidprep.solver.results import json_safe, plot_signals, write_csv, write_results
    from sidprep.solver.scene import load_scene, simulate
    from sidprep.errors import WARNING_PREFIX, InputError, SimulationFailed, note_line

    require_toml(args.scene, "scene file", not_a_scene_hint(args.scene))
    phases = Phases(verbose=not args.quiet)
    with phases("scene", args.scene):
        scene = load_scene(args.scene, t_end=args.t_end)
    if args.list_signals:
        from sidprep.solver.results import signal_names
        from sidprep.solver.scene import empty_result

        print("\n".join(signal_names(empty_result(scene.system))))
        return 0
    out = Path(args.output) if args.output else Path(Path(args.scene).stem + ".results.h5")
    base = out.name.removesuffix(".h5").removesuffix(".results")

    def beside(suffix: str) -> Path:
        return out.with_name(base + suffix)

    animate = args.animate or scene.output.animate
    surfaces = animation_surfaces(scene) if animate else {}          # its OBJ files read before the run
    settings = replace(scene.settings, **solver_overrides(args))     # the run's: the command line's overrides
    with phases("simulate", f"0 .. {scene.t_end:g} s, {settings.method}, step {settings.h:g} s"):
        try:
            with SimulationProgress(scene.t_end, enabled=not args.quiet) as progress:
                result = simulate(scene, replace(settings, progress=progress))
        except SimulationFailed as exc:  # keep what was computed, under a name no one takes for the whole run
            kept = write_results(exc.result, beside(".failed.h5"), scene=scene.provenance(), bodies=scene.sources)
            raise InputError(f"{exc} in {kept} ({out} not written)") from None
    outputs = {}
    with phases("write", str(out)):
        outputs["results"] = str(write_results(result, out, scene=scene.provenance(), bodies=scene.sources))
        signals = list(scene.output.signals or DEFAULT_SIGNALS)
        if args.plot or scene.output.plot:
            outputs["plot"] = str(plot_signals(result, signals, beside(".png"), title=scene.title))
        if args.csv or scene.output.csv:
            outputs["csv"] = str(write_csv(result, signals, beside(".csv")))
    if animate:
        from sidprep.solver.animation import write_animation

        with phases("animate", f"{len(result.t)} frames"):
            outputs["animation"] = str(write_animation(result, surfaces, beside(".pvd")))
    report = result.effects.text()
    if args.json:
        s = summary(scene, result, outputs)
        if not args.quiet:
            print(report, file=sys.stderr)
        if s["energy"].get("warning"):
            print(note_line(WARNING_PREFIX + s["energy"]["warning"]), file=sys.stderr)
        print(json.dumps(json_safe(s)))
    else:
        s = summary(scene, result, outputs)
        e = s["energy"]
        print(report)
        print(f"{scene.title}: {s['steps']} steps to t = {s['t_end']:g} s in {s['cpu_s']:.2f} s CPU; "
              f"energy {e['initial']:.6g} -> {e['final']:.6g} J (balance error {e.get('balance_error', 0.0):.2e} "
              "of the energy exchanged)")
        if e.get("warning"):
            print(note_line(WARNING_PREFIX + e["warning"]), file=sys.stderr)
        for kind, path in outputs.items():
            print(f"  {kind}: {path}")
    return 0
