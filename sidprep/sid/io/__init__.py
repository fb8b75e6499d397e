"""File formats, one module per format, each a read/write pair with a version."""

from __future__ import annotations

from pathlib import Path

from sidprep.errors import InputError

#: file-name endings of SID files and the reader of each (lower case)
SID_SUFFIXES = {".sid.h5": "hdf5", ".h5": "hdf5", ".hdf5": "hdf5", ".sid_fem": "ascii"}


def read_sid(path):
    """Read a SID file chosen by its ending: ``.sid.h5``/``.h5``/``.hdf5`` or ``.SID_FEM``."""
    path = Path(path)
    name = path.name.lower()
    kind = next((k for suffix, k in SID_SUFFIXES.items() if name.endswith(suffix)), None)
    if kind is None:
        raise InputError(f"{path}: unknown SID file type; use a .sid.h5 or .SID_FEM file")
    if not path.is_file():
        raise InputError(f"{path}: no such file; check the path")
    if kind == "hdf5":
        from sidprep.sid.io.sid_hdf5 import read_sid_hdf5
        return read_sid_hdf5(path)
    from sidprep.sid.io.sid_fem import read_sid_fem
    return read_sid_fem(path)
