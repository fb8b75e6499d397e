"""The ``sidprep`` command.  Each sub-command is one module here with ``register(subparsers)``."""

from sidprep.lazy import submodule


def __getattr__(name: str):
    """The package's modules on first use (sidprep.lazy)."""
    return submodule(__name__, name)
