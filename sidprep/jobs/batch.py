"""Batch reduction: many jobs on a local process pool or a Dask cluster, with a content-addressed
cache, memory-aware scheduling and failure isolation.

A batch is a list of ``BatchJob`` (a name, a mesh file and ReduceOptions).  Each job runs in a
worker process with one BLAS thread (sidprep.jobs.reduce.reduce) and writes OUTDIR/<name>.sid.h5 (+ .SID_FEM,
.obj) atomically; the driver then writes the job's cache record OUTDIR/.cache/<key>.json, also
atomically.  The key hashes the mesh file's bytes, the options and the sidprep version, so a re-run
skips finished jobs and a killed batch resumes without lost or half-written outputs.
"""

from __future__ import annotations

import csv
import glob
import hashlib
import io
import itertools
import json
import math
import re
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from sidprep import __version__
from sidprep.errors import InputError
from sidprep.fe.mesh import read_mesh
from sidprep.fe.readers.gmsh import GEOMETRY_SUFFIXES
from sidprep.jobs.executor import task_pool
from sidprep.jobs.guard import folder_lock, require_main_guard
from sidprep.jobs.jobfile import check_inside, job_from_table, split_job_table
from sidprep.jobs.options import OutputOptions, ReduceOptions
from sidprep.jobs.output import output_paths, write_reduction
from sidprep.jobs.reduce import reduce
from sidprep.jobs.scheduler_address import scheduler_address
from sidprep.progress import peak_memory_mb
from sidprep.reduction.craig_bampton import reduction_peak_bytes
from sidprep.sid.io.atomic import atomic_path
from sidprep.tables import checked_table, read_toml

#: fraction of the available memory a batch may plan for
MEMORY_FRACTION = 0.8
#: DOF assumed for a geometry file meshed by gmsh (GEOMETRY_SUFFIXES: unknown before meshing)
GEOMETRY_DOF_GUESS = 100_000
#: the first elastic frequencies kept in a job's record
RECORD_FREQUENCIES = 6
CACHE_DIR = ".cache"


@dataclass(frozen=True)
class BatchOptions:
    """outdir : output folder; workers : parallel jobs (default: cores, or the cluster's threads);
    scheduler : Dask scheduler address (None = local process pool); memory_limit_mb : memory the
    batch may plan for (default MEMORY_FRACTION x available); sid_fem, obj : also write those files."""

    outdir: str = "batch"
    workers: int | None = None
    scheduler: str | None = None
    memory_limit_mb: float | None = None
    sid_fem: bool = True
    obj: bool = True

    def __post_init__(self):
        if self.workers is not None and not self.workers >= 1:
            raise InputError(f"workers = {self.workers}: must be >= 1 (or left out: one per core)")
        if self.scheduler is not None:
            scheduler_address(self.scheduler, "scheduler =")
        if self.memory_limit_mb is not None and not (self.memory_limit_mb > 0 and math.isfinite(self.memory_limit_mb)):
            raise InputError(f"memory_limit_mb = {self.memory_limit_mb}: must be a positive number of MiB "
                             "(or left out: a share of the available memory)")


@dataclass(frozen=True)
class BatchJob:
    """One reduction of a batch; ``params`` : the swept values that made it (name -> value)."""

    name: str
    mesh: str
    options: ReduceOptions = ReduceOptions()
    params: tuple = ()


@dataclass
class BatchReport:
    """records : one dict per job (status ok | cached | failed, error, wall_s, peak_memory_mb, dof,
    frequencies_hz, checks_passed, checks, files, params); outdir; wall_s of the whole batch."""

    records: list
    outdir: str
    wall_s: float = 0.0
    files: dict = field(default_factory=dict)

    @property
    def failed(self) -> list:
        return [r for r in self.records if r["status"] == "failed"]

    @property
    def exit_code(self) -> int:
        return 1 if self.failed else 0


# ---------------------------------------------------------------------------------------------
# jobs
# ---------------------------------------------------------------------------------------------

def estimate_job_memory_mb(n_dof: int) -> float:
    """Planned peak memory of one reduction job (MiB) from its FE DOF count: the estimate the
    reduction itself checks before it starts (sidprep.reduction.craig_bampton.reduction_peak_bytes)."""

    return reduction_peak_bytes(n_dof) / 2.0**20


