"""``sidprep reduce MESH|JOB.toml``: tetrahedral FE model -> reduced flexible body (SID files)."""

from __future__ import annotations

import argparse
import gc
import os
import sys
from dataclasses import fields, replace

from sidprep.cli.options import SOLVER_THREADS, add_json, add_model_arguments, add_output, add_quiet, add_sid_files


def add_reduce_arguments(p) -> None:
    """The reduction options (material, interfaces, frame, modes, FRMs, damping, checks); shared with batch."""
    add_model_arguments(p, units_default=None)
    p.add_argument("--interface", dest="interfaces", action="append", metavar="NAME[:rbe2|rbe3]",
                   help="node set coupled to a 6-DOF master (repeat); default: all node sets that can carry 6 DOF")
    p.add_argument("--frame", help="reference frame: free (default) or the name of an interface to attach it to")
    n = p.add_mutually_exclusive_group()
    n.add_argument("--modes", type=int, help="number of elastic eigenmodes of interest (default 8)")
    n.add_argument("--fmax", type=float, help="keep all eigenmodes up to this frequency (Hz)")
    p.add_argument("--frm", action=argparse.BooleanOptionalAction, default=None,
                   help="frequency-response modes at the interface masters (default on)")
    p.add_argument("--frm-nodes", action="append", metavar="NODESET",
                   help="extra FRM load nodes: every node of this node set gets unit x, y, z forces (repeat)")
    p.add_argument("--cutoff-factor", type=float, help="FRM cut-off / highest frequency of interest (default 5)")
    p.add_argument("--path", dest="paths", action="append",
                   metavar="NAME:x0,y0,z0:x1,y1,z1[:x2,y2,z2 ...][:n] | NAME:nodes=SET:dir=x[:n]",
                   help="a path in or on the body along which loads move (repeat): the curve through the given "
                        "points (mesh coordinates, in the job's units) or through the nodes of node set SET "
                        "ordered along dir (x, y, z, -x, ... or dx,dy,dz); straight for 2 points, else a smooth "
                        "cubic spline (no corners: the solver differentiates the path), sampled at n points "
                        "(default 201) of equal arc length. Its mode shapes are interpolated from the full FE "
                        "modes and stored in the SID; points on a curved surface just outside the faceted mesh "
                        "(within 0.1 element edge) are accepted")
    d = p.add_mutually_exclusive_group()
    d.add_argument("--damping", type=float, help="modal damping ratio of every mode (default 0.02)")
    d.add_argument("--rayleigh", type=float, nargs=2, metavar=("ALPHA", "BETA"),
                   help="Rayleigh damping De = alpha Me + beta Ke instead (1/s, s)")
    p.add_argument("--stiffening", action="store_true", default=None,
                   help="compute the geometric-stiffening unit load cases (docs/sid-spec.md 6)")
    p.add_argument("--stress", nargs="?", const="surface", choices=("surface", "all"), default=None,
                   help="store the modal stresses (Pa per unit modal coordinate) at the outer surface's nodes "
                        "(--stress) or at every node (--stress all), for `sidprep stress` after a simulation")
    p.add_argument("--matrices", metavar="FILE",
                   help="K and M written by another FE code instead of sidprep's own assembly: CalculiX .sti "
                        "(*FREQUENCY, SOLVER=MATRIXSTORAGE) or .eig, Abaqus _STIF1.mtx, Nastran DMIG .pch, Ansys "
                        ".full; MESH is then the deck they come from (any solid elements); values in --units "
                        "(docs/import.md)")
    p.add_argument("--check-frequencies", action=argparse.BooleanOptionalAction, default=None,
                   help="compare with a full-model eigen solve (default on; the costliest check)")


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "reduce", help="reduce a tetrahedral FE model to a flexible body (SID .sid.h5, .SID_FEM, .obj)",
        description="Craig-Bampton on the interface masters, then eigenmodes of interest + frequency-response "
                    "modes (FEMBS style). MESH may be a mesh/geometry file or a TOML job file with the same "
                    "option names (mesh = \"...\", interfaces = [\"big_end:rbe2\"], ...). Defaults: steel, every "
                    "node set that can carry 6 DOF as an RBE2 interface, free frame, 8 eigenmodes + FRMs.")
    p.add_argument("mesh", metavar="MESH", help="mesh (.msh .inp .bdf .vtu ...), geometry (.geo .step) or job (.toml)")
    add_reduce_arguments(p)
    add_output(p, "OUT.sid.h5", "./<MESH stem>.sid.h5")
    add_sid_files(p)
    p.add_argument("--parts", type=int, metavar="N",
                   help="reduce the model in N parts (component mode synthesis: each part a task, docs/scale.md)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="with --parts or an assembly: run the parts on this Dask scheduler (tcp://host:port); "
                        "default a local pool")
    p.add_argument("--workers", type=int, metavar="N",
                   help="with --parts or an assembly: local worker processes (default: cores)")
    add_json(p)
    add_quiet(p)
    p.set_defaults(func=run, process_setup=process_setup)


def process_setup(args) -> None:
    """What ``sidprep reduce`` changes about its process when it runs as one (not ``main`` called
    from Python), before its imports.  One BLAS thread from the start (SOLVER_THREADS, unless the
    environment sets it): the reduction runs with one anyway (sidprep.fe.linalg.single_threaded_blas),
    but OpenBLAS starts a pool per copy loaded (numpy's, scipy's) whose other thread spins while the
    modules load; not with --parts or a job file, whose driver uses every core between rounds
    (all_cores_blas).  And the reduction's modules imported with the cyclic garbage collector paused,
    their objects then frozen out of its later collections (gc.freeze): it would scan them ~120
    times while they load and once more in full during the run; it runs as always for the run's
    own objects."""
    if not (args.parts or args.mesh.lower().endswith(".toml")):
        for name, value in SOLVER_THREADS.items():
            os.environ.setdefault(name, value)
    gc.disable()
    try:
        import sidprep.jobs.jobfile  # noqa: F401 - what run imports, loaded here with the collector paused
        import sidprep.jobs.output  # noqa: F401
        import sidprep.jobs.reduce  # noqa: F401
        import sidprep.reduction.fe_checks  # noqa: F401
    finally:
        gc.freeze()
        gc.enable()


def job_from_args(args):
    """The Job of the command line; a .toml MESH is a job file that the options override."""
    from sidprep.jobs.jobfile import Job, read_job
    from sidprep.jobs.options import OutputOptions, ReduceOptions

    base = read_job(args.mesh) if args.mesh.lower().endswith(".toml") else Job(args.mesh)
    return replace(base, options=replace(base.options, **options_given(args, ReduceOptions)),
                   output=replace(base.output, **options_given(args, OutputOptions)))


def options_given(args, cls) -> dict:
    """The fields of settings class ``cls`` given on the command line (lists as tuples)."""
    out = {f.name: getattr(args, f.name) for f in fields(cls) if getattr(args, f.name, None) is not None}
    if getattr(args, "rayleigh", None) and "damping" in {f.name for f in fields(cls)}:
        out["damping"] = {"rayleigh": tuple(args.rayleigh)}
    return {k: tuple(v) if isinstance(v, list) else v for k, v in out.items()}


def run(args) -> int:
    import json

    from sidprep.cli.options import cli_flags, quiet_native_output
    from sidprep.errors import InputError, note_line
    from sidprep.jobs.output import run_job
    from sidprep.jobs.scheduler_address import probe_scheduler
    from sidprep.progress import Phases
    from sidprep.reduction.fe_checks import format_checks

    ph = Phases(verbose=not args.quiet)
    with cli_flags():
        job = job_from_args(args)
        if (args.scheduler is not None or args.workers is not None) and not (job.options.parts or job.components):
            raise InputError("--scheduler and --workers apply to a reduction in parts; add --parts N")
        if args.workers is not None and args.workers < 1:
            raise InputError(f"--workers {args.workers}: must be >= 1 (or left out: one per core)")
        scheduler = probe_scheduler(args.scheduler) if args.scheduler is not None else None
        with quiet_native_output():
            run = run_job(job, phases=ph, scheduler=scheduler, workers=args.workers)
    result, files = run.result, run.files
    if not args.quiet:
        for note in result.notes:
            print(note_line(note), file=sys.stderr)
        print(format_checks(result.checks), file=sys.stderr)
    if args.json:
        summary = {"files": files, "dof": result.n_dof, "nq": result.sid.nq, "labels": list(result.sid.labels),
                   "kinds": list(result.sid.mode_kinds), "notes": list(result.notes), "checks": result.checks,
                   "timings_s": {**result.timings_s, "write": ph.timings_s.get("write", 0.0)},
                   "peak_memory_mb": result.peak_memory_mb}
        print(json.dumps(summary, indent=2, default=float))
    else:
        for path in files.values():
            print(path)
    return 0
