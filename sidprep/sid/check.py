"""One model check: a measured value against its tolerance, with a severity and a description.

The record of every check sidprep runs (sidprep.sid.checks on a SID, sidprep.reduction.fe_checks
and sidprep.reduction.stress against the full FE model).  Files and JSON hold it as the dict
``{"value", "tolerance", "passed", "severity", "description"}`` (:meth:`Check.as_dict`,
:meth:`Check.from_dict`).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields

#: what a failed check means: "error" breaks the model, "warning" may legitimately break, "info" tests nothing
SEVERITIES = ("error", "warning", "info")


@dataclass(frozen=True)
class Check:
    """A check's outcome.

    value : float or int or None
        The measured quantity (a relative residual unless the description says otherwise).
    tolerance : float or None
        The largest passing value; None for an "info" entry.
    passed : bool
    severity : str
        One of SEVERITIES.
    description : str
        What is compared, in one line.
    """

    value: float | int | None
    tolerance: float | None
    passed: bool
    severity: str
    description: str

    @classmethod
    def measured(cls, value, tolerance, description: str, severity: str = "error") -> Check:
        """``value`` (float) against ``tolerance``: passed when value <= tolerance (always, without one)."""
        tol = None if tolerance is None else float(tolerance)
        return cls(float(value), tol, bool(tol is None or value <= tol), severity, description)

    @classmethod
    def note(cls, value, description: str) -> Check:
        """An "info" entry: a reported number that tests nothing."""
        return cls(value, None, True, "info", description)

    @classmethod
    def from_dict(cls, entry: dict) -> Check:
        """The record of its dict form (:meth:`as_dict`), as read back from a file."""
        return cls(**{f.name: entry[f.name] for f in fields(cls)})

    def as_dict(self) -> dict:
        """The file / JSON form ``{"value", "tolerance", "passed", "severity", "description"}``."""
        return asdict(self)


def checks_as_dicts(checks: dict) -> dict:
    """``{name: Check}`` in its file / JSON form ``{name: {"value", ...}}``."""
    return {name: c.as_dict() for name, c in checks.items()}
