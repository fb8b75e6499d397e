"""SID file formats, one module per format, each a read/write pair with a version; the registry
``FORMATS`` chooses one by the file ending (as meshio's ``_helpers``)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from sidprep.errors import InputError
from sidprep.sid.io.obj import write_obj
from sidprep.sid.io.sid_fem import read_sid_fem, write_sid_fem
from sidprep.sid.io.sid_hdf5 import read_sid_hdf5, write_sid_hdf5


def _write_hdf5(sid, path, comment: str) -> Path:
    return write_sid_hdf5(sid, path)


def _write_sid_fem(sid, path, comment: str) -> Path:
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
    SIDFormat("sid_fem", (".sid_fem",), read_sid_fem, _write_sid_fem),
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


def read_sid(path):
    """Read a SID file chosen by its ending: ``.sid.h5``/``.h5``/``.hdf5`` or ``.SID_FEM``."""
    path = Path(path)
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
