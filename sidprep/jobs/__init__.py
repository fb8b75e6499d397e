"""Jobs a user runs: typed options, job files, the reduction job, the modal analysis, the files of
a reduction and batches on a process pool or a Dask cluster. The top of the FE side: imports fe/,
reduction/ and sid/."""

import importlib
import importlib.util


def __getattr__(name: str):
    """The job modules on first use: ``import sidprep`` then ``sidprep.jobs.batch.read_study(...)``."""
    if not name.startswith("_") and importlib.util.find_spec(f"{__name__}.{name}") is not None:
        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
