"""What accuracy costs on the user's own scene: a ladder of solver settings, each run's error
estimated from the ladder itself, and the cheapest setting that meets a tolerance.

The scene runs (to the end of its window) once per setting: for each method a geometric ladder of
steps h0 * 2, h0, h0 / 2, ... (fixed-step generalised-alpha at each rho_inf, RK4) or of rtol
(RK45, DOP853), plus the other effects choice ("all" against "auto").  The reference is the
Richardson extrapolation of the finest three runs of the most converged fixed-step ladder
(Richardson 1911; Roache 1998, "Verification and Validation in Computational Science", ch. 5):

    p  = log2(|x_2h - x_h| / |x_h - x_h/2|)          observed order, max over the output samples
    x* = x_h/2 + (x_h/2 - x_h) / (2^p - 1)            extrapolated signal

and every run's error is max |x - x*| over the window's output samples, relative to the range of
x* there.  The runs execute on any executor with ``submit(fn, *args) -> future`` and ``wait(futures)
-> done`` (a local process pool or Dask: sidprep.jobs.executor), or one by one in this process.
"""

from __future__ import annotations

import functools
import math
import os
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from sidprep.solver.integrators.settings import ADAPTIVE_ONLY, METHODS
from sidprep.solver.results import signal
from sidprep.solver.scene import empty_result, load_scene, simulate

from sidprep.errors import InputError

#: default relative tolerance of ``converge`` (error / signal range)
DEFAULT_TOL = 1e-3
#: runs per ladder: fixed steps h0 * 2 ... h0 / 2^(LEVELS - 2); rtol ADAPTIVE_RTOL0 ... / 10^(LEVELS - 1)
LEVELS = 5
#: the coarsest rtol of the RK45 / DOP853 ladders and the factor between rungs
ADAPTIVE_RTOL0 = 1e-3
RTOL_FACTOR = 10.0
#: generalised-alpha is laddered at the scene's rho_inf and at this one
RHO_ALTERNATIVE = 0.6
#: observed orders outside [P_MIN, P_MAX] are not asymptotic: the reference is then the finest run
#: itself, and its own error is taken as the whole last difference (no extrapolation)
P_MIN, P_MAX = 0.5, 8.0
#: a warm-up run of this many steps before a process's first timed run of a method and effects: the
#: first call's costs (the modules the run imports on first use) stay out of the run's CPU-s
WARM_UP_STEPS = 5


@dataclass(frozen=True)
class Setting:
    """One rung: method, step h (s; the initial step of rk45 / dop853), rho_inf (genalpha, else
    None), rtol (step-size control, else None), effects ("auto", "all" or a tuple of names)."""

    method: str
    h: float
    rho_inf: float | None = None
    rtol: float | None = None
    effects: object = "auto"

    @property
    def label(self) -> str:
        step = f"rtol {self.rtol:.0e}" if self.rtol else f"h {self.h:.4g} s"
        rho = f", rho_inf {self.rho_inf:g}" if self.rho_inf is not None else ""
        return f"{self.method} {step}{rho}, effects {self.effects}"

    @property
    def family(self) -> str:
        """The ladder it belongs to (one line of the Pareto plot)."""
        rho = f" rho_inf {self.rho_inf:g}" if self.rho_inf is not None else ""
        return f"{self.method}{rho}" + ("" if self.effects == "auto" else f" effects {self.effects}")

    def toml(self) -> str:
        """The lines to paste into [solver] (the effects go into [scene])."""
        lines = [f'method = "{self.method}"', f"step = {self.h:.6g}"]
        if self.rho_inf is not None:
            lines.append(f"rho_inf = {self.rho_inf:g}")
        if self.rtol is not None:
            lines.append(f"rtol = {self.rtol:.3g}")
        return "\n".join(lines)


@dataclass(frozen=True)
class Outcome:
    """What a run returns from its worker: the window's sample times (nt,), signal values
    (n_signals, nt), CPU-s of the run (after the warm-up), CPU-s of the process's warm-up
    (0 when it was warm), the energy balance error (sidprep/solver/energy.py) and a failure (or None)."""

    t: np.ndarray
    values: np.ndarray
    cpu_s: float
    warm_up_cpu_s: float
    balance_error: float | None
    failed: str | None = None


@dataclass(frozen=True)
class SignalError:
    """A run's error in one signal: max |x - x*| (signal unit), that over the range of x*, and the
    observed order of its ladder at this rung (None: no two finer rungs)."""

    name: str
    absolute: float
    relative: float
    order: float | None


