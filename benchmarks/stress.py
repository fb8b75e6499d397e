"""Cost of stress recovery (run on demand).

    python benchmarks/stress.py [--repeat 5]

1. ``sidprep reduce data/meshes/piston_rod.msh`` with and without ``--stress`` (in one process,
   alternating, so both see the same machine load): median wall and CPU seconds of the whole
   reduction, and of the two stress phases (modal stresses; the FE stress check inside "checks").
   Target: --stress adds <= 30 %.
2. ``sidprep.recover_stress`` of 1 s of examples/engine at 5000 samples/s (5001 samples, 20 modal
   coordinates, all 3726 surface nodes): the run is simulated once into a temporary folder.
   Target: <= 1 s.

The machine is shared: the load average is printed with every row.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ENGINE = ROOT / "examples" / "engine"
ROD = ROOT / "data" / "meshes" / "piston_rod.msh"


def timed(fn):
    """(wall s, CPU s of this process) of fn()."""
    w, c = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - w, time.process_time() - c


def reduce_cost(repeat: int) -> dict:
    from sidprep.jobs.options import ReduceOptions
    from sidprep.jobs.reduce import reduce

    out = {None: [], "surface": []}
    phases = {"stress": [], "checks with": [], "checks without": []}
    reduce(ROD, ReduceOptions())                                          # imports, caches
    for _ in range(repeat):
        for stress in (None, "surface"):
            holder = {}
            out[stress].append(timed(lambda: holder.setdefault("r", reduce(ROD, ReduceOptions(stress=stress)))))
            t = holder["r"].timings_s
            if stress:
                phases["stress"].append(t["stress"])
                phases["checks with"].append(t["checks"])
            else:
                phases["checks without"].append(t["checks"])
    med = {k: (statistics.median(w for w, _ in v), statistics.median(c for _, c in v)) for k, v in out.items()}
    return {"without": med[None], "with": med["surface"],
            "phases": {k: statistics.median(v) for k, v in phases.items()}}


def engine_results(folder: Path) -> Path:
    for name in ("scene.toml", "gas_force.py", "crank.obj", "piston.obj"):
        shutil.copy(ENGINE / name, folder / name)
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    run = [sys.executable, "-m", "sidprep.cli.main"]
    subprocess.run(run + ["reduce", str(ROD), "-o", "piston_rod.sid.h5", "-q", "--stress", "--no-sid-fem",
                          "--no-obj"], cwd=folder, env=env, check=True, capture_output=True)
    subprocess.run(run + ["simulate", "scene.toml", "-q", "-o", "scene.results.h5"], cwd=folder, env=env,
                   check=True, capture_output=True)
    return folder / "scene.results.h5"


def recovery_cost(repeat: int) -> dict:
    import sidprep

    with tempfile.TemporaryDirectory() as tmp:
        results = engine_results(Path(tmp))
        rec = sidprep.recover_stress(results)
        runs = [timed(lambda: sidprep.recover_stress(results)) for _ in range(repeat)]
    return {"samples": len(rec.time), "nodes": len(rec.node_ids), "wall": statistics.median(w for w, _ in runs),
            "cpu": statistics.median(c for _, c in runs)}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--repeat", type=int, default=5)
    args = p.parse_args()
    r = reduce_cost(args.repeat)
    (w0, c0), (w1, c1) = r["without"], r["with"]
    print(f"load average {os.getloadavg()[0]:.1f}")
    print("| piston rod reduce | wall s | CPU s |\n|---|---|---|")
    print(f"| without --stress | {w0:.2f} | {c0:.2f} |\n| with --stress | {w1:.2f} | {c1:.2f} |")
    print(f"| ratio | {w1 / w0:.3f} | {c1 / c0:.3f} |")
    ph = r["phases"]
    print(f"phases (median s): stress {ph['stress']:.3f}, checks {ph['checks without']:.3f} -> {ph['checks with']:.3f}")
    s = recovery_cost(args.repeat)
    print(f"load average {os.getloadavg()[0]:.1f}")
    print(f"recover_stress, engine 1 s: {s['samples']} samples x {s['nodes']} surface nodes: "
          f"wall {s['wall']:.3f} s, CPU {s['cpu']:.3f} s (median of {args.repeat})")


if __name__ == "__main__":
    main()
