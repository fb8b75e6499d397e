#!/usr/bin/env python3
"""A model reduced in parts against the monolithic reduction of the same mesh.

The tet10 bar of benchmarks/scale.py (1.0 x 0.05 x 0.08 m, RBE2 masters on both end faces, 30
modes + FRMs, all checks), meshed once to a binary .msh for the DOF target; then, alternating,
``sidprep reduce MESH`` and ``sidprep reduce MESH --parts P --workers W``, each in a fresh process
with one BLAS thread.  Columns: wall time (median), the driver's peak RSS (the JSON summary's
peak_memory_mb), the largest worker peak (the parts note: at the end of a part's reduction; and the
largest worker RSS sampled every second over the whole run, the parts the workers hold included),
the largest relative difference of the eigen-mode frequencies to the monolithic run, and whether
the checks passed; then each variant's
wall time per phase (the last run).  The machine is
shared: quote the ratios measured side by side.

    python benchmarks/parts.py --dof 200000 --parts 8 --workers 2
    python benchmarks/parts.py --dof 1000000 --parts 16 --workers 2 --no-monolithic   # the issue's 1M row

``--no-monolithic`` skips the monolithic run (at 1M DOF it needs ~16 GB; docs/performance.md has its
row): the frequency column is then empty.  ``--dask-memory GB`` runs the parts on a Dask LocalCluster
of ``--workers`` worker processes (one thread each) limited to GB each, through ``--scheduler`` (the
stand-in for a cluster of machines), and prints every worker's sampled peak:

    python benchmarks/parts.py --dof 1120000 --parts 16 --workers 2 --no-monolithic --dask-memory 12
"""

from __future__ import annotations

import argparse
import contextlib
import json
import re
import statistics
import sys
import tempfile
import threading
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "benchmarks"))


#: seconds between samples of the workers' RSS
SAMPLE_S = 1.0


class WorkerPeaks:
    """The largest RSS (MiB) of every pool or Dask worker (a spawned child) of this process tree,
    sampled every SAMPLE_S while the ``with`` block runs (``peaks`` by pid; ``peak`` the largest): the
    workers' peaks over the whole run, held parts included."""

    def __enter__(self):
        self.peaks, self.stop = {}, threading.Event()
        self.thread = threading.Thread(target=self.sample, daemon=True)
        self.thread.start()
        return self

    def sample(self) -> None:
        import psutil

        while not self.stop.wait(SAMPLE_S):
            for child in psutil.Process().children(recursive=True):
                try:
                    if "spawn_main" in " ".join(child.cmdline()):
                        rss = child.memory_info().rss / 2.0**20
                        self.peaks[child.pid] = max(self.peaks.get(child.pid, 0.0), rss)
                except psutil.Error:
                    pass

    def __exit__(self, *exc):
        self.stop.set()
        self.thread.join()

    @property
    def peak(self) -> float:
        return max(self.peaks.values(), default=0.0)


def run(mesh: Path, work: Path, parts: int | None, workers: int, scheduler: str | None = None) -> dict:
    from scale import timed

    cmd = [sys.executable, "-m", "sidprep.cli.main", "reduce", str(mesh), "--interface", "fixed_end", "--interface",
           "free_end", "--modes", "30", "-q", "--json", "-o", str(work / "out.sid.h5"), "--no-obj", "--no-sid-fem"]
    if parts:
        cmd += ["--parts", str(parts)] + (["--scheduler", scheduler] if scheduler else ["--workers", str(workers)])
    with WorkerPeaks() as sampled:
        out, err, wall, rss = timed(cmd, work)
    summary = json.loads(out)
    note = next((n for n in summary["notes"] if "parts" in n), "")
    worker = re.search(r"worker peak (\d+) MiB", note)
    eigen = [f for f, k in zip(read_frequencies(work / "out.sid.h5"), summary["kinds"]) if k == "eigen"]
    return {"wall_s": wall, "driver_mb": summary["peak_memory_mb"], "tree_mb": rss,
            "worker_mb": float(worker.group(1)) if worker else None, "worker_sampled_mb": sampled.peak,
            "worker_peaks_mb": sorted(sampled.peaks.values(), reverse=True), "passed": summary["checks"]["passed"],
            "dof": summary["dof"], "eigen_hz": eigen, "note": note, "phases": summary["timings_s"]}