@dataclass(frozen=True)
class LadderRun:
    setting: Setting
    cpu_s: float
    errors: tuple[SignalError, ...]
    energy_balance_error: float | None
    failed: str | None = None

    @property
    def limiting(self) -> SignalError | None:
        """The signal of the largest relative error (None for a failed run)."""
        return max(self.errors, key=lambda e: e.relative, default=None)

    @property
    def estimated_error(self) -> float:
        """The largest relative error over the signals (inf for a failed run)."""
        return max((e.relative for e in self.errors), default=math.inf) if self.failed is None else math.inf

    def as_dict(self) -> dict:
        s = self.setting
        return {"method": s.method, "step": s.h, "rho_inf": s.rho_inf, "rtol": s.rtol, "effects": s.effects,
                "cpu_s": self.cpu_s, "estimated_error": _finite(self.estimated_error),
                "energy_balance_error": self.energy_balance_error, "failed": self.failed,
                "signals": {e.name: {"absolute": e.absolute, "relative": e.relative, "order": e.order}
                            for e in self.errors}}


@dataclass(frozen=True)
class ConvergeOptions:
    """signals : names (sidprep/solver/results.py), default the scene's [output] signals but energy.*;
    tol : relative error to meet; window : (t0, t1) s, the scene runs to t1 and is compared on
    [t0, t1] (default: 0 to its t_end); methods : the ladders' methods; levels : rungs per
    ladder; effects : also run the other effects choice; progress : None or callable(done, total)."""

    signals: tuple[str, ...] = ()
    tol: float = DEFAULT_TOL
    window: tuple[float, float] | None = None
    methods: tuple[str, ...] = METHODS
    levels: int = LEVELS
    effects: bool = True
    step: float | None = None
    progress: object = None


@dataclass(frozen=True)
class ConvergeReport:
    """scene : file; signals; window (t0, t1) s; tol; reference : the ladder extrapolated;
    orders : {signal: observed order of the reference ladder}; runs; recommended (None: no run
    meets tol); effects_change : max relative change of the other effects choice (None: not run);
    warm_up_cpu_s : CPU-s the processes spent in warm-up runs before their first timed run; wall_s;
    load : the machine's load average (1, 5, 15 min) at the end: the CPU-s are this machine's."""

    scene: str
    signals: tuple[str, ...]
    window: tuple[float, float]
    tol: float
    reference: str
    orders: dict
    runs: tuple[LadderRun, ...]
    recommended: LadderRun | None
    effects_change: float | None
    warm_up_cpu_s: float
    wall_s: float
    load: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def recommendation(self) -> LadderRun:
        """The recommended run; InputError naming what was tried and what came closest if none."""
        if self.recommended is not None:
            return self.recommended
        done = [r for r in self.runs if r.failed is None]
        best = min(done, key=lambda r: r.estimated_error)
        missed = {e.name for e in best.errors if e.relative > self.tol}
        unresolved = [f"{name} (observed order {p:.2g})" for name, p in self.orders.items()
                      if name in missed and not P_MIN <= p <= P_MAX]
        why = (f"; not converging over the ladder: {', '.join(unresolved)}: at the solver's noise floor or "
               "needing smaller steps, leave them out (--signal) or give a smaller --step" if unresolved else "")
        raise InputError(f"{self.scene}: no setting meets --tol {self.tol:g}: tried {len(self.runs)} settings "
                         f"({', '.join(sorted({r.setting.family for r in self.runs}))}); closest: "
                         f"{best.setting.label} with {best.estimated_error:.3g} at {best.cpu_s:.3g} CPU-s{why}; "
                         "loosen --tol or add rungs (--levels)")

    def as_dict(self) -> dict:
        rec = self.recommended
        return {"scene": self.scene, "signals": list(self.signals), "window": list(self.window), "tol": self.tol,
                "reference": self.reference, "observed_order": self.orders, "effects_change": self.effects_change,
                "warm_up_cpu_s": self.warm_up_cpu_s, "wall_s": self.wall_s,
                "load_average": list(self.load),
                "runs": [r.as_dict() for r in self.runs],
                "recommended": None if rec is None else {**rec.as_dict(), "toml": rec.setting.toml()}}


def _finite(x: float) -> float | None:
    return x if math.isfinite(x) else None


# ---------------------------------------------------------------------------------------------
# the ladder


