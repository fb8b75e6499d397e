#!/usr/bin/env python3
"""Long runs of the hard cases of tests/test_stability.py on every integrator (run on demand).

    python benchmarks/stability.py [--cases whirl rotor dead_centres] [--methods genalpha rk4 rk45 dop853]
                                   [--t-end 60] [--explicit-t-end 5]

The scenes are those of ``tests/test_stability.py`` (imported from there, one definition):

* ``whirl``: the bundled 10-mode bar (examples/flexible_pendulum/bar.sid.h5, 264 Hz ... 2.7 kHz,
  no damping) hinged at its end face about y, started at 50 rad/s under gravity;
* ``rotor``: the bar clamped-frame, 4 modes, reduced with ``--stiffening``, driven about z
  through its root at 1.5 x its first lag frequency, centrifugal stiffening on (above the
  critical speed without it the lag mode is unstable: the test shows that);
* ``dead_centres``: the undriven rigid slider crank at 30 rad/s (a dead centre every half
  turn: 19 per second), no gravity, no friction.

Per method the settings of the test suite: genalpha h = 1 ms, rho_inf 0.9 (rotor: 0.25 ms);
rk4 inside its stability limit (h = 0.1 ms, rotor 0.05 ms); rk45 / dop853 rtol 1e-8.  The
explicit methods run ``--explicit-t-end`` (they take ~100x the CPU).  Columns: simulated time,
the energy balance error (sidprep/solver/energy.py: largest |E(t) - E(0)| over the energy exchanged),
|E(end) - E(0)| / E(0) (secular drift), steps, integration CPU s and CPU s per simulated s.  The
machine's load average is printed: the CPU columns are noisy on the shared machine.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from test_stability import (ON, PENDULUM_SID, _Z_TO_Y, hinged_flexible, reduced_bar, rotor,  # noqa: E402
                            slider_crank)

from sidprep.errors import SimulationFailed  # noqa: E402
from sidprep.sid.io import read_sid  # noqa: E402
from sidprep.solver import simulate  # noqa: E402
from sidprep.solver.integrators.settings import METHODS  # noqa: E402

CASES = ("whirl", "rotor", "dead_centres")
#: per case, the settings that differ from the suite's ON (a faster scene needs a finer step)
CASE_SETTINGS = {"rotor": {"genalpha": {"h": 2.5e-4}, "rk4": {"h": 5e-5}}}


def settings(case: str, method: str) -> dict:
    """The solver settings of ``case`` on ``method``."""
    return {**ON[method], **CASE_SETTINGS.get(case, {}).get(method, {})}


def scene(case: str, workdir: Path):
    """The System of ``case`` (SIDs reduced into ``workdir`` where needed)."""
    from sidprep.solver import Revolute, System

    if case == "whirl":
        s = System(gravity=(0.0, 0.0, -9.81))
        _, marker = hinged_flexible(read_sid(PENDULUM_SID))(s)
        s.add(Revolute(s.ground.marker(rotation=_Z_TO_Y), marker, name="hinge"))
        return s
    if case == "rotor":
        return rotor(reduced_bar(workdir, "--modes", "4", "--frame", "fixed_end", "--stiffening"), True)[0]
    return slider_crank()


def measure(case: str, method: str, t_end: float, workdir: Path) -> dict:
    """One long run: its balance error, drift, steps and CPU (a failure is reported, not raised)."""
    try:
        r = simulate(scene(case, workdir), t_end, method=method, output_dt=1e-2, **settings(case, method))
        failed = ""
    except SimulationFailed as exc:
        r, failed = exc.result, str(exc)[:90]
    e = r.energy["total"]
    cpu = r.stats.cpu_integration
    return {"t": float(r.t[-1]), "balance": r.stats.energy_balance.balance_error,
            "drift": abs(e[-1] - e[0]) / abs(e[0]), "steps": r.stats.steps, "cpu": cpu,
            "cpu_per_s": cpu / max(float(r.t[-1]), 1e-12), "failed": failed}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cases", nargs="+", choices=CASES, default=list(CASES))
    p.add_argument("--methods", nargs="+", choices=METHODS, default=list(METHODS))
    p.add_argument("--t-end", type=float, default=60.0, help="simulated time of genalpha, s")
    p.add_argument("--explicit-t-end", type=float, default=5.0, help="simulated time of rk4 / rk45 / dop853, s")
    args = p.parse_args(argv)
    print("load average %.1f %.1f %.1f" % os.getloadavg())
    print("| case | method | settings | t s | balance error | drift E(end) | steps | CPU s | CPU s / s | note |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for case in args.cases:
            for method in args.methods:
                t_end = args.t_end if method == "genalpha" else args.explicit_t_end
                m = measure(case, method, t_end, Path(tmp))
                shown = ", ".join(f"{k} {v:g}" for k, v in settings(case, method).items())
                print(f"| {case} | {method} | {shown} | {m['t']:.4g} | {m['balance']:.2g} | {m['drift']:.2g} | "
                      f"{m['steps']} | {m['cpu']:.1f} | {m['cpu_per_s']:.2f} | {m['failed']} |", flush=True)
    print("load average %.1f %.1f %.1f" % os.getloadavg())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
