"""Batch benchmark: 16 reductions (the bar and the piston rod at several mesh sizes).

Measures, side by side and repeated (median): the wall time of ``run_batch`` with one worker (the
jobs one by one) and with 2 workers (target >= 1.85x on 2 cores), and the cache-hit
re-run of the whole batch (target < 1 s).  Each worker runs single-threaded (sidprep.jobs.batch
SINGLE_THREAD_ENV).  On a shared machine the pool can only be as fast as the cores it gets: each
run also prints the cores it obtained (the jobs' CPU seconds over the wall time) and the load
average, so that a low ratio from a loaded machine is told apart from a slow pool.

    PYTHONPATH=. python benchmarks/batch.py [--repeats 2] [--workers 2]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: target element sizes [m]: 8 bars (make_bar.py default 0.04) and 8 piston rods (default 0.012)
BAR_SIZES = (0.06, 0.055, 0.05, 0.045, 0.04, 0.035, 0.03, 0.028)
ROD_SIZES = (0.024, 0.022, 0.02, 0.018, 0.016, 0.015, 0.014, 0.013)


def make_meshes(folder: Path) -> list[Path]:
    out = []
    for script, sizes, stem in (("make_bar.py", BAR_SIZES, "bar"), ("make_piston_rod.py", ROD_SIZES, "rod")):
        for h in sizes:
            path = folder / f"{stem}_{h:g}.msh"
            subprocess.run([sys.executable, str(ROOT / "data" / "meshes" / script), "--size", str(h), "--out",
                            str(path)], check=True, capture_output=True, cwd=ROOT / "data" / "meshes")
            out.append(path)
    return out


def timed_batch(jobs, outdir: Path, workers: int) -> tuple[float, object]:
    from sidprep.jobs.batch import BatchOptions, run_batch

    t0 = time.perf_counter()
    report = run_batch(jobs, BatchOptions(outdir=str(outdir), workers=workers))
    return time.perf_counter() - t0, report


def cores_obtained(report, wall: float) -> float:
    """The jobs' CPU seconds over the batch's wall time: the cores the batch actually got."""
    return sum(r.get("cpu_s") or 0.0 for r in report.records) / wall


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--repeats", type=int, default=2)
    p.add_argument("--workers", type=int, default=2)
    args = p.parse_args(argv)
    from sidprep.jobs.batch import jobs_from_meshes

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        meshes = make_meshes(tmp)
        jobs = jobs_from_meshes(meshes)
        serial, pool, cached, cores = [], [], [], []
        for r in range(args.repeats):                      # alternate: the machine's load hits both alike
            dt, rep1 = timed_batch(jobs, tmp / f"serial{r}", 1)
            serial.append(dt)
            cores.append(f"one by one {cores_obtained(rep1, dt):.2f} (load {os.getloadavg()[0]:.1f})")
            dt, rep2 = timed_batch(jobs, tmp / f"pool{r}", args.workers)
            pool.append(dt)
            cores.append(f"pool {cores_obtained(rep2, dt):.2f} (load {os.getloadavg()[0]:.1f})")
            dt, rep3 = timed_batch(jobs, tmp / f"pool{r}", args.workers)
            cached.append(dt)
            assert rep1.exit_code == rep2.exit_code == 0 and all(x["status"] == "cached" for x in rep3.records)
        dofs = sorted(x["dof"] for x in rep2.records)
        s, q, c = statistics.median(serial), statistics.median(pool), statistics.median(cached)
        print(f"16 reductions, {dofs[0]}-{dofs[-1]} DOF (default options: 8 modes + FRMs, all checks)")
        print("| run | median wall [s] | runs | ratio |")
        print("|---|---|---|---|")
        print(f"| one by one (1 worker) | {s:.1f} | {', '.join(f'{x:.1f}' for x in serial)} | 1.00 |")
        print(f"| pool, {args.workers} workers | {q:.1f} | {', '.join(f'{x:.1f}' for x in pool)} | {s / q:.2f}x |")
        print(f"| cache-hit re-run | {c:.2f} | {', '.join(f'{x:.2f}' for x in cached)} | - |")
        print("cores obtained (job CPU s / wall s) and 1-min load average, run by run: " + "; ".join(cores))
    return 0


if __name__ == "__main__":
    sys.exit(main())
