"""From the FE model to a reduced basis: interfaces (RBE2/RBE3), Craig-Bampton, eigen- and
frequency-response modes, geometric stiffening, paths, the analytical Beam and the checks of the
reduction against the full model. Imports fe/ and sid/ (the SID it builds)."""

from sidprep.lazy import submodule


def __getattr__(name: str):
    """The package's modules on first use (sidprep.lazy)."""
    return submodule(__name__, name)