def read_frequencies(path: Path) -> list[float]:
    from sidprep.sid.io.sid_hdf5 import read_sid_hdf5

    return [float(f) for f in read_sid_hdf5(path).frequencies_hz]


def main(argv=None) -> int:
    from scale import BAR_GEO, BOX, bar_h, write_msh

    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--dof", type=int, default=200_000)
    p.add_argument("--parts", type=int, nargs="+", default=[8])
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--repeat", type=int, default=1)
    p.add_argument("--no-monolithic", action="store_true", help="only the runs in parts")
    p.add_argument("--mesh", type=Path, default=None, help="a tet10 .msh of the bar (its fixed_end and free_end "
                   "surfaces) instead of meshing one for --dof")
    p.add_argument("--dask-memory", type=float, default=None, metavar="GB",
                   help="the parts on a Dask LocalCluster of --workers processes limited to GB each")
    args = p.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp, contextlib.ExitStack() as stack:
        scheduler = None
        if args.dask_memory:
            from distributed import LocalCluster

            cluster = stack.enter_context(LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True,
                                                       memory_limit=f"{args.dask_memory}GB", dashboard_address=None))
            scheduler = cluster.scheduler_address
        tmp = Path(tmp)
        mesh = args.mesh
        if mesh is None:
            geo = tmp / "bar.geo"
            geo.write_text(BAR_GEO.format(a=BOX[0], b=BOX[1], c=BOX[2], h=bar_h(args.dof, free=True)))
            mesh = write_msh(geo)
        rows: dict = {}
        for _ in range(args.repeat):                        # alternate: the load hits every variant alike
            for parts in ([] if args.no_monolithic else [None]) + args.parts:
                rows.setdefault(parts, []).append(run(mesh, tmp, parts, args.workers, scheduler if parts else None))
    mono = rows[None][0]["eigen_hz"] if None in rows else None
    kind = "Dask workers" if args.dask_memory else "workers"
    print("| DOF | run | wall s (median) | driver peak MiB | worker peak MiB (note / sampled) | max rel. eigen freq. diff "
          "| checks |")
    print("|---|---|---|---|---|---|---|")
    for parts, rs in rows.items():
        diff = max(abs(a / b - 1) for r in rs for a, b in zip(r["eigen_hz"], mono)) if mono else float("nan")
        worker = max((r["worker_mb"] or 0) for r in rs)
        sampled = max(r["worker_sampled_mb"] for r in rs)
        print(f"| {rs[0]['dof']} | {'monolithic' if parts is None else f'{parts} parts, {args.workers} {kind}'} "
              f"| {statistics.median(r['wall_s'] for r in rs):.1f} | {max(r['driver_mb'] for r in rs):.0f} "
              f"| {worker:.0f} / {sampled:.0f} | {diff:.1e} | {'passed' if all(r['passed'] for r in rs) else 'FAILED'} |")
    for parts, rs in rows.items():
        phases = ", ".join(f"{k} {v:.1f}" for k, v in rs[-1]["phases"].items())
        print(f"{'monolithic' if parts is None else f'parts {parts}'}: wall s per phase: {phases}")
        if parts:
            print(f"parts {parts}: {rs[-1]['note']}")
            print(f"parts {parts}: every worker's sampled peak MiB: "
                  f"{', '.join(f'{m:.0f}' for m in rs[-1]['worker_peaks_mb'])}"
                  f"{f' (Dask LocalCluster, {args.dask_memory:g} GB per worker)' if args.dask_memory else ''}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
