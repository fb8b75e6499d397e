"""Files of a reduction: where they go (``output_paths``), writing them (``write_reduction``), and a
job reduced and written in one call (``run_job``: what ``sidprep reduce`` runs).

Every file is written atomically, the files of one reduction as one set (sidprep.sid.io.atomic): a
killed run leaves no half-written output and no set without its other files.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from sidprep.jobs.options import OutputOptions, check_output
from sidprep.progress import Phases
from sidprep.sid.io import write_sid
from sidprep.sid.io.atomic import output_set


def output_paths(mesh, out: OutputOptions = OutputOptions()) -> dict[str, Path]:
    """{"hdf5": ..., "sid_fem": ..., "obj": ...} for the enabled outputs (default ./<mesh stem>.sid.h5),
    checked (file type, folder writable) before any work."""
    h5 = check_output(out.output if out.output else Path(Path(mesh).stem + ".sid.h5"))
    stem = h5.name[:-len(".sid.h5")] if h5.name.lower().endswith(".sid.h5") else h5.stem
    paths = {"hdf5": h5}
    if out.sid_fem:
        paths["sid_fem"] = h5.with_name(stem + ".SID_FEM")
    if out.obj:
        paths["obj"] = h5.with_name(stem + ".obj")
    return paths


def write_reduction(sid, paths: dict[str, Path], *, source: str = "", command: str = "reduce") -> dict[str, str]:
    """Write the files named by ``output_paths``; returns {kind: path string}. The SID_FEM and OBJ
    comment names the command and its input (``sidprep reduce bar.msh``)."""
    comment = f"sidprep {command} {Path(source).name}".strip() if source or command != "reduce" else ""
    with output_set():                 # all files, or none (an error or a signal while writing)
        for path in paths.values():
            write_sid(sid, path, comment=comment)
    return {k: str(v) for k, v in paths.items()}


def write_beam_files(options, output, sid_fem: bool = True, obj: bool = True) -> dict:
    """Build the analytical beam's SID (``options``: sidprep.reduction.beam.BeamOptions) and write
    ``output`` (.sid.h5, checked before the work) and its companions <stem>.SID_FEM and <stem>.obj,
    as ``sidprep reduce`` does; returns a summary dict (files, mass kg, nq, labels, frequencies Hz)."""
    from sidprep.reduction.beam import beam_sid  # deferred: `sidprep beam` only, not the FE reduction

    paths = output_paths(output, OutputOptions(output=str(output), sid_fem=sid_fem, obj=obj))
    sid = beam_sid(options)
    files = write_reduction(sid, paths, command="beam")
    return {"files": files, "mass_kg": sid.mass, "nq": sid.nq, "labels": list(sid.labels),
            "frequencies_hz": sid.frequencies_hz.tolist()}


@dataclass(frozen=True)
class JobRun:
    """A reduction job done: the ReductionResult (SID, checks, notes, timings) and the files
    written ({"hdf5", "sid_fem", "obj"}: path strings)."""

    result: object
    files: dict


def run_job(job, *, phases=None, scheduler=None, workers=None) -> JobRun:
    """Reduce ``job`` (sidprep.jobs.jobfile.Job: one mesh, or an assembly of components) and write
    its files (``job.output``; the paths are checked before the work).  ``scheduler``/``workers``:
    the executor of a reduction in parts or of an assembly's components."""
    from sidprep.jobs.reduce import reduce  # deferred: the FE side, which `sidprep beam` never needs

    phases = phases or Phases(verbose=False)
    paths = output_paths(job.mesh, job.output)
    if job.components:
        from sidprep.jobs.assembly import reduce_assembly  # deferred: assemblies only (parts, imported K, M)

        result = reduce_assembly(job, phases=phases, scheduler=scheduler, workers=workers)
    else:
        result = reduce(job.mesh, job.options, phases=phases, scheduler=scheduler, workers=workers)
    with phases("write", ", ".join(str(p) for p in paths.values())):
        files = write_reduction(result.sid, paths, source=job.mesh)
    return JobRun(result, files)
