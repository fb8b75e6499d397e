"""``sidprep converge SCENE.toml | MESH | JOB.toml``: what accuracy costs on your own model, and the
cheapest setting that meets a tolerance: a scene on a ladder of solver settings
(sidprep.solver.converge), or a body reduced with a ladder of mode counts (sidprep.jobs.fe_ladder).
One command for both sides: the input says which (a scene has bodies, a job file names its mesh)."""

from __future__ import annotations

import json
import math
import sys

from sidprep.cli.options import add_json, add_output, add_quiet, process_setup
from sidprep.cli.simulate import positive
from sidprep.solver.integrators.settings import METHODS


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "converge", help="run a scene on a ladder of solver settings; the cheapest one that meets --tol",
        description="Runs the scene on a ladder of solver settings (per method: steps h0*2, h0, h0/2, ... or rtol "
                    "1e-3, 1e-4, ...; generalised-alpha at the scene's rho_inf and 0.6; the other effects choice), "
                    "estimates each run's error by Richardson extrapolation of the finest runs (with the observed "
                    "order), and prints a table of method, step, rho_inf, effects, CPU-s and error per signal, the "
                    "cheapest setting whose estimated error meets --tol and the [solver] lines to paste. Exit 2 "
                    "when no setting meets it.")
    p.add_argument("scene", metavar="SCENE|MESH|JOB", help="scene file (.toml), or a mesh or reduce job file (FE ladder)")
    p.add_argument("--signal", action="append", default=[], metavar="NAME",
                   help="a signal to converge (repeatable; default: the scene's [output] signals but energy.*)")
    p.add_argument("--tol", type=positive, default=None, metavar="REL",
                   help="error to meet, relative to each signal's range (default 1e-3)")
    p.add_argument("--window", type=float, nargs=2, metavar=("T0", "T1"),
                   help="run to T1 (s) and compare on [T0, T1] (default: 0 to the scene's t_end)")
    p.add_argument("--method", action="append", choices=METHODS, metavar="METHOD",
                   help=f"a method to ladder (repeatable; default all: {', '.join(METHODS)})")
    p.add_argument("--step", type=positive, metavar="H0", help="the ladders' h0 in s (default the scene's step)")
    p.add_argument("--levels", type=int, default=None, metavar="N", help="rungs per ladder (default 5, >= 3)")
    p.add_argument("--no-effects", action="store_true", help="do not run the other effects choice")
    p.add_argument("--workers", type=int, help="parallel runs (default: cores, or the cluster's threads)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="Dask scheduler, e.g. tcp://10.0.0.5:8786")
    add_output(p, "PLOT.png", "none: the Pareto plot, error against CPU-s, is written when named")
    add_json(p)
    add_quiet(p)
    fe = p.add_argument_group("FE ladder (MESH or job file: reduced with each mode count, with and without FRMs)")
    fe.add_argument("--modes-ladder", type=int, nargs="+", metavar="N", help="eigenmode counts (default 2 4 6 8 12 16 24)")
    fe.add_argument("--static-tol", type=positive, default=None, metavar="REL",
                    help="static deflection error at the interfaces to meet (default 0.01, the FEMBS promise)")
    fe.add_argument("--frequency-tol", type=positive, default=None, metavar="REL",
                    help="frequency error of the kept eigenmodes to meet (default 0.01)")
    p.set_defaults(func=run, process_setup=process_setup)


def options_from_args(args):
    """The ConvergeOptions of the command line (only the options given; the rest their defaults)."""
    from dataclasses import replace

    from sidprep.solver.converge import ConvergeOptions

    given = {"signals": tuple(args.signal), "tol": args.tol, "levels": args.levels, "step": args.step,
             "window": tuple(args.window) if args.window else None,
             "methods": tuple(dict.fromkeys(args.method)) if args.method else None,
             "effects": False if args.no_effects else None}
    return replace(ConvergeOptions(), **{k: v for k, v in given.items() if v is not None})


def print_table(report) -> None:
    """One row per run: method, step or rtol, rho_inf, effects, CPU-s, error per signal (absolute
    and relative), the observed order of its ladder in the signal of the largest relative error,
    the energy balance error."""
    print(f"{report.scene}: t = {report.window[0]:g}-{report.window[1]:g} s, reference: Richardson extrapolation of "
          f"{report.reference} (observed order "
          + ", ".join(f"{n} {p:.2f}" for n, p in report.orders.items() if math.isfinite(p)) + ")")
    head = ["method", "step / rtol", "rho_inf", "effects", "CPU-s"] + [f"{n} abs | rel" for n in report.signals] \
        + ["order", "energy bal."]
    print(" | ".join(head))
    for r in report.runs:
        s = r.setting
        cells = [s.method, f"rtol {s.rtol:.0e}" if s.rtol else f"{s.h:.4g}",
                 "-" if s.rho_inf is None else f"{s.rho_inf:g}", str(s.effects), f"{r.cpu_s:.3g}"]
        if r.failed:
            print(" | ".join(cells + [f"failed: {r.failed}"]))
            continue
        cells += [f"{e.absolute:.2e} | {e.relative:.2e}" for e in r.errors]
        order = r.limiting.order
        cells += ["-" if order is None else f"{order:.2f}",
                  "-" if r.energy_balance_error is None else f"{r.energy_balance_error:.1e}"]
        print(" | ".join(cells))
    if report.effects_change is not None:
        print(f"the other effects choice changes the signals by {report.effects_change:.2e} of their range")
    print(f"{len(report.runs)} runs, {report.wall_s:.1f} s wall, load average {report.load[0]:.1f}: the CPU-s are "
          f"this machine's; kernels loaded once per process ({report.warm_up_cpu_s:.2f} CPU-s, not counted in the runs)")


def is_scene(path: str) -> bool:
    """Whether ``path`` is a scene file (a .toml without the ``mesh`` or ``component`` of a job file)."""
    from sidprep.tables import read_toml

    if not path.lower().endswith(".toml"):
        return False
    root = read_toml(path, "scene or job file")
    return not ("mesh" in root or "component" in root)


def run(args) -> int:
    from sidprep.jobs.executor import task_pool

    pool = task_pool(args.scheduler, args.workers)
    try:
        return run_scene(args, pool) if is_scene(args.scene) else run_fe(args, pool)
    finally:
        pool.close()


def run_fe(args, pool) -> int:
    """The FE ladder of a mesh or job file: a table (or JSON) and the recommended reduction."""
    from sidprep.solver.results import json_safe

    from sidprep.jobs.fe_ladder import FREQUENCY_TOL, MODE_LADDER, fe_ladder
    from sidprep.jobs.jobfile import Job, read_job
    from sidprep.reduction.fe_checks import STATIC_CHECK_TOL

    job = read_job(args.scene) if args.scene.lower().endswith(".toml") else Job(args.scene)
    report = fe_ladder(job.mesh, job.options, modes=tuple(args.modes_ladder or MODE_LADDER),
                       static_tol=args.static_tol or STATIC_CHECK_TOL,
                       frequency_tol=args.frequency_tol or FREQUENCY_TOL, pool=pool)
    if args.json:
        print(json.dumps(json_safe(report.as_dict())))
    else:
        print("modes | FRMs | nq | CPU-s | static deflection error | frequency error")
        for r in report.rungs:
            print(f"{r.modes} | {'yes' if r.frm else 'no'} | " + (f"failed: {r.failed}" if r.failed else
                  f"{r.nq} | {r.cpu_s:.3g} | {r.static_error:.2e} | {r.frequency_error:.2e}"))
    rec = report.recommendation()
    if not args.json:
        print(f"smallest body meeting static {report.static_tol:g} and frequency {report.frequency_tol:g}: "
              f"{rec.modes} modes{' + FRMs' if rec.frm else ', no FRMs'} (nq = {rec.nq}, {rec.cpu_s:.3g} CPU-s to "
              f"reduce): sidprep reduce {args.scene} --modes {rec.modes}{'' if rec.frm else ' --no-frm'}")
    return 0


def run_scene(args, pool) -> int:
    """The solver ladder of a scene: table (or JSON), plot, the recommended [solver] lines."""
    from sidprep.solver.converge import plot_pareto
    from sidprep.solver.results import json_safe

    report = with_progress(args.scene, options_from_args(args), pool, args.quiet)
    if args.output:
        plot_pareto(report, args.output)
    if args.json:
        print(json.dumps(json_safe(report.as_dict())))
    else:
        print_table(report)
    rec = report.recommendation()                     # InputError (exit 2) when no setting meets --tol
    if not args.json:
        print(f"cheapest setting meeting --tol {report.tol:g}: {rec.setting.label}, estimated error "
              f"{rec.estimated_error:.2e}, {rec.cpu_s:.3g} CPU-s; paste into [solver]:\n{rec.setting.toml()}")
    return 0


def with_progress(scene, options, pool, quiet: bool):
    """converge() with a rich progress bar of the runs on stderr (a terminal), else a line per run
    (none when quiet)."""
    from dataclasses import replace

    from sidprep.solver.converge import converge

    if quiet:
        return converge(scene, options, pool)
    if not sys.stderr.isatty():
        def line(done, total):
            print(f"  converge: {done} / {total} runs", file=sys.stderr, flush=True)
        return converge(scene, replace(options, progress=line), pool)
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
    )

    with Progress(TextColumn("converge"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                  console=Console(stderr=True), transient=True) as bar:
        task = bar.add_task("", total=None)

        def progress(done, total):
            bar.update(task, completed=done, total=total)
        return converge(scene, replace(options, progress=progress), pool)
