"""Descriptions of a mechanism: bodies and markers, joints and drivers, force elements, System."""

from sidprep.lazy import submodule


def __getattr__(name: str):
    """The package's modules on first use (sidprep.lazy)."""
    return submodule(__name__, name)
