"""The SID (Standard Input Data, Wallrapp 1994): the model and its invariants (``model``), the
physical checks (``checks``), the summary of a file (``summary``), the body surface (``surface``)
and the file formats (``io``, one read/write pair per format). Depends on numpy and h5py only: the
solver reads SID files through this package without importing the FE side."""

from sidprep.lazy import submodule


def __getattr__(name: str):
    """The package's modules on first use (sidprep.lazy)."""
    return submodule(__name__, name)
