"""Browser pages: a SID's modes and a simulation's bodies drawn from the one surface model of
``sidprep.sid.surface``. Imports sid/ and the solver's results."""

from sidprep.lazy import submodule


def __getattr__(name: str):
    """The package's modules on first use (sidprep.lazy)."""
    return submodule(__name__, name)
