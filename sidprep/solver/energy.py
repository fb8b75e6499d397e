"""The energy balance of a run: the one figure that says how accurately it was integrated.

Booked at every output sample (postprocess.py):

    E(t) = kinetic + strain + gravity + spring + dissipated - external     (J)

with ``dissipated`` the work of damping and friction and ``external`` the work of the applied
loads and of the drives since t = 0 (trapezoidal integrals over the steps).  The equations
conserve E exactly, so any change of it is integration error (or a term of the model whose
work is not booked).  The balance error is

    max_t |E(t) - E(0)| / W,   W = max(largest range of any booked term, largest kinetic energy)

W is the energy exchanged between the terms (a hinged body swinging under gravity: the swing's
kinetic energy), or the energy the motion carries when nothing is exchanged (a body spinning
freely).  Above ``energy_tol`` (SolverSettings, default ENERGY_TOL) the run carries one warning
naming the likely cause and the fix, unless the change itself is below the floor

    max(ENERGY_FLOOR_J, ROUND_OFF_RTOL * largest |booked term|)

at which the books cannot tell integration error from the Newton tolerance and round-off (a run
that exchanges almost nothing, e.g. a static start: a relative error of a few 1e-11 J means
nothing).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sidprep.solver.integrators.settings import ENERGY_TOL
#: booked energy terms (postprocess.ENERGY_KINDS without the total)
BOOKED = ("kinetic", "strain", "gravity", "spring", "dissipated", "external", "stiffening")
#: a change of the booked total below this, J, is no evidence of an integration error
ENERGY_FLOOR_J = 1e-12
#: ... nor one below this fraction of the largest booked energy (the Newton tolerance's and the
#: round-off's share of the terms that are summed)
ROUND_OFF_RTOL = 1e-9


def parabola_first_intervals(y: np.ndarray, dx: np.ndarray) -> np.ndarray:
    """int_{x_i}^{x_i+1} of the parabola through the samples i, i+1, i+2 (n-2,), for samples y (n,)
    at the spacings dx (n-1,) (Cartwright 2017, "Simpson's rule cumulative integration with
    irregularly-spaced data", eq. 8; scipy's cumulative_simpson uses the same)."""
    x21, x32 = dx[:-1], dx[1:]
    a = x21 / (x21 + x32)
    b = a * (x21 / x32)
    return x21 / 6 * ((3 - a) * y[:-2] + (3 + b + a) * y[1:-1] - b * y[2:])


def work_integral(t: np.ndarray, power: np.ndarray) -> np.ndarray:
    """W(t_k) = int_0^t_k P dt (nt,) J of the power P (nt,) W sampled at the times t (nt,) s:
    composite Simpson for irregular samples (each interval from the parabola through it and a
    neighbouring sample: the intervals starting a pair from the forward parabola, the others and
    the last from the backward one, as scipy's cumulative_simpson; the trapezoidal rule for two
    samples).  Its error falls as dt^3 against the trapezoid's dt^2: a power sampled at 100 Hz
    that swings at 4 Hz left 1.1e-3 of the energy exchanged with the trapezoid
    (examples/beam_buckling), 2e-5 with Simpson.  (Written out here: scipy.integrate costs 0.3
    CPU-s of import, a fifth of a simulate process.)"""
    t, power = np.asarray(t, dtype=float), np.asarray(power, dtype=float)
    if t.size < 2:
        return np.zeros(t.size)
    dx = np.diff(t)
    if t.size == 2:
        return np.array([0.0, dx[0] * (power[0] + power[1]) / 2.0])
    forward = parabola_first_intervals(power, dx)
    backward = parabola_first_intervals(power[::-1], dx[::-1])[::-1]
    pieces = np.empty(t.size - 1)
    pieces[:-1:2] = forward[::2]
    pieces[1::2] = backward[::2]
    pieces[-1] = backward[-1]
    return np.concatenate([[0.0], np.cumsum(pieces)])


@dataclass(frozen=True)
class EnergyBalance:
    """How well a run's energy books close (module doc).

    balance_error : the largest change of the total energy over the energy exchanged (NaN for a run
    that exchanged none); exchanged : J; change : J, E(end) - E(0); excursion : J, the largest change
    E - E(0) with its sign; worst : J, its size; floor : J, what the books resolve; tolerance : the
    run's energy_tol; warning : the one line naming cause and fix when the error passes the
    tolerance (``balance_warning``), else None.  A results file written before excursion, worst and
    floor were booked reads them as NaN, inf and 0 (no floor).
    """

    balance_error: float
    exchanged: float
    change: float
    excursion: float = float("nan")
    worst: float = float("inf")
    floor: float = 0.0
    tolerance: float = ENERGY_TOL
    warning: str | None = None


def energy_balance(energy: dict, tolerance: float = ENERGY_TOL) -> EnergyBalance:
    """The EnergyBalance of the energy histories ``energy`` ({kind: (nt,) J} with "total"), without
    its warning."""
    total = np.asarray(energy["total"], float)
    if total.size == 0:
        return EnergyBalance(0.0, 0.0, 0.0, 0.0, 0.0, ENERGY_FLOOR_J, tolerance)
    if not np.all(np.isfinite(total)):  # the run blew up (an explicit method beyond its stability limit)
        return EnergyBalance(float("inf"), float("nan"), float("inf"), float("inf"), float("inf"), ENERGY_FLOOR_J,
                             tolerance)
    terms = [np.asarray(energy[k], float) for k in BOOKED if k in energy]
    exchanged = max([float(np.ptp(e)) for e in terms] + [float(np.max(np.abs(energy["kinetic"])))])
    worst_at = int(np.argmax(np.abs(total - total[0])))
    worst = abs(float(total[worst_at] - total[0]))
    error = worst / exchanged if exchanged > 0 else (0.0 if worst == 0 else float("nan"))
    floor = max(ENERGY_FLOOR_J, ROUND_OFF_RTOL * max(float(np.max(np.abs(e))) for e in terms))
    return EnergyBalance(error, exchanged, float(total[-1] - total[0]), float(total[worst_at] - total[0]), worst,
                         floor, tolerance)


def balance_beyond(balance: EnergyBalance, level: float) -> bool:
    """Whether the balance error passes ``level`` (relative to the energy exchanged) by a change
    above the floor of what the books resolve (module doc)."""
    return balance.balance_error > level and not balance.worst <= balance.floor


def balance_warning(balance: EnergyBalance, method: str, h: float, rho_inf: float | None, rtol: float | None,
                    stops: tuple = ()) -> str | None:
    """One line naming the likely cause and the fix when the balance error passes its tolerance
    by more than the floor (None otherwise); ``stops``: the names of the force elements with a
    bump stop (an unresolved impact is then the first suspect)."""
    error, tol = balance.balance_error, balance.tolerance
    if not balance_beyond(balance, tol):
        return None
    change = balance.excursion  # the largest change, not the end's: an impact may gain what the end lost
    grew = change > 0
    head = (f"energy balance error {error:.2g} of the energy exchanged ({balance.exchanged:.4g} J) passes "
            f"energy_tol = {tol:g}: the integration is not accurate" if np.isfinite(error) else
            "the energy became infinite or NaN: the integration blew up")
    if stops and np.isfinite(error):
        how = "grew" if grew else "fell"
        cause = (f"energy {how} by {abs(change):.3g} J: an impact on the bump stop of "
                 f"{', '.join(repr(n) for n in stops)} not resolved by the steps ({method}, "
                 + (f"h = {h:g} s" if method in ("genalpha", "rk4") and not rtol else f"rtol = {rtol:g}") + ")")
        fix = ("halve h" if method in ("genalpha", "rk4") and not rtol else "tighten rtol") + \
            ", or soften the stop (a lower stiffness or exponent) if its contact is shorter than the motion needs"
    elif method == "genalpha":
        if grew:
            cause = (f"energy grew by {change:.3g} J: the step h = {h:g} s is too large for the fastest "
                     "motion (the error falls as h^2)")
            fix = "halve h, or check the run against method = \"dop853\""
        elif rho_inf < 1.0:
            cause = (f"energy fell by {-change:.3g} J: numerical damping of rho_inf = {rho_inf:g} at "
                     f"h = {h:g} s")
            fix = "halve h or raise rho_inf towards 0.95"
        else:  # rho_inf = 1 damps nothing: the step does not resolve the motion
            cause = (f"energy fell by {-change:.3g} J: the step h = {h:g} s is too large for the fastest "
                     "motion (rho_inf = 1 has no numerical damping)")
            fix = "halve h, or lower rho_inf to 0.9 to damp the unresolved modes"
    else:
        cause = f"{method} with " + (f"rtol = {rtol:g}" if rtol else f"the fixed step h = {h:g} s (beyond its "
                                                                      "stability limit if the energy blew up)")
        fix = "tighten rtol (or halve h), or use method = \"genalpha\" for stiff scenes"
    return f"{head}; likely cause: {cause}; fix: {fix}"
