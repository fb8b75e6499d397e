"""The tables every scene file has, floating-frame and absolute-nodal alike: [solver] (how it is
integrated: a SolverSettings) and [output] (what is written besides the results file)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from sidprep.errors import InputError
from sidprep.solver.integrators.settings import METHODS, SolverSettings
from sidprep.tables import TomlTable


@dataclass(frozen=True)
class OutputSettings:
    """What ``sidprep simulate`` writes besides the results file.

    rate : samples per second of the results (None: every step); signals : names plotted and
    exported (sidprep/solver/results.py); plot, csv, animate : write a PNG, a CSV, a ParaView series.
    """

    rate: float | None = None
    signals: tuple[str, ...] = ()
    plot: bool = False
    csv: bool = False
    animate: bool = False


def read_output_settings(file: Path, root: dict) -> OutputSettings:
    """The OutputSettings of the [output] table of the parsed scene ``root`` (from ``file``)."""
    t = TomlTable(file, "output", root.get("output", {}))
    out = OutputSettings(rate=t.number("rate", None, positive=True), signals=t.strings("signals", []),
                         plot=t.boolean("plot"), csv=t.boolean("csv"), animate=t.boolean("animate"))
    t.finish()
    return out


#: [solver] keys read as numbers: scene key -> SolverSettings field
SOLVER_NUMBERS = {"step": "h", "rho_inf": "rho_inf", "rtol": "rtol", "atol": "atol", "newton_tol": "newton_tol",
                  "deformation_limit": "deformation_limit", "energy_tol": "energy_tol"}
#: [solver] keys read as true / false (same names as the SolverSettings fields)
SOLVER_FLAGS = ("static_start",)


def read_solver_settings(t: TomlTable, output: OutputSettings, t_end_override: float | None, *, methods=METHODS,
                         numbers=SOLVER_NUMBERS, flags=SOLVER_FLAGS, defaults=None) -> tuple[float, SolverSettings]:
    """(t_end s, SolverSettings) of a [solver] table ``t`` and the [output] rate: only the keys
    given are passed on, so every default and range check is SolverSettings' own (``defaults``:
    a formulation's own {field: value} where its scene leaves a key out; ``methods``, ``numbers``,
    ``flags``: the method names, number keys and true/false keys its scenes may use)."""
    given = dict(defaults or {})
    for key, name in numbers.items():
        value = t.number(key, None, positive=key != "rho_inf")
        if value is not None:
            given[name] = value
    method = t.string("method", None, methods)
    if method is not None:
        given["method"] = method
    for key in flags:
        if t.raw(key, None) is not None:
            given[key] = t.boolean(key)
    if output.rate is not None:
        given["output_dt"] = 1.0 / output.rate
    if t_end_override is None:
        t_end = t.number("t_end", positive=True)
    else:
        t.raw("t_end", None)
        if t_end_override <= 0:
            t.fail("t_end", f"--t-end must be > 0, got {t_end_override}", "give a positive end time in s")
        t_end = t_end_override
    try:
        settings = SolverSettings(**given)
    except InputError as exc:
        raise InputError(f"{t.file}: [solver] {exc}") from None
    if settings.h > t_end:
        t.fail("step", f"{settings.h} s is longer than t_end = {t_end} s", "use a smaller step")
    t.finish()
    return t_end, settings
