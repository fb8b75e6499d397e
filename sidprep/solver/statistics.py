"""How a run went and what it cost: the ``RunStatistics`` record of a Result.

A run builds the record once, at its end (sidprep/solver/run.py, sidprep/solver/absolute_nodal/run.py);
the results file stores its dict form (:meth:`RunStatistics.as_dict`) as JSON in ``/stats`` and the
reader turns it back into the record (:meth:`RunStatistics.from_dict`), so files written before the
record existed read unchanged.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields
from typing import Mapping

from sidprep.solver.energy import EnergyBalance


@dataclass(frozen=True)
class RunStatistics:
    """How a run went and what it cost.

    method : "genalpha", "rk4", ...; cpu_time : s, process time of the whole run; steps, rejected :
    accepted and rejected steps; h_min, h_max : s, the step sizes used.  A floating-frame run adds
    rhs_evaluations, newton_iterations, jacobians, the settings h (s), rho_inf, rtol, cpu_setup and
    cpu_integration (s), dropped_constraint_rows (names of the redundant rows left out),
    n_coordinates, planar, n_constraints and energy_balance (an EnergyBalance with its warning); an absolute-nodal run adds formulation, nodes and dof.  failed : why the
    run stopped early, None when it did not.
    """

    method: str
    cpu_time: float
    steps: int
    rejected: int
    h_min: float | None = None
    h_max: float | None = None
    rhs_evaluations: int | None = None
    newton_iterations: int | None = None
    jacobians: int | None = None
    h: float | None = None
    rho_inf: float | None = None
    rtol: float | None = None
    cpu_setup: float | None = None
    cpu_integration: float | None = None
    dropped_constraint_rows: tuple[str, ...] = ()
    n_coordinates: int | None = None
    planar: bool | None = None
    n_constraints: int | None = None
    energy_balance: EnergyBalance | None = None
    formulation: str | None = None
    nodes: int | None = None
    dof: int | None = None
    failed: str | None = None

    def as_dict(self) -> dict:
        """The file / JSON form: the keys of the run's formulation (absolute-nodal when ``formulation``
        is set, else floating-frame) in file order, and "failed" for a run that stopped early."""
        keys = ABSOLUTE_NODAL_STATISTICS if self.formulation else FLOATING_FRAME_STATISTICS
        out = {key: getattr(self, key) for key in keys}
        if "dropped_constraint_rows" in out:
            out["dropped_constraint_rows"] = list(self.dropped_constraint_rows)
        if self.energy_balance is not None:
            out["energy_balance"] = asdict(self.energy_balance)
        if self.failed is not None:
            out["failed"] = self.failed
        return out

    @classmethod
    def from_dict(cls, stats: Mapping) -> RunStatistics:
        """The record of its dict form (:meth:`as_dict`), as read back from a results file; keys
        this version does not know are left out."""
        stats = {key: value for key, value in stats.items() if key in {f.name for f in fields(cls)}}
        if "dropped_constraint_rows" in stats:
            stats["dropped_constraint_rows"] = tuple(stats["dropped_constraint_rows"])
        if stats.get("energy_balance") is not None:
            booked = {f.name for f in fields(EnergyBalance)}
            stats["energy_balance"] = EnergyBalance(**{key: value for key, value in stats["energy_balance"].items()
                                                       if key in booked})
        return cls(**stats)


#: the statistics of a floating-frame run and of an absolute-nodal run, in file order
FLOATING_FRAME_STATISTICS = ("steps", "rejected", "rhs_evaluations", "newton_iterations", "jacobians", "h_min",
                             "h_max", "method", "h", "rho_inf", "rtol", "cpu_time", "cpu_setup", "cpu_integration",
                             "dropped_constraint_rows", "n_coordinates", "planar", "n_constraints", "energy_balance")
ABSOLUTE_NODAL_STATISTICS = ("method", "cpu_time", "steps", "rejected", "h_min", "h_max", "formulation", "nodes",
                             "dof")
