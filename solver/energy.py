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
naming the likely cause and the fix.
"""

from __future__ import annotations

import numpy as np

from sidprep.solver.integrators.settings import ENERGY_TOL
#: booked energy terms (postprocess.ENERGY_KINDS without the total)
BOOKED = ("kinetic", "strain", "gravity", "spring", "dissipated", "external", "stiffening")


def energy_balance(energy: dict, tolerance: float = ENERGY_TOL) -> dict:
    """{"balance_error", "exchanged" (J), "change" (J, E(end) - E(0)), "tolerance"} of the energy
    histories ``energy`` ({kind: (nt,) J} with "total"); balance_error is NaN for a run that
    exchanged no energy."""
    total = np.asarray(energy["total"], float)
    if total.size == 0:
        return {"balance_error": 0.0, "exchanged": 0.0, "change": 0.0, "tolerance": tolerance}
    if not np.all(np.isfinite(total)):  # the run blew up (an explicit method beyond its stability limit)
        return {"balance_error": float("inf"), "exchanged": float("nan"), "change": float("inf"),
                "tolerance": tolerance}
    terms = [np.asarray(energy[k], float) for k in BOOKED if k in energy]
    exchanged = max([float(np.ptp(e)) for e in terms] + [float(np.max(np.abs(energy["kinetic"])))])
    worst = float(np.max(np.abs(total - total[0])))
    error = worst / exchanged if exchanged > 0 else (0.0 if worst == 0 else float("nan"))
    return {"balance_error": error, "exchanged": exchanged, "change": float(total[-1] - total[0]),
            "tolerance": tolerance}


def balance_warning(balance: dict, method: str, h: float, rho_inf: float | None, rtol: float | None) -> str | None:
    """One line naming the likely cause and the fix when the balance error passes its tolerance
    (None otherwise)."""
    error, tol = balance["balance_error"], balance["tolerance"]
    if not error > tol:
        return None
    grew = balance["change"] > 0
    head = (f"energy balance error {error:.2g} of the energy exchanged ({balance['exchanged']:.4g} J) passes "
            f"energy_tol = {tol:g}: the integration is not accurate" if np.isfinite(error) else
            "the energy became infinite or NaN: the integration blew up")
    if method == "genalpha":
        if grew:
            cause = (f"energy grew by {balance['change']:.3g} J: the step h = {h:g} s is too large for the fastest "
                     "motion (the error falls as h^2)")
            fix = "halve h, or check the run against method = \"dop853\""
        elif rho_inf < 1.0:
            cause = (f"energy fell by {-balance['change']:.3g} J: numerical damping of rho_inf = {rho_inf:g} at "
                     f"h = {h:g} s")
            fix = "halve h or raise rho_inf towards 0.95"
        else:  # rho_inf = 1 damps nothing: the step does not resolve the motion
            cause = (f"energy fell by {-balance['change']:.3g} J: the step h = {h:g} s is too large for the fastest "
                     "motion (rho_inf = 1 has no numerical damping)")
            fix = "halve h, or lower rho_inf to 0.9 to damp the unresolved modes"
    else:
        cause = f"{method} with " + (f"rtol = {rtol:g}" if rtol else f"the fixed step h = {h:g} s (beyond its "
                                                                      "stability limit if the energy blew up)")
        fix = "tighten rtol (or halve h), or use method = \"genalpha\" for stiff scenes"
    return f"{head}; likely cause: {cause}; fix: {fix}"
