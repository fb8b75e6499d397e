"""Opening HDF5 files for reading (SID files, results): bad files and foreign content refused.

HDF5 lets a file pull in other files: an external link (an object that lives in another file),
external raw storage (a dataset whose bytes are read from any file, e.g. a text file) and virtual
datasets (mapped from other files).  sidprep never writes them, and following them would read
files the user never named, so ``open_hdf5`` refuses a file holding any of them, before a single
dataset is read.
"""

from __future__ import annotations

import contextlib
from pathlib import Path

import h5py

from sidprep.errors import InputError

#: deepest group nesting walked (a hard-linked cycle of groups would otherwise recurse forever)
MAX_GROUP_DEPTH = 32


@contextlib.contextmanager
def open_hdf5(path, what: str, fix: str):
    """Yield ``h5py.File(path, "r")`` once it is known to be a readable HDF5 file that names no
    other file; else an InputError "``path``: ... ; ``fix``".  ``what`` names the expected file
    ("SID file", "results file")."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such {what}; {fix}")
    try:
        f = h5py.File(path, "r")
    except OSError as exc:
        reason = str(exc).split("(")[-1].rstrip(")") if "(" in str(exc) else str(exc)
        raise InputError(f"{path}: not a readable HDF5 file ({reason}); {fix}") from None
    with f:
        foreign = foreign_content(f)
        if foreign:
            raise InputError(f"{path}: {foreign}; sidprep reads no file other than the one named "
                             f"(refused), {fix}")
        yield f


def foreign_content(group: h5py.Group, depth: int = 0) -> str | None:
    """What in ``group`` refers to another file (external link, external storage, virtual
    dataset, user-defined link), or None.  Links are inspected without being followed."""
    if depth > MAX_GROUP_DEPTH:
        return f"groups nested deeper than {MAX_GROUP_DEPTH} at {group.name}"
    for name in group:
        link = group.get(name, getlink=True)
        where = f"{group.name.rstrip('/')}/{name}"
        if isinstance(link, h5py.ExternalLink):
            return f"{where} is an external link to {link.filename!r}"
        if isinstance(link, h5py.SoftLink):
            continue                             # a path inside this file: its target is walked anyway
        if not isinstance(link, h5py.HardLink):
            return f"{where} is a {type(link).__name__}"
        obj = group[name]
        if isinstance(obj, h5py.Group):
            found = foreign_content(obj, depth + 1)
            if found:
                return found
        elif isinstance(obj, h5py.Dataset):
            if obj.external:
                return f"{where} stores its data in the external file {obj.external[0][0]!r}"
            if obj.is_virtual:
                return f"{where} is a virtual dataset mapped from {obj.virtual_sources()[0].file_name!r}"
    return None
