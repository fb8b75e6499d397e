"""Solver settings: one typed, frozen dataclass; each default is written here once."""

from __future__ import annotations

from dataclasses import dataclass

from sidprep.errors import InputError

#: integration methods: implicit index-3 Lie-group generalised-alpha, and explicit Runge-Kutta
#: on the index-1 form (fixed-step classic RK4; RK45 / DOP853 with error control)
METHODS = ("genalpha", "rk4", "rk45", "dop853")
#: methods that need an error tolerance (they choose their own steps)
ADAPTIVE_ONLY = ("rk45", "dop853")
#: rtol of RK45 / DOP853 when none is given
ADAPTIVE_RTOL = 1e-8
#: energy balance error above which a run warns, relative to the energy exchanged (solver/energy.py)
ENERGY_TOL = 1e-3


@dataclass(frozen=True)
class SolverSettings:
    """How a System is integrated (``System.simulate(t_end, settings, **overrides)``).

    method : one of METHODS
    h : step size (genalpha, rk4) or initial step (error-controlled runs), s
    rho_inf : spectral radius at infinity of generalised-alpha (1 = no numerical damping)
    rtol : relative tolerance of the step-size control; None = fixed step h (genalpha, rk4),
        ADAPTIVE_RTOL for rk45 / dop853
    atol : absolute tolerance of the step-size control, m (coordinates scaled to lengths)
    output_dt : sampling interval of the results, s (None: every step)
    static_start : start with the elastic coordinates in quasi-static equilibrium with the
        initial rigid-body accelerations (no start-up vibration)
    newton_tol : Newton tolerance of generalised-alpha: position correction / system length
    deformation_limit : generalised-alpha stops when a body's elastic deflection exceeds this
        fraction of its size (the floating frame's small-deformation range; docs/solver.md)
    max_steps : the run stops with an error after this many steps
    baumgarte : constraint stabilisation rate of the explicit methods, 1/s
    energy_tol : energy balance error (relative to the energy exchanged, solver/energy.py) above
        which the run warns
    effects : None (the System's choice), "auto", "all" or a list of effect names
    """

    method: str = "genalpha"
    h: float = 1e-3
    rho_inf: float = 0.9
    rtol: float | None = None
    atol: float = 1e-9
    output_dt: float | None = None
    static_start: bool = False
    newton_tol: float = 1e-8
    deformation_limit: float = 0.2
    max_steps: int = 10_000_000
    baumgarte: float = 20.0
    energy_tol: float = ENERGY_TOL
    effects: object = None

    def __post_init__(self):
        if self.method not in METHODS:
            raise InputError(f"unknown integration method {self.method!r}; use one of {', '.join(METHODS)}")
        if not self.h > 0:
            raise InputError(f"the step size h must be > 0 s, got {self.h}")
        if not 0.0 <= self.rho_inf <= 1.0:
            raise InputError(f"rho_inf must be in [0, 1], got {self.rho_inf}; use e.g. 0.9")
        for name in ("rtol", "output_dt"):
            value = getattr(self, name)
            if value is not None and not value > 0:
                raise InputError(f"{name} must be > 0 (or not given), got {value}")
        if not (self.atol > 0 and self.newton_tol > 0 and self.deformation_limit > 0 and self.baumgarte >= 0
                and self.max_steps > 0 and self.energy_tol > 0):
            raise InputError("atol, newton_tol, deformation_limit, energy_tol and max_steps must be > 0 and "
                             "baumgarte >= 0")

    @property
    def tolerance(self) -> float | None:
        """The rtol in force: None for a fixed-step run."""
        if self.rtol is None and self.method in ADAPTIVE_ONLY:
            return ADAPTIVE_RTOL
        return self.rtol
