"""The equations of motion, compiled: rotations, body equations, constraints, curves, force
elements, the layout of a system and its assembly (one implementation of each formula)."""

from sidprep.lazy import submodule


def __getattr__(name: str):
    """The package's modules on first use (sidprep.lazy)."""
    return submodule(__name__, name)