def ladder(base, options: ConvergeOptions, scene_effects) -> list[Setting]:
    """The settings to run: per method its rungs; the other effects choice at the scene's method
    and step.  ``base``: the scene's SolverSettings."""
    h0 = options.step or base.h
    steps = [h0 * 2.0 ** (1 - k) for k in range(options.levels)]
    rtols = [ADAPTIVE_RTOL0 / RTOL_FACTOR ** k for k in range(options.levels)]
    effects = scene_effects if scene_effects in ("auto", "all") else tuple(scene_effects)
    settings = []
    for method in options.methods:
        if method == "genalpha":
            for rho in dict.fromkeys((base.rho_inf, RHO_ALTERNATIVE)):
                settings += [Setting(method, h, rho_inf=rho, effects=effects) for h in steps]
        elif method in ADAPTIVE_ONLY:
            settings += [Setting(method, h0, rtol=r, effects=effects) for r in rtols]
        else:
            settings += [Setting(method, h, effects=effects) for h in steps]
    if options.effects:
        other = "all" if effects != "all" else "auto"
        first = settings[0]
        settings.append(replace(first, h=steps[min(2, len(steps) - 1)] if first.rtol is None else first.h,
                                effects=other))
    return settings


@functools.lru_cache(maxsize=4)
def _scene(path: str, sha256: str):
    """The parsed scene of a worker process (parsed once per process; sha256 keys its content)."""
    return load_scene(path)


_WARM: set = set()


def run_setting(path: str, sha256: str, setting: Setting, t_end: float, output_dt: float, signals: tuple,
                window: tuple) -> Outcome:
    """One rung (a top-level function: the task a worker runs).  The first run of a method and
    effects in a process is preceded by a warm-up of WARM_UP_STEPS steps (the first call's imports),
    so that cpu_s is the run's own."""
    scene = _scene(path, sha256)
    kw = {"method": setting.method, "h": setting.h, "rtol": setting.rtol, "output_dt": output_dt,
          "effects": setting.effects, "progress": None,
          "rho_inf": setting.rho_inf if setting.rho_inf is not None else scene.settings.rho_inf}
    warm = 0.0
    if (setting.method, setting.effects) not in _WARM:
        cpu0 = time.process_time()
        try:
            simulate(scene, replace(scene.settings, **kw), t_end=min(t_end, WARM_UP_STEPS * setting.h))
        except InputError:
            pass                  # the run itself reports it
        _WARM.add((setting.method, setting.effects))
        warm = time.process_time() - cpu0
    try:
        result = simulate(scene, replace(scene.settings, **kw), t_end=t_end)
    except InputError as exc:
        return Outcome(np.zeros(0), np.zeros((len(signals), 0)), math.nan, warm, None,
                       str(exc).split("\n")[0].removeprefix(f"{path}: "))
    inside = (result.t >= window[0] - 1e-9 * t_end) & (result.t <= window[1] + 1e-9 * t_end)
    values = np.array([signal(result, name)[0][inside] for name in signals])
    failed = None if np.all(np.isfinite(values)) else "non-finite signal values"
    return Outcome(result.t[inside], values, float(result.stats.cpu_time), warm,
                   result.stats.energy_balance.balance_error, failed)


def execute(tasks: list[tuple], pool=None, progress=None) -> list[Outcome]:
    """run_setting(*task) for every task, on ``pool`` (submit / wait) or one by one here."""
    outcomes: list = [None] * len(tasks)

    def finished(k, outcome):
        outcomes[k] = outcome
        if progress:
            progress(sum(o is not None for o in outcomes), len(tasks))

    if pool is None:
        for k, task in enumerate(tasks):
            finished(k, run_setting(*task))
        return outcomes
    futures = {pool.submit(run_setting, *task): k for k, task in enumerate(tasks)}
    pending = set(futures)
    while pending:
        for f in pool.wait(pending):
            pending.discard(f)
            finished(futures[f], f.result())
    return outcomes


# ---------------------------------------------------------------------------------------------
# the error estimate


def observed_order(coarse: np.ndarray, middle: np.ndarray, fine: np.ndarray) -> float:
    """p = log2(max|x_2h - x_h| / max|x_h - x_h/2|) of three rungs halving the step, (nt,) each."""
    d1, d2 = np.max(np.abs(coarse - middle)), np.max(np.abs(middle - fine))
    return float(np.log2(d1 / d2)) if d1 > 0 and d2 > 0 else math.nan


