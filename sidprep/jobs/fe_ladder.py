"""What accuracy costs on the FE side: one body reduced with a ladder of mode counts, with and
without frequency-response modes, each rung's errors against the full FE model and its cost.

Every rung is a complete ``reduce`` (mesh, assembly, Craig-Bampton, modal basis, SID, checks), so
its CPU-s is what ``sidprep reduce`` with that setting costs.  The errors are the ones the checks
of every reduction make against the full FE model (sidprep.reduction.fe_checks): the static
deflection at the interface masters under unit loads (the FEMBS 1 % promise) and the
eigenfrequencies of the kept eigenmodes.  The rungs run on any executor with ``submit(fn, *args) ->
future`` (sidprep.jobs.executor.task_pool) or one by one in this process.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

from sidprep.errors import InputError
from sidprep.jobs.options import ReduceOptions
from sidprep.jobs.reduce import reduce
from sidprep.reduction.fe_checks import STATIC_CHECK_TOL

#: eigenmode counts of the ladder
MODE_LADDER = (2, 4, 6, 8, 12, 16, 24)
#: default tolerance of the kept eigenmodes' frequency error (relative)
FREQUENCY_TOL = 0.01


@dataclass(frozen=True)
class FERung:
    """One reduction: its eigenmode count, FRMs on / off, body size nq, CPU-s of the reduction,
    static deflection error at the interfaces (max over unit forces, relative), the kept
    eigenmodes' frequency error (relative), or the failure."""

    modes: int
    frm: bool
    nq: int = 0
    cpu_s: float = math.nan
    static_error: float = math.inf
    frequency_error: float = math.inf
    failed: str | None = None

    def meets(self, static_tol: float, frequency_tol: float) -> bool:
        return self.failed is None and self.static_error <= static_tol and self.frequency_error <= frequency_tol

    def as_dict(self) -> dict:
        return {"modes": self.modes, "frm": self.frm, "nq": self.nq, "cpu_s": self.cpu_s,
                "static_deflection_error": self.static_error, "frequency_error": self.frequency_error,
                "failed": self.failed}


@dataclass(frozen=True)
class FELadderReport:
    """mesh; the tolerances; rungs; recommended: the meeting rung of the smallest nq, then the
    cheapest (None: none meets)."""

    mesh: str
    static_tol: float
    frequency_tol: float
    rungs: tuple[FERung, ...]
    recommended: FERung | None

    def recommendation(self) -> FERung:
        """The recommended rung; InputError naming what was tried and what came closest if none."""
        if self.recommended is not None:
            return self.recommended
        done = [r for r in self.rungs if r.failed is None]
        if not done:
            raise InputError(f"{self.mesh}: every reduction of the ladder failed, e.g. {self.rungs[0].failed}")
        best = min(done, key=lambda r: max(r.static_error / self.static_tol, r.frequency_error / self.frequency_tol))
        raise InputError(f"{self.mesh}: no reduction meets static {self.static_tol:g} and frequency "
                         f"{self.frequency_tol:g}: tried modes {', '.join(map(str, sorted({r.modes for r in self.rungs})))}"
                         f" with and without FRMs; closest: {best.modes} modes{' + FRMs' if best.frm else ''} (static "
                         f"{best.static_error:.3g}, frequency {best.frequency_error:.3g}); loosen the tolerances or "
                         "add larger mode counts (--modes-ladder)")

    def as_dict(self) -> dict:
        rec = self.recommended
        return {"mesh": self.mesh, "static_tol": self.static_tol, "frequency_tol": self.frequency_tol,
                "runs": [r.as_dict() for r in self.rungs], "recommended": None if rec is None else rec.as_dict()}


def reduce_rung(mesh: str, options: ReduceOptions) -> FERung:
    """One rung (a top-level function: the task a worker runs): ``reduce`` timed in CPU-s."""
    cpu0 = time.process_time()
    try:
        result = reduce(mesh, options)
    except InputError as exc:
        return FERung(options.modes, options.frm, failed=str(exc))
    checks = result.checks
    return FERung(options.modes, options.frm, result.sid.nq, time.process_time() - cpu0,
                  checks["static_deflection_max_rel_error"], checks.get("eigen_frequency_max_rel_error", math.nan))


def fe_ladder(mesh, options: ReduceOptions = ReduceOptions(), *, modes=MODE_LADDER, static_tol=STATIC_CHECK_TOL,
              frequency_tol=FREQUENCY_TOL, pool=None) -> FELadderReport:
    """Reduce ``mesh`` (a path) with ``options`` at every count of ``modes``, with and without FRMs.

    pool : an executor (``submit``) or None (this process).  Recommended: the rung meeting both
    tolerances with the smallest body (nq: what the solver carries), then the least CPU-s.
    """
    if not (static_tol > 0 and frequency_tol > 0) or not modes or min(modes) < 1:
        raise InputError(f"{mesh}: the tolerances must be > 0 and the mode counts >= 1, got static {static_tol}, "
                         f"frequency {frequency_tol}, modes {list(modes)}")
    settings = [replace(options, modes=int(n), fmax=None, frm=frm) for frm in (True, False) for n in modes]
    if pool is None:
        rungs = [reduce_rung(str(mesh), o) for o in settings]
    else:
        futures = [pool.submit(reduce_rung, str(mesh), o) for o in settings]
        rungs = [f.result() for f in futures]
    meeting = [r for r in rungs if r.meets(static_tol, frequency_tol)]
    recommended = min(meeting, key=lambda r: (r.nq, r.cpu_s)) if meeting else None
    return FELadderReport(str(mesh), static_tol, frequency_tol, tuple(rungs), recommended)
