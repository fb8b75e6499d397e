"""TOML job files of ``sidprep reduce JOB.toml``: the ReduceOptions and OutputOptions fields plus
``mesh``; ``mesh``, ``output`` and ``matrices`` are relative to the job file's folder.

An assembly's job file has ``[[component]]`` tables (name, mesh, material) and ``[[join]]`` tables
(sidprep.fe.joined.Join) instead of ``mesh`` (sidprep.jobs.assembly, docs/scale.md)."""

from __future__ import annotations

import warnings
from dataclasses import dataclass, fields
from pathlib import Path

from sidprep.errors import InputError
from sidprep.fe.joined import Join, check_join_form
from sidprep.jobs.options import OutputOptions, ReduceOptions
from sidprep.tables import checked_table, read_toml


@dataclass(frozen=True)
class Component:
    """One component of an assembly: its ``name`` (node sets are "NAME.SET"), its ``mesh`` (path),
    its material (a name, or E, nu, rho in the job's units; default the job's), ``size`` (the
    element size when the mesh is a geometry file; default the job's) and ``matrices``: K and M
    written by another FE code for that mesh (a tetrahedral deck; sidprep.fe.matrices), instead of
    the material."""

    name: str
    mesh: str
    material: str | None = None
    E: float | None = None
    nu: float | None = None
    rho: float | None = None
    size: float | None = None
    matrices: str | None = None


@dataclass(frozen=True)
class Job:
    """One reduction job: the mesh (path; an assembly's job file itself), the reduction settings
    and the files to write; an assembly's ``components`` and ``joins`` (empty for one mesh)."""

    mesh: str
    options: ReduceOptions = ReduceOptions()
    output: OutputOptions = OutputOptions()
    components: tuple[Component, ...] = ()
    joins: tuple[Join, ...] = ()


@dataclass(frozen=True)
class _JobTable(ReduceOptions, OutputOptions):
    """Every key a job file may hold (checked by sidprep.tables)."""

    mesh: str | None = None


class OutsideWarning(UserWarning):
    """A job or study file writes outside its own folder."""


def check_inside(key: str, value: str, base: Path, source, safe: bool = False) -> None:
    """An output path from a file (``key = value``, resolved) that leaves the file's folder
    ``base`` (``../..``, an absolute path) is named in an OutsideWarning, or refused (``safe``:
    a study run with ``--safe``, e.g. one received from someone else)."""
    target, folder = (Path(base) / value).resolve(), Path(base).resolve()
    if target == folder or folder in target.parents:
        return
    message = f"{source}: {key} = {value!r} writes outside the file's folder {folder} (to {target})"
    if safe:
        raise InputError(f"{message}; refused with --safe: write inside the study's folder")
    warnings.warn(f"{message}; check that this is meant", OutsideWarning, stacklevel=2)


def split_job_table(table: dict, source, base: Path, *, context: str = "", safe: bool = False) -> dict:
    """A checked job table with ``mesh``, ``output`` and ``matrices`` resolved against ``base``; an ``output``
    outside ``base`` is named or refused (``check_inside``)."""
    data = checked_table(table, _JobTable, source, context=context)
    for key in ("mesh", "output", "matrices"):
        if data.get(key) is not None and not Path(data[key]).is_absolute():
            data[key] = str((base / data[key]).resolve())
    if data.get("output") is not None:
        check_inside("output", table["output"], base, source, safe)
    return data


def job_from_table(data: dict) -> Job:
    """Job from a checked table (split_job_table); ``mesh`` must be set."""
    red = {f.name for f in fields(ReduceOptions)}
    out = {f.name for f in fields(OutputOptions)}
    return Job(data["mesh"], ReduceOptions(**{k: v for k, v in data.items() if k in red}),
               OutputOptions(**{k: v for k, v in data.items() if k in out}))


def read_job(path) -> Job:
    """The Job of a TOML job file (one-line InputErrors: file not found, syntax, key, type)."""

    path = Path(path)
    doc = read_toml(path, "job file")
    if "component" in doc or "join" in doc:
        return read_assembly(path, doc)
    data = split_job_table(doc, path, path.parent)
    if data.get("mesh") is None:
        raise InputError(f"{path}: the job file needs mesh = \"FILE\" (relative to the job file)")
    return job_from_table(data)


#: job-file keys that an assembly takes from its components instead
NOT_IN_ASSEMBLIES = {"mesh": "give each [[component]] its mesh", "matrices": "give the [[component]] whose K "
                     "and M another FE code wrote its matrices", "parts": "an assembly's parts are its components"}


def read_assembly(path: Path, doc: dict) -> Job:
    """The Job of an assembly's job file (``doc`` its TOML): at least two [[component]] tables with
    unique names and existing meshes, and [[join]] tables of one of the two forms (sidprep.fe.joined)."""

    components, joins = doc.pop("component", None), doc.pop("join", [])
    for key, fix in NOT_IN_ASSEMBLIES.items():
        if key in doc:
            raise InputError(f"{path}: {key} = ... does not apply to an assembly; {fix}")
    if not isinstance(components, list) or len(components) < 2 or not all(isinstance(c, dict) for c in components):
        raise InputError(f"{path}: an assembly needs two or more [[component]] tables (name = ..., mesh = ...)")
    if not isinstance(joins, list) or not all(isinstance(j, dict) for j in joins):
        raise InputError(f"{path}: join must be [[join]] tables (nodes = [...] or tied = ..., to = ...)")
    comps = []
    for k, table in enumerate(components):
        c = Component(**checked_table(table, Component, path, context=f"[[component]] {k + 1}"))
        if not c.name or "." in c.name or c.name in {x.name for x in comps}:
            raise InputError(f"{path}: [[component]] {k + 1}: name = {c.name!r}: give each component a unique name "
                             "without '.' (its node sets are NAME.SET)")
        files = {}
        for key in ("mesh", "matrices"):
            if getattr(c, key) is None:
                continue
            files[key] = (path.parent / getattr(c, key)).resolve()
            if not files[key].is_file():
                raise InputError(f"{path}: [[component]] {c.name}: {key} {getattr(c, key)} not found (looked for "
                                 f"{files[key]}); check the path (relative to the job file)")
        comps.append(Component(**{**vars(c), **{k: str(v) for k, v in files.items()}}))
    js = []
    for k, table in enumerate(joins):
        j = Join(**checked_table(table, Join, path, context=f"[[join]] {k + 1}"))
        check_join_form(j, f"{path}: [[join]] {k + 1}")
        js.append(j)
    job = job_from_table({**split_job_table(doc, path, path.parent), "mesh": str(path)})
    return Job(job.mesh, job.options, job.output, tuple(comps), tuple(js))