def gmsh_node_count(path) -> int | None:
    """Node count from the $Nodes header of a gmsh .msh file (ASCII v2 / v4) without reading the
    mesh; None when the header is not found (binary, other format)."""

    try:
        with open(path, "rb") as f:
            head = f.read(1 << 16)
            while b"$Nodes" not in head and len(head) < (64 << 20):
                chunk = f.read(1 << 20)
                if not chunk:
                    return None
                head += chunk
            rest = head[head.index(b"$Nodes") + 7:] + f.read(256)
        version, binary, size = head.split(b"\n", 2)[1].split()[:3]
        if binary == b"1":                                  # v4 binary: 4 size_t after the tag line
            return int(np.frombuffer(rest[:4 * int(size)], dtype=f"<u{int(size)}")[1]) if version.startswith(b"4") \
                else int(rest.split(b"\n", 1)[0])
        numbers = rest.split(b"\n", 1)[0].split()
        return int(numbers[1] if len(numbers) == 4 else numbers[0])
    except (OSError, ValueError, IndexError):
        return None


def job_dof(job: BatchJob) -> int:
    """FE DOF of a job's mesh before it runs: 3 x the nodes of a gmsh header, else the mesh read
    (geometry files: GEOMETRY_DOF_GUESS); InputError if the file cannot be read."""

    if job.mesh.lower().endswith(GEOMETRY_SUFFIXES):
        return GEOMETRY_DOF_GUESS
    n = gmsh_node_count(job.mesh) if job.mesh.lower().endswith(".msh") else None
    return 3 * n if n else int(read_mesh(job.mesh).n_dof)


def job_key(job: BatchJob, opts: BatchOptions) -> str:
    """Content address: sha256 of the mesh bytes, the options, the outputs and the sidprep version."""

    h = hashlib.sha256()
    try:
        h.update(Path(job.mesh).read_bytes())
    except OSError:
        h.update(b"<unreadable>" + job.mesh.encode())
    h.update(json.dumps({"options": asdict(job.options), "name": job.name, "sid_fem": opts.sid_fem,
                         "obj": opts.obj, "version": __version__}, sort_keys=True, default=str).encode())
    return h.hexdigest()


def _safe(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.=+-]+", "_", str(text)).strip("_")


def unique_names(jobs: list[BatchJob]) -> list[BatchJob]:
    """Jobs with distinct names (a repeated name gets -2, -3, ...)."""
    seen: dict[str, int] = {}
    out = []
    for j in jobs:
        n = seen.get(j.name, 0) + 1
        seen[j.name] = n
        out.append(j if n == 1 else replace(j, name=f"{j.name}-{n}"))
    return out


def jobs_from_meshes(meshes, options: ReduceOptions = ReduceOptions()) -> list[BatchJob]:
    """One job per mesh file (globs expanded); InputError for a pattern that matches nothing."""
    files = []
    for m in meshes:
        hits = sorted(glob.glob(str(m))) if glob.has_magic(str(m)) else [str(m)]
        if not hits:
            raise InputError(f"{m}: no file matches this pattern; check the path")
        files.extend(hits)
    return unique_names([BatchJob(_safe(Path(f).name.split(".")[0]), f, options) for f in files])


