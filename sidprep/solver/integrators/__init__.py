"""Time integration: settings, the stepper contract (base), generalised-alpha, explicit
Runge-Kutta (RK4 fixed step, RK45 / DOP853 error-controlled), the consistent start and
planar scenes."""

from sidprep.lazy import submodule


def __getattr__(name: str):
    """The package's modules on first use (sidprep.lazy)."""
    return submodule(__name__, name)
