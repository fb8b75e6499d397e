"""Jobs a user runs: typed options, job files, the reduction job, the modal analysis, the files of
a reduction and batches on a process pool or a Dask cluster. The top of the FE side: imports fe/,
reduction/ and sid/."""

from sidprep.lazy import submodule


def __getattr__(name: str):
    """The package's modules on first use (sidprep.lazy)."""
    return submodule(__name__, name)
