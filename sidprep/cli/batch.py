"""``sidprep batch MESH... -o OUTDIR`` or ``sidprep batch study.toml``: many reductions in parallel."""

from __future__ import annotations

import sys

from sidprep.cli.options import add_json, add_output, add_quiet, add_sid_files
from sidprep.cli.reduce import add_reduce_arguments


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "batch", help="reduce many meshes or a parameter study (process pool or Dask cluster, cached)",
        description="Runs the reduction of 'sidprep reduce' over many meshes (files or globs, with the same "
                    "options) or over a study manifest (study.toml: a base job plus sweeps, docs/batch.md). "
                    "Jobs run in parallel (one BLAS thread each), never more than fit the memory; finished jobs "
                    "are cached by content (mesh bytes + options + version), so a re-run or a resumed batch "
                    "skips them. Exit 0 when every job succeeded, 1 when some failed.")
    p.add_argument("inputs", nargs="+", metavar="MESH|STUDY.toml", help="mesh files / globs, or one study.toml")
    add_reduce_arguments(p)
    add_output(p, "OUTDIR", "the folder ./batch, or the study's [batch] outdir")
    p.add_argument("--workers", type=int, help="parallel jobs (default: cores, or the cluster's threads)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="Dask scheduler, e.g. tcp://10.0.0.5:8786")
    p.add_argument("--memory-limit", dest="memory_limit_mb", type=float, metavar="MIB",
                   help="memory the batch may plan for (default 80 %% of the available memory)")
    add_sid_files(p)
    add_json(p)
    add_quiet(p)
    p.add_argument("--safe", action="store_true",
                   help="refuse a study whose outdir or output leaves the study file's folder (a study from someone else)")
    p.set_defaults(func=run)


def batch_from_args(args):
    """(jobs, BatchOptions) of the command line: a study manifest, or meshes with reduce options."""
    from dataclasses import replace

    from sidprep.cli.reduce import options_given
    from sidprep.jobs.batch import BatchOptions, jobs_from_meshes, read_study
    from sidprep.errors import InputError
    from sidprep.jobs.options import ReduceOptions

    given = options_given(args, BatchOptions)
    if args.output:
        given["outdir"] = args.output
    if len(args.inputs) == 1 and args.inputs[0].lower().endswith(".toml"):
        jobs, settings = read_study(args.inputs[0], safe=args.safe)
        overrides = options_given(args, ReduceOptions)
        jobs = [replace(j, options=replace(j.options, **overrides)) for j in jobs]
        return jobs, BatchOptions(**{**settings, **given})
    if any(i.lower().endswith(".toml") for i in args.inputs):
        raise InputError("batch: give one study .toml file, or mesh files; not both")
    return jobs_from_meshes(args.inputs, ReduceOptions(**options_given(args, ReduceOptions))), BatchOptions(**given)


def run(args) -> int:
    import json

    from sidprep.cli.options import cli_flags
    from dataclasses import replace

    from sidprep.jobs.batch import run_batch
    from sidprep.jobs.scheduler_address import probe_scheduler
    from sidprep.jobs.options import check_reduce_options

    with cli_flags():
        jobs, opts = batch_from_args(args)
        for job in jobs:
            check_reduce_options(job.options)
    if opts.scheduler:             # a Dask scheduler there, before distributed reads from it
        opts = replace(opts, scheduler=probe_scheduler(opts.scheduler, "--scheduler" if args.scheduler else
                                                       "scheduler ="))
    if args.quiet:
        report = run_batch(jobs, opts)
    else:
        report = _with_progress(jobs, opts)
    cached = sum(r["status"] == "cached" for r in report.records)
    if cached:                      # with -q too: the outputs were not recomputed
        print(f"sidprep batch: {cached} of {len(report.records)} job(s) served from the cache "
              f"({opts.outdir}/.cache)", file=sys.stderr)
    for r in report.failed:
        print(f"sidprep batch: {r['name']} failed: {r['error']}", file=sys.stderr)
    if args.json:
        print(json.dumps({"outdir": report.outdir, "wall_s": report.wall_s, "files": report.files,
                          "jobs": report.records}, default=float))
    elif args.quiet:
        print(report.outdir)
    else:
        print_summary(report)
    return report.exit_code


def _with_progress(jobs, opts):
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    from sidprep.jobs.batch import run_batch

    console = Console(stderr=True)
    with Progress(TextColumn("batch"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                  TextColumn("{task.description}"), console=console, transient=True) as bar:
        task = bar.add_task("", total=len(jobs))

        def progress(record, done, total, running):
            bar.update(task, completed=done, description=("running: " + ", ".join(running)) if running else "")
        return run_batch(jobs, opts, progress=progress)


def checks_cell(record: dict) -> str:
    """"passed", "FAILED", or "warn N %": the static deflection error N misses the 1 % promise."""
    passed = record.get("checks_passed")
    if passed is None:
        return "-"
    if not passed:
        return "FAILED"
    static = record.get("checks", {}).get("static_deflection_max_rel_error")
    within = record.get("checks", {}).get("static_within_fembs_promise", True)
    return "passed" if within or static is None else f"warn {100 * static:.1f} %"


def print_summary(report, console=None) -> None:
    """The summary table on stdout, one row per job, readable at 80 columns (names folded, never
    cut); the files and the full report are named below it."""
    from rich import box
    from rich.console import Console
    from rich.table import Table

    t = Table(title=f"sidprep batch: {report.outdir} ({report.wall_s:.1f} s)", box=box.SIMPLE_HEAD, pad_edge=False,
              collapse_padding=True)
    t.add_column("job", overflow="fold", ratio=1)
    for col in ("status", "DOF", "wall s", "MiB", "f1 Hz", "checks"):
        t.add_column(col, no_wrap=True, justify="left" if col in ("status", "checks") else "right")
    for r in report.records:
        f = r.get("frequencies_hz") or []
        t.add_row(r["name"], r["status"], str(r.get("dof") or "-"),
                  f"{r['wall_s']:.1f}" if r.get("wall_s") is not None else "-",
                  f"{r['peak_memory_mb']:.0f}" if r.get("peak_memory_mb") else "-",
                  f"{f[0]:.1f}" if f else "-", checks_cell(r))
    (console or Console()).print(t)
    print(f"files: {report.outdir}/<job>.sid.h5 (+ .SID_FEM, .obj); report: {', '.join(report.files.values())}")