def read_study(path, safe: bool = False) -> tuple[list[BatchJob], dict]:
    """Jobs and [batch] settings of a study manifest (docs/batch.md).

    [job] : a base job (job-file keys; ``mesh`` relative to the manifest); [sweep] : key -> list of
    values (``mesh`` entries may be globs), combined as the cartesian product (``combine =
    "product"``, default) or element-wise (``combine = "zip"``); [[case]] : explicit override tables
    (each crossed with the sweep); [batch] : outdir (relative to the manifest), workers, scheduler,
    memory_limit_mb, sid_fem, obj.  An outdir or output leaving the manifest's folder is named in a
    warning, or refused when ``safe`` (sidprep.jobs.jobfile.check_inside).
    """

    path = Path(path)
    doc = read_toml(path, "study file")
    unknown = sorted(set(doc) - {"job", "sweep", "case", "batch"})
    if unknown:
        raise InputError(f"{path}: unknown table(s) {', '.join(unknown)}; valid: job, sweep, case, batch")
    base = dict(doc.get("job", {}))
    sweep = dict(doc.get("sweep", {}))
    combine = sweep.pop("combine", "product")
    if combine not in ("product", "zip"):
        raise InputError(f"{path}: [sweep] combine = {combine!r}: expected \"product\" or \"zip\"")
    for key, values in sweep.items():
        if not isinstance(values, list) or not values:
            raise InputError(f"{path}: [sweep] {key} = {values!r}: expected a non-empty list of values")
    if "mesh" in sweep:
        sweep["mesh"] = [str(f) for m in sweep["mesh"]
                         for f in (sorted(glob.glob(str(path.parent / m))) if glob.has_magic(m) else [m])]
        if not sweep["mesh"]:
            raise InputError(f"{path}: [sweep] mesh: no file matches; check the patterns")
    keys = list(sweep)
    if combine == "zip":
        lengths = {len(v) for v in sweep.values()}
        if len(lengths) > 1:
            raise InputError(f"{path}: [sweep] combine = \"zip\" needs lists of equal length")
        points = list(zip(*sweep.values()))
    else:
        points = list(itertools.product(*sweep.values()))
    cases = doc.get("case", [{}]) or [{}]
    jobs, tables = [], []
    for c, case in enumerate(cases):
        for point in points:
            params = dict(zip(keys, point))
            table = {**base, **case, **params}
            tables.append(table)
            context = f"[case {c + 1}]" if len(cases) > 1 else ("[sweep]" if params else "[job]")
            data = split_job_table(table, path, path.parent, context=context, safe=safe)
            if data.get("mesh") is None:
                raise InputError(f"{path}: [job] needs mesh = \"FILE\" or [sweep] mesh = [...]")
            job = job_from_table(data)
            shown = {k: (Path(v).name.split(".")[0] if k == "mesh" else v) for k, v in {**case, **params}.items()}
            label = "-".join(f"{k}={v}" for k, v in shown.items() if k != "mesh")
            name = _safe(Path(job.mesh).name.split(".")[0] + (f"-{label}" if label else ""))
            jobs.append(BatchJob(name, job.mesh, job.options, tuple(sorted(shown.items()))))
    settings = {**study_file_switches(tables, doc.get("batch", {}), path),
                **checked_table(doc.get("batch", {}), BatchOptions, path, context="[batch]")}
    if "outdir" in settings:
        check_inside("[batch] outdir", settings["outdir"], path.parent, path, safe)
    try:
        BatchOptions(**settings)
    except InputError as exc:
        raise InputError(f"{path}: [batch] {exc}") from None
    if "outdir" in settings and not Path(settings["outdir"]).is_absolute():
        settings["outdir"] = str(path.parent / settings["outdir"])
    return unique_names(jobs), settings


def study_file_switches(tables: list[dict], batch: dict, path) -> dict:
    """The job-file output keys of a study's jobs, honoured or refused: ``sid_fem`` / ``obj`` the
    same for every job become the batch's (a [batch] value must agree); ``output`` is refused (a
    study names each job's files OUTDIR/<job name>.*)."""
    if any("output" in t for t in tables):
        raise InputError(f"{path}: output = ...: a study writes each job's files as OUTDIR/<job name>.sid.h5; "
                         "remove output and set [batch] outdir = \"FOLDER\" instead")
    out = {}
    for key in ("sid_fem", "obj"):
        if not any(key in t for t in tables):
            continue
        values = {t.get(key, getattr(BatchOptions, key)) for t in tables}
        if len(values) > 1:
            raise InputError(f"{path}: {key} differs between the jobs; a batch writes the same files for every "
                             f"job: set {key} once in [job] or [batch]")
        if values:
            value = values.pop()
            if key in batch and batch[key] != value:
                raise InputError(f"{path}: [job] {key} = {str(value).lower()} but [batch] {key} = "
                                 f"{str(batch[key]).lower()}; keep one of them")
            out[key] = value
    return out


# ---------------------------------------------------------------------------------------------
# running
# ---------------------------------------------------------------------------------------------

def failed_record(job: BatchJob, error: str) -> dict:
    """The record of a job that did not produce a body (every field of a report row)."""
    return {"name": job.name, "mesh": job.mesh, "params": dict(job.params), "status": "failed", "error": error,
            "wall_s": None, "cpu_s": None, "peak_memory_mb": None, "dof": None, "nq": None, "frequencies_hz": [],
            "checks_passed": None, "checks": {}, "files": {}}


