"""From a model to the kernels' tables: the one place that turns a System's descriptions into the
flat arrays the compiled equations read (``layout``)."""

from sidprep.lazy import submodule


def __getattr__(name: str):
    """The package's modules on first use (sidprep.lazy)."""
    return submodule(__name__, name)
