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
#: most steps of a run (t_end / step of a fixed-step run is checked before the work): 1e7
#: generalised-alpha steps of a small scene already take hours
MAX_STEPS = 10_000_000
#: most result samples kept (t_end * rate, or the steps when every step is kept): memory
MAX_SAMPLES = 1_000_000
#: shortest step, s: no mechanical time scale is shorter, and h^2 underflows near 1e-160
MIN_STEP_S = 1e-12
#: energy balance error above which a run warns, relative to the energy exchanged (sidprep/solver/energy.py)
ENERGY_TOL = 1e-3


def check_run_size(t_end: float, h: float, output_dt: float | None, fixed_step: bool,
                   max_steps: int = MAX_STEPS) -> None:
    """Refuse, before the work, a run whose step count or result samples exceed the limits above.

    t_end, h, output_dt : end time, step, sampling interval (None: every step), s.
    """
    if not MIN_STEP_S <= h:
        raise InputError(f"step = {h:g} s: shorter than {MIN_STEP_S:g} s; give a step of the scene's time "
                         "scale (e.g. 1e-3 s)")
    steps = t_end / h
    if fixed_step and steps > max_steps:
        raise InputError(f"t_end = {t_end:g} s with step = {h:g} s: {steps:.3g} steps, more than {max_steps:g}; "
                         "shorten t_end or lengthen the step")
    samples = t_end / output_dt if output_dt else (steps if fixed_step else 0.0)
    if samples > MAX_SAMPLES:
        raise InputError(f"t_end = {t_end:g} s: {samples:.3g} result samples, more than {MAX_SAMPLES:g}; "
                         "lower [output] rate or shorten t_end")


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
    energy_tol : energy balance error (relative to the energy exchanged, sidprep/solver/energy.py) above
        which the run warns
    effects : None (the System's choice), "auto", "all" or a list of effect names
    progress : None, or a callable(t, t_end, steps) the run calls between chunks of steps (the
        compiled loop runs a chunk without returning; sidprep.progress.SimulationProgress)
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
    max_steps: int = MAX_STEPS
    baumgarte: float = 20.0
    energy_tol: float = ENERGY_TOL
    effects: object = None
    progress: object = None

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