def extrapolated(middle: np.ndarray, fine: np.ndarray, p: float) -> np.ndarray:
    """x* = x_h/2 + (x_h/2 - x_h) / (2^p - 1) (Richardson); the finest rung when p is not in
    [P_MIN, P_MAX], with its error taken as the whole last difference (x* = 2 x_h/2 - x_h)."""
    if not P_MIN <= p <= P_MAX:
        return fine + (fine - middle)
    return fine + (fine - middle) / (2.0**p - 1.0)


def fixed_ladders(settings, outcomes) -> dict:
    """{family: [(h, outcome), ...] finest last} of the fixed-step ladders' successful rungs."""
    ladders: dict = {}
    for s, o in zip(settings, outcomes):
        if s.rtol is None and o.failed is None:
            ladders.setdefault(s.family, []).append((s.h, o))
    return {f: sorted(rungs, key=lambda r: -r[0]) for f, rungs in ladders.items()}


def reference_signals(ladders: dict, signals: tuple) -> tuple[str, np.ndarray, np.ndarray, dict]:
    """(family, t, x* (n_signals, nt), {signal: p}) of the most converged ladder with three
    successful rungs halving the step (smallest last difference relative to the signal ranges)."""
    best = None
    for family, rungs in ladders.items():
        if len(rungs) < 3 or not np.isclose(rungs[-3][0], 4 * rungs[-1][0]):
            continue
        (_, a), (_, b), (_, c) = rungs[-3:]
        if a.values.shape != c.values.shape or b.values.shape != c.values.shape:
            continue
        ranges = np.ptp(c.values, axis=1) + 1e-300
        spread = float(np.max(np.max(np.abs(c.values - b.values), axis=1) / ranges))
        if best is None or spread < best[0]:
            best = (spread, family, a, b, c)
    if best is None:
        return None
    _, family, a, b, c = best
    orders = {name: observed_order(a.values[i], b.values[i], c.values[i]) for i, name in enumerate(signals)}
    ref = np.array([extrapolated(b.values[i], c.values[i], orders[name]) for i, name in enumerate(signals)])
    return family, c.t, ref, orders


def run_errors(setting, outcome, reference, ladders, signals) -> LadderRun:
    """The LadderRun of one rung: its errors against the reference x*, the observed order of its
    own ladder from this rung down (when two finer rungs exist)."""
    if outcome.failed is not None:
        return LadderRun(setting, outcome.cpu_s, (), outcome.balance_error, outcome.failed)
    _, t_ref, ref, _ = reference
    rungs = ladders.get(setting.family, []) if setting.rtol is None else []
    hs = [h for h, _ in rungs]
    k = next((i for i, h in enumerate(hs) if np.isclose(h, setting.h)), None)
    errors = []
    for i, name in enumerate(signals):
        x = np.interp(t_ref, outcome.t, outcome.values[i]) if outcome.t.shape != t_ref.shape or \
            not np.allclose(outcome.t, t_ref) else outcome.values[i]
        absolute = float(np.max(np.abs(x - ref[i])))
        scale = float(np.ptp(ref[i])) or float(np.max(np.abs(ref[i]))) or 1.0
        order = None
        if k is not None and k + 2 < len(rungs) and np.isclose(hs[k], 4 * hs[k + 2]):
            p = observed_order(*(rungs[j][1].values[i] for j in (k, k + 1, k + 2)))
            order = p if math.isfinite(p) else None
        errors.append(SignalError(name, absolute, absolute / scale, order))
    return LadderRun(setting, outcome.cpu_s, tuple(errors), outcome.balance_error)


# ---------------------------------------------------------------------------------------------
# the study


def scene_signals(scene, names: tuple) -> tuple[str, ...]:
    """The signals compared: ``names``, else the scene's [output] signals but the energy books
    (their balance is reported per run); InputError for an unknown name or none at all."""
    chosen = tuple(names) or tuple(n for n in scene.output.signals if not n.startswith("energy."))
    if not chosen:
        raise InputError(f"{scene.path}: no signals to compare: the scene's [output] signals name none but "
                         "energy.*; name them with --signal (e.g. a joint's .coordinate or a body's .q.1)")
    empty = empty_result(scene.system)
    for name in chosen:
        try:
            signal(empty, name)
        except InputError as exc:
            raise InputError(f"{scene.path}: --signal: {exc}") from None
    return chosen


def study_window(scene, window) -> tuple[float, float]:
    """(t0, t1) s of the comparison; InputError for an empty or negative one."""
    t0, t1 = window if window is not None else (0.0, scene.t_end)
    if not (0.0 <= t0 < t1 and math.isfinite(t1)):
        raise InputError(f"{scene.path}: --window {t0:g} {t1:g}: needs 0 <= T0 < T1 (s)")
    return float(t0), float(t1)