def run_job(job: BatchJob, outdir: str, sid_fem: bool = True, obj: bool = True) -> dict:
    """Run one job in the current process and write its files; never raises (failures are records)."""


    t0, cpu0 = time.perf_counter(), time.process_time()
    record = failed_record(job, "")
    record["started_unix_s"] = time.time()
    try:
        paths = output_paths(job.mesh, OutputOptions(str(Path(outdir) / f"{job.name}.sid.h5"), sid_fem, obj))
        result = reduce(job.mesh, job.options)
        record["files"] = write_reduction(result.sid, paths, source=job.mesh)
        f = np.asarray(result.sid.frequencies_hz)
        eigen = [float(x) for x, k in zip(f, result.sid.mode_kinds) if k == "eigen"]
        record.update(status="ok", dof=result.n_dof, nq=result.sid.nq, frequencies_hz=eigen[:RECORD_FREQUENCIES],
                      checks_passed=result.passed,
                      checks={k: v for k, v in result.checks.items() if isinstance(v, (bool, int, float))})
    except InputError as exc:
        record["error"] = str(exc)
    except Exception as exc:  # a job's internal error must not stop the batch
        record["error"] = f"internal error: {type(exc).__name__}: {exc}"
    record["wall_s"] = time.perf_counter() - t0
    record["cpu_s"] = time.process_time() - cpu0
    record["finished_unix_s"] = time.time()
    record["peak_memory_mb"] = peak_memory_mb()
    return record


def available_memory_mb() -> float:
    """MemAvailable of /proc/meminfo (MiB); 4 GiB where unknown."""
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return 4096.0


def _cached(record_path: Path) -> dict | None:
    """The finished record of a job if it and all its files are on disk."""
    try:
        record = json.loads(record_path.read_text())
    except (OSError, ValueError):
        return None
    if record.get("status") != "ok" or not all(Path(p).is_file() for p in record["files"].values()):
        return None
    return record


def _write_json(path: Path, data) -> None:

    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(data, indent=1, default=float))


def run_batch(jobs: list[BatchJob], options: BatchOptions = BatchOptions(), *, progress=None,
              client=None) -> BatchReport:
    """Run ``jobs``; returns the BatchReport and writes OUTDIR/batch.json and batch.csv.

    progress : callable(record or None, done, total, running_names), optional; called as jobs
    start and finish.  client : a dask.distributed Client to use instead of ``options.scheduler``.
    Jobs start only while the sum of their estimated peak memory (estimate_job_memory_mb) fits the
    budget; at least one always runs.
    """
    if client is None and not options.scheduler:
        require_main_guard("run_batch")
    t0 = time.perf_counter()
    outdir = Path(options.outdir)
    cache = outdir / CACHE_DIR
    try:
        outdir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"{outdir}: cannot create the output folder ({exc.strerror}); choose a writable folder") from None
    with folder_lock(outdir):                               # one batch per folder; .part files go with it
        cache.mkdir(exist_ok=True)
        jobs = unique_names(list(jobs))
        records: dict[str, dict] = {}
        todo = []
        for job in jobs:
            key = job_key(job, options)
            hit = _cached(cache / f"{key}.json")
            if hit is not None:
                records[job.name] = {**hit, "status": "cached", "params": dict(job.params)}
            else:
                todo.append((job, key))
        total = len(jobs)
        if progress:
            for r in records.values():
                progress(r, len(records), total, [])
        if todo:
            _run_pending(todo, options, client, records, cache, progress, total)
        report = BatchReport([records[j.name] for j in jobs], str(outdir), time.perf_counter() - t0)
        report.files = write_report(report)
    return report


def _run_pending(todo, options, client, records, cache, progress, total):
    pool = task_pool(options.scheduler, options.workers, client)
    cluster_mb = sum(pool.worker_memory_limits() or []) / 2**20     # a Dask cluster's workers' limits
    budget = options.memory_limit_mb or cluster_mb or MEMORY_FRACTION * available_memory_mb()
    queue = []
    for job, key in todo:                                   # DOF and memory before starting; bad mesh -> record
        try:
            queue.append((job, key, estimate_job_memory_mb(job_dof(job))))
        except InputError as exc:
            records[job.name] = failed_record(job, str(exc))
            if progress:
                progress(records[job.name], len(records), total, [])
    queue.sort(key=lambda item: -item[2])       # largest first (memory ~ DOF ~ time): no long job in the tail
    running = {}
    try:
        while queue or running:
            planned = sum(m for _, _, m in running.values())
            while queue and len(running) < pool.workers and (not running or planned + queue[0][2] <= budget):
                job, key, mem = queue.pop(0)
                running[pool.submit(run_job, job, str(cache.parent), options.sid_fem, options.obj)] = (job, key, mem)
                planned += mem
                if progress:
                    progress(None, len(records), total, [j.name for j, _, _ in running.values()])
            for fut in pool.wait(list(running)):
                job, key, mem = running.pop(fut)
                try:
                    record = fut.result()
                except Exception as exc:                    # a worker died (killed, out of memory)
                    record = failed_record(job, f"worker lost: {type(exc).__name__}: {exc}")
                record["params"] = dict(job.params)
                record["estimated_memory_mb"] = mem
                if record["status"] == "ok":
                    _write_json(cache / f"{key}.json", record)
                records[job.name] = record
                if progress:
                    progress(record, len(records), total, [j.name for j, _, _ in running.values()])
    except BaseException:                                   # ^C, SIGTERM: the running jobs stop too
        pool.stop(list(running))
        raise
    finally:
        pool.close()


