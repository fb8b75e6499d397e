"""SID file formats, one module per format, each a read/write pair with a version; the registry
``FORMATS`` chooses one by the file ending (as meshio's ``_helpers``)."""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from sidprep.errors import InputError
from sidprep.lazy import submodule
from sidprep.sid.checks import physical_problems, structure_problem
from sidprep.sid.io.obj import write_obj
from sidprep.sid.io.sid_hdf5 import read_sid_hdf5, write_sid_hdf5


def _write_hdf5(sid, path, comment: str) -> Path:
    return write_sid_hdf5(sid, path)


def _read_sid_fem(path):
    # deferred: 11 CPU-ms of import that a process reading only .sid.h5 files (a simulation) skips
    from sidprep.sid.io.sid_fem import read_sid_fem

    return read_sid_fem(path)


def _write_sid_fem(sid, path, comment: str) -> Path:
    from sidprep.sid.io.sid_fem import write_sid_fem  # deferred: 11 CPU-ms of import, see _read_sid_fem

    return write_sid_fem(sid, path, comment=comment)


def _write_surface(sid, path, comment: str) -> Path:
    if sid.surface is None:
        raise InputError(f"{path}: this SID has no surface to write as OBJ; write .sid.h5 or .SID_FEM")
    return write_obj(path, sid.surface.points, sid.surface.triangles, comment=comment)


@dataclass(frozen=True)
class SIDFormat:
    """A SID file format: its name, file endings (lower case), reader (None: write only) and
    writer ``write(sid, path, comment) -> Path``."""

    name: str
    suffixes: tuple[str, ...]
    read: Callable | None
    write: Callable


#: the formats, by file ending; ``.obj`` holds only a SID's surface (written, not read as a SID)
FORMATS = (
    SIDFormat("hdf5", (".sid.h5", ".h5", ".hdf5"), read_sid_hdf5, _write_hdf5),
    SIDFormat("sid_fem", (".sid_fem",), _read_sid_fem, _write_sid_fem),
    SIDFormat("obj", (".obj",), None, _write_surface),
)
#: file endings of HDF5 SID files (lower case)
HDF5_SUFFIXES = FORMATS[0].suffixes
#: file endings of the SID files that can be read (lower case)
SID_SUFFIXES = tuple(s for f in FORMATS if f.read for s in f.suffixes)


def sid_format(path) -> SIDFormat | None:
    """The format of ``path`` by its ending, or None."""
    name = Path(path).name.lower()
    return next((f for f in FORMATS if name.endswith(f.suffixes)), None)


class SIDWarning(UserWarning):
    """A SID that was read but is not physically possible (``physical="warn"``)."""


def read_sid(path, physical: str = "warn"):
    """Read a SID file chosen by its ending: ``.sid.h5``/``.h5``/``.hdf5`` or ``.SID_FEM``.

    physical : what a SID that fails the physical checks (``sidprep.sid.checks.physical_problems``:
        finite entries, mass, inertia, Me, Ke) gives: "error" an InputError
        (``simulate``), "warn" one SIDWarning per problem (``info``, ``view``), "off" nothing
        (``check``, which lists every check itself).
    """
    sid = _read(Path(path))
    problem = structure_problem(sid)
    if problem:
        raise InputError(f"{path}: not a consistent SID ({problem}); re-export the file")
    if physical != "off":
        with np.errstate(all="ignore"):          # huge entries: the check fails, silently
            problems = physical_problems(sid)
        fix = f"regenerate the SID (sidprep check {path} lists every check)"
        if problems and physical == "error":
            more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
            raise InputError(f"{path}: not a physically possible body: {problems[0]}{more}; {fix}")
        for problem in problems if physical == "warn" else ():
            warnings.warn(f"{path}: {problem}; {fix}", SIDWarning, stacklevel=2)
    return sid


def _read(path: Path):
    fmt = sid_format(path)
    if fmt is None or fmt.read is None:
        raise InputError(f"{path}: unknown SID file type; use a .sid.h5 or .SID_FEM file")
    if not path.is_file():
        raise InputError(f"{path}: no such file; check the path")
    return fmt.read(path)


def write_sid(sid, path, *, comment: str = "") -> Path:
    """Write ``sid`` by the file ending: .sid.h5 / .h5 / .hdf5 (HDF5), .SID_FEM (ASCII), .obj
    (its surface); atomically."""
    path = Path(path)
    fmt = sid_format(path)
    if fmt is None:
        raise InputError(f"{path}: unknown SID file type; use .sid.h5, .SID_FEM or .obj")
    return fmt.write(sid, path, comment)


def __getattr__(name: str):
    """The package's modules on first use (sidprep.lazy)."""
    return submodule(__name__, name)