def converge(scene_path, options: ConvergeOptions = ConvergeOptions(), pool=None) -> ConvergeReport:
    """Run the scene file ``scene_path`` on the ladder of settings and estimate every run's error.

    pool : an executor (``submit``, ``wait``; sidprep.jobs.executor.task_pool) or None (this process).
    Returns the ConvergeReport; InputError for bad input and for a scene that fails at every rung.
    """
    if not options.tol > 0 or options.levels < 3:
        raise InputError(f"converge: --tol {options.tol:g} must be > 0 and --levels {options.levels} >= 3")
    bad = [m for m in options.methods if m not in METHODS]
    if bad:
        raise InputError(f"converge: unknown method {bad[0]!r}; use one of {', '.join(METHODS)}")
    wall0 = time.perf_counter()
    scene = load_scene(scene_path)
    signals = scene_signals(scene, options.signals)
    window = study_window(scene, options.window)
    effects = scene.settings.effects if scene.settings.effects is not None else scene.system.effects
    settings = ladder(scene.settings, options, effects)
    output_dt = scene.settings.output_dt or 2.0 * (options.step or scene.settings.h)
    tasks = [(str(scene.path), scene.sha256, s, window[1], output_dt, signals, window) for s in settings]
    outcomes = execute(tasks, pool, options.progress)
    ladders = fixed_ladders(settings, outcomes)
    reference = reference_signals(ladders, signals)
    if reference is None:
        failed = [(s, o) for s, o in zip(settings, outcomes) if o.failed is not None]
        first = f"; e.g. {failed[0][0].label}: {failed[0][1].failed}" if failed else ""
        raise InputError(f"{scene.path}: no fixed-step ladder has three successful rungs to extrapolate: tried "
                         f"{len(settings)} settings, {len(failed)} failed{first}; check the scene with "
                         "`sidprep simulate` or give a smaller [solver] step")
    runs = tuple(run_errors(s, o, reference, ladders, signals) for s, o in zip(settings, outcomes))
    meeting = [r for r in runs if r.estimated_error <= options.tol and r.setting.effects == settings[0].effects]
    recommended = min(meeting, key=lambda r: r.cpu_s) if meeting else None
    effects_change = effects_difference(settings, outcomes)
    return ConvergeReport(str(scene.path), signals, window, options.tol, reference[0], reference[3], runs,
                          recommended, effects_change, sum(o.warm_up_cpu_s for o in outcomes),
                          time.perf_counter() - wall0, os.getloadavg())


def effects_difference(settings, outcomes) -> float | None:
    """max over the signals of max |x_other - x_scene| / range(x_scene): what the other effects
    choice changes at the same step (None when it was not run or one of the two failed)."""
    by_setting = dict(zip(settings, outcomes))
    other = next((s for s in settings if s.effects != settings[0].effects), None)
    if other is None:
        return None
    a, b = by_setting[other], by_setting.get(replace(other, effects=settings[0].effects))
    if b is None or a.failed or b.failed or a.values.shape != b.values.shape:
        return None
    scale = np.ptp(b.values, axis=1) + 1e-300
    return float(np.max(np.max(np.abs(a.values - b.values), axis=1) / scale))


def plot_pareto(report: ConvergeReport, path) -> Path:
    """The Pareto plot: estimated error against CPU-s, one line per ladder, the tolerance dotted."""
    import matplotlib  # deferred: 0.45 CPU-s of import (with pyplot), plots only

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # deferred: see above

    fig, ax = plt.subplots(figsize=(7, 4.5))
    for family in dict.fromkeys(r.setting.family for r in report.runs):
        rows = sorted((r.cpu_s, r.estimated_error) for r in report.runs
                      if r.setting.family == family and r.failed is None and r.estimated_error > 0)
        if rows:
            ax.loglog(*zip(*rows), "o-", label=family)
    ax.axhline(report.tol, ls=":", color="k", label=f"tol {report.tol:g}")
    if report.recommended is not None:
        ax.loglog(report.recommended.cpu_s, report.recommended.estimated_error, "k*", ms=14, label="recommended")
    ax.set_xlabel("CPU-s per run")
    ax.set_ylabel("estimated error / signal range")
    ax.set_title(f"{Path(report.scene).name}: t = {report.window[0]:g}-{report.window[1]:g} s")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