CSV_COLUMNS = ("name", "status", "error", "wall_s", "cpu_s", "peak_memory_mb", "dof", "nq", "frequencies_hz",
               "static_deflection_max_rel_error", "eigen_frequency_max_rel_error", "checks_passed", "files", "params")
#: the columns read from a record's FE checks: the accuracy of the body, beside its cost (cpu_s) and size (nq)
CHECK_COLUMNS = ("static_deflection_max_rel_error", "eigen_frequency_max_rel_error")


def write_report(report: BatchReport) -> dict:
    """OUTDIR/batch.json and batch.csv (atomic); returns their paths."""


    outdir = Path(report.outdir)
    data = {"outdir": report.outdir, "wall_s": report.wall_s, "jobs": report.records,
            "ok": sum(r["status"] != "failed" for r in report.records), "failed": len(report.failed)}
    _write_json(outdir / "batch.json", data)
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(CSV_COLUMNS)
    for r in report.records:
        w.writerow([" ".join(f"{x:.6g}" for x in r.get(c) or []) if c == "frequencies_hz"
                    else (" ".join(r.get(c, {}).values()) if c == "files"
                          else (json.dumps(r.get(c)) if c == "params"
                                else ((r.get("checks") or {}).get(c) if c in CHECK_COLUMNS else r.get(c))))
                    for c in CSV_COLUMNS])
    with atomic_path(outdir / "batch.csv") as tmp:
        tmp.write_text(buf.getvalue())
    files = {"json": str(outdir / "batch.json"), "csv": str(outdir / "batch.csv")}
    plot = study_plot(report)
    if plot:
        files["plot"] = plot
    return files


def study_figure(report: BatchReport):
    """The matplotlib figure of the study plot (``study_plot``), or None without one numeric
    swept parameter; an axis of whole-number values gets whole-number ticks."""
    ok = [r for r in report.records if r["status"] != "failed" and r.get("frequencies_hz")]
    numeric = sorted({k for r in ok for k, v in r.get("params", {}).items()
                      if isinstance(v, (int, float)) and not isinstance(v, bool)})
    if len(ok) < 2 or len(numeric) != 1:
        return None
    import matplotlib  # deferred: 1.2 s import, plots only
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # deferred: 1.2 s import, plots only
    from matplotlib.ticker import MaxNLocator  # deferred: with matplotlib


    key = numeric[0]
    fig, ax = plt.subplots(figsize=(6, 4))
    groups: dict[str, list] = {}
    for r in ok:
        other = ", ".join(f"{k}={v}" for k, v in r["params"].items() if k != key)
        groups.setdefault(other, []).append(r)
    for other, rs in groups.items():
        rs = sorted(rs, key=lambda r: r["params"][key])
        for i in range(min(3, min(len(r["frequencies_hz"]) for r in rs))):
            ax.plot([r["params"][key] for r in rs], [r["frequencies_hz"][i] for r in rs], "o-",
                    label=f"mode {i + 1}" + (f" ({other})" if other else ""))
    ax.set_xlabel(key)
    ax.set_ylabel("elastic eigenfrequency [Hz]")
    ax.legend(fontsize=7)
    ax.grid(True, alpha=0.3)
    if all(float(r["params"][key]).is_integer() for r in ok):
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    return fig


def study_plot(report: BatchReport) -> str | None:
    """OUTDIR/study.png: first elastic frequencies against the one numeric swept parameter, if any."""
    fig = study_figure(report)
    if fig is None:
        return None
    import matplotlib.pyplot as plt  # deferred: 1.2 s import, plots only

    path = Path(report.outdir) / "study.png"
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=100)
    plt.close(fig)
    return str(path)
