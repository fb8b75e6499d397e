"""TOML job files of ``sidprep reduce JOB.toml``: the ReduceOptions and OutputOptions fields plus
``mesh``; ``mesh``, ``output`` and ``matrices`` are relative to the job file's folder."""

from __future__ import annotations

import warnings
from dataclasses import dataclass, fields
from pathlib import Path

from sidprep.errors import InputError
from sidprep.jobs.options import OutputOptions, ReduceOptions
from sidprep.tables import checked_table, read_toml


@dataclass(frozen=True)
class Job:
    """One reduction job: the mesh (path), the reduction settings and the files to write."""

    mesh: str
    options: ReduceOptions = ReduceOptions()
    output: OutputOptions = OutputOptions()


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
    data = split_job_table(read_toml(path, "job file"), path, path.parent)
    if data.get("mesh") is None:
        raise InputError(f"{path}: the job file needs mesh = \"FILE\" (relative to the job file)")
    return job_from_table(data)
