#!/usr/bin/env python3
"""Parse speed of the number scanner (sidprep.fe.matrices.numbers.table_blocks) in MB/s, on CalculiX's
own ASCII matrix files, optionally against another checkout.

The tet10 bar of benchmarks/scale.py (1.0 x 0.05 x 0.08 m, h for the DOF target) is written as a
CalculiX deck and run once by ``ccx`` with ``*FREQUENCY, SOLVER=MATRIXSTORAGE``: bar.sti and bar.mas,
one ``row column value`` per line.  Each timed run is a fresh process that scans both files once to
warm up (the page cache) and then once timed: bytes per
second of wall time and of the process's CPU time (the steadier figure on a shared machine).  With
``--before CHECKOUT`` that checkout's scanner runs too, the children alternating so that they share
the machine's load; medians and the 1-minute load average at each run (/proc/loadavg).

    python benchmarks/parse_speed.py --dof 30000 --repeat 7 --before /work/main
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

BENCHMARKS = Path(__file__).resolve().parent
ROOT = BENCHMARKS.parent
sys.path.insert(0, str(BENCHMARKS))

from scale import BAR_GEO, BOX, bar_h, write_msh  # noqa: E402  (the bar of the scaling table)

#: one timed scan of the files given, in a checkout given first; prints MB per wall and per CPU second
CHILD = r"""
import sys, time
sys.path.insert(0, sys.argv[1])
from sidprep.fe.matrices.numbers import table_blocks
paths = sys.argv[2:]
def scan():
    return sum(len(ints) for p in paths for ints, _ in table_blocks(p, "iir"))
scan()
t, c = time.perf_counter(), time.process_time()
scan()
wall, cpu = time.perf_counter() - t, time.process_time() - c
mb = sum(__import__("os").path.getsize(p) for p in paths) / 1e6
print(mb / wall, mb / cpu)
"""


def matrix_files(tmp: Path, dof: int) -> list[Path]:
    """bar.sti and bar.mas of ccx's MATRIXSTORAGE run on the scale bar at ``dof``."""
    from sidprep.fe.material import builtin_material
    from sidprep.fe.matrices.calculix import tet_deck
    from sidprep.fe.mesh import read_mesh

    geo = tmp / "bar.geo"
    a, b, c = BOX
    geo.write_text(BAR_GEO.format(a=a, b=b, c=c, h=bar_h(dof, free=True)))
    mesh = read_mesh(write_msh(geo))
    tet_deck(mesh, tmp / "bar.inp", builtin_material("steel"))
    env = dict(os.environ, OMP_NUM_THREADS="1", CCX_NPROC_STIFFNESS="1", CCX_NPROC_EQUATION_SOLVER="1")
    subprocess.run(["ccx", "bar"], cwd=tmp, env=env, check=True, capture_output=True)
    print(f"bar: {mesh.n_dof} DOF", flush=True)
    return [tmp / "bar.sti", tmp / "bar.mas"]


def load() -> float:
    return float(Path("/proc/loadavg").read_text().split()[0])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dof", type=int, default=30_000)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--before", type=Path, help="another checkout (its scanner built) to compare")
    args = ap.parse_args()
    if shutil.which("ccx") is None:
        sys.exit("ccx not found: apt-get install calculix-ccx")
    checkouts = {"this checkout": ROOT, **({f"before ({args.before})": args.before} if args.before else {})}
    with tempfile.TemporaryDirectory() as tmp:
        files = matrix_files(Path(tmp), args.dof)
        mb = sum(f.stat().st_size for f in files) / 1e6
        speeds = {k: [] for k in checkouts}
        loads = []
        for _ in range(args.repeat):
            for name, checkout in checkouts.items():
                out = subprocess.run([sys.executable, "-c", CHILD, str(checkout), *map(str, files)], check=True,
                                     capture_output=True, text=True, env=dict(os.environ, PYTHONPATH=str(checkout)))
                speeds[name].append([float(x) for x in out.stdout.split()[-2:]])
                loads.append(load())
    print(f"| scanner | files MB | MB/s wall | MB/s CPU (median of {args.repeat}) | CPU runs | load (1 min) |")
    print("|---|---|---|---|---|---|")
    for name, runs in speeds.items():
        wall, cpu = zip(*runs)
        print(f"| {name} | {mb:.0f} | {statistics.median(wall):.0f} | **{statistics.median(cpu):.0f}** | "
              f"{', '.join(f'{x:.0f}' for x in cpu)} | {min(loads):.1f}-{max(loads):.1f} |")


if __name__ == "__main__":
    main()
