#!/usr/bin/env python3
"""Scaling table: ``sidprep modes`` and ``sidprep reduce`` on gmsh-generated tet10 bars of growing
size, with the memory estimate (sidprep.fe.linalg.estimate_peak_memory) beside the measured peak,
the backend the automatic choice took, and CalculiX 2.20 (``ccx``, if installed) on the same mesh.

Each run is its own process under GNU ``/usr/bin/time -v`` (wall, peak RSS of the whole process),
single-threaded BLAS.  Bar 1.0 x 0.05 x 0.08 m (as benchmarks/modes_vs_calculix.py), mesh size h
chosen for the DOF target (h = 0.01 m ~ 107k DOF).  ``modes``: clamped at x = 0, 10 modes.
``reduce``: Craig-Bampton with RBE2 masters on both end faces, 30 modes plus FRMs, all checks.
The machine is shared: quote the ratios measured side by side, not the absolute times.

    python benchmarks/scale.py --dof 100000 250000            # the table rows
    python benchmarks/scale.py --dof 100000 --ccx             # with CalculiX beside it
    python benchmarks/scale.py --dof --piston-rod 7           # the piston rod's whole process, medians of 7
    python benchmarks/scale.py --dof --piston-rod 7 --before /work/main   # and another checkout alternately
    python benchmarks/scale.py --dof 1000000 --no-modes --mesh-first   # the 1M-DOF reduction alone

``--mesh-first`` writes the tet10 mesh to a binary .msh (gmsh, in this process) before the runs, so
that the runs measure the model, not the meshing; ``--dof`` then targets the reduction's DOF (free).

``--piston-rod N``: ``sidprep reduce data/meshes/piston_rod.msh`` (16k DOF, the defaults) as a user
runs it, N fresh processes: wall and CPU s (user + system) of the whole process, the sum of its
phases (the ``--json`` summary's timings) and the rest of the wall time (Python's start-up, the
imports, the work between the phases, the exit); ``--before PATH`` runs another checkout's command
alternately, so that both share the machine's load.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "benchmarks"))
BOX = (1.0, 0.05, 0.08)
#: DOF of the bar at h = 0.01 m (measured: 107 622 free DOF clamped)
DOF_AT_H001 = 107_622
BAR_GEO = """SetFactory("OpenCASCADE");
Box(1) = {{0, 0, 0, {a}, {b}, {c}}};
Mesh.MeshSizeMin = {h};
Mesh.MeshSizeMax = {h};
Physical Volume("bar") = {{1}};
Physical Surface("fixed_end") = {{1}};
Physical Surface("free_end") = {{2}};
"""
SINGLE_THREAD = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


#: free DOF of the bar meshed to .msh at h = 0.007551 m (measured: 210 600)
FREE_DOF_AT_H0007551 = (0.007551, 210_600)


def bar_h(dof: int, free: bool = False) -> float:
    """Mesh size for about ``dof`` DOF (DOF ~ h^-3): clamped DOF of the .geo, or with ``free`` all DOF."""
    h0, n0 = FREE_DOF_AT_H0007551 if free else (0.01, DOF_AT_H001)
    return h0 * (n0 / dof) ** (1.0 / 3.0)


def write_msh(geo: Path) -> Path:
    """Mesh the .geo to a binary tet10 .msh beside it (one gmsh session in this process)."""
    import gmsh

    out = geo.with_suffix(".msh")
    gmsh.initialize(readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.open(str(geo))
        gmsh.model.mesh.generate(3)
        gmsh.model.mesh.setOrder(2)
        gmsh.option.setNumber("Mesh.Binary", 1)
        gmsh.write(str(out))
    finally:
        gmsh.finalize()
    return out


def timed(cmd: list[str], cwd: Path) -> tuple[str, str, float, float]:
    """(stdout, stderr, wall s, peak RSS MiB) of ``cmd`` under /usr/bin/time -v."""
    from modes_vs_calculix import gnu_time

    env = dict(os.environ, **SINGLE_THREAD, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    log = cwd / "stderr.log"
    out, wall, rss = gnu_time(["bash", "-c", " ".join(cmd) + f" 2> {log}"], env, cwd)
    return out, log.read_text(), wall, rss


def estimate_mb(mesh_path: Path, n_modes: int, clamp: bool) -> tuple[int, float]:
    import numpy as np

    from sidprep.fe.linalg import estimate_peak_memory
    from sidprep.fe.mesh import read_mesh

    mesh = read_mesh(mesh_path)
    n = mesh.n_dof - (3 * int((mesh.points[:, 0] < 1e-9).sum()) if clamp else 0)
    est = estimate_peak_memory(n, extent=np.ptp(mesh.points, axis=0), n_modes=n_modes)
    return n, est.direct_peak_bytes / 2 ** 20


def reduce_estimate_mb(mesh_path: Path) -> float:
    """The reduction's own estimate of its peak (sidprep.reduction.craig_bampton.reduction_peak_bytes), MiB."""
    import numpy as np

    from sidprep.reduction.craig_bampton import reduction_peak_bytes
    from sidprep.fe.mesh import read_mesh

    mesh = read_mesh(mesh_path)
    return reduction_peak_bytes(mesh.n_dof, extent=np.ptp(mesh.points, axis=0)) / 2 ** 20


def run_modes(mesh: Path, work: Path) -> dict:
    cmd = [sys.executable, "-m", "sidprep.cli.main", "modes", str(mesh), "--clamp", "fixed_end", "--count", "10"]
    _, err, wall, rss = timed(cmd, work)
    note = next((line.strip() for line in err.splitlines() if "memory estimate" in line), "")
    return {"wall_s": wall, "rss_mb": rss, "choice": note.rpartition("backend ")[2] or "?"}


def run_reduce(mesh: Path, work: Path) -> dict:
    cmd = [sys.executable, "-m", "sidprep.cli.main", "reduce", str(mesh), "--interface", "fixed_end", "--interface",
           "free_end", "--modes", "30", "-q", "--json", "-o", str(work / "out.h5")]
    out, _, wall, rss = timed(cmd, work)
    summary = json.loads(out)
    return {"wall_s": wall, "rss_mb": rss, "passed": summary["checks"]["passed"], "dof": summary["dof"]}


def run_calculix(h: float, work: Path) -> dict | None:
    if shutil.which("ccx") is None:
        return None
    import modes_vs_calculix as mvc

    if not mvc.VALIDATION.exists():
        mvc.VALIDATION = Path("/work/shared/validation")
    return mvc.run_ccx("cantilever", mvc.make_mesh(round(h, 5), work), work)


def piston_rod_run(root: Path, output: Path) -> dict:
    """One ``sidprep reduce`` process of the piston rod, the command of the checkout ``root``: wall,
    CPU (user + system), the sum of its phases and the rest (start-up, imports, between the phases, exit), s."""
    c0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    out = subprocess.run([sys.executable, "-m", "sidprep.cli.main", "reduce", str(root / "data/meshes/piston_rod.msh"),
                          "-q", "--json", "-o", str(output)], check=True, cwd=root, capture_output=True, text=True,
                         env=dict(os.environ, PYTHONPATH=str(root))).stdout
    wall = time.perf_counter() - t0
    c1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    phases = sum(json.loads(out)["timings_s"].values())
    return {"wall": wall, "cpu": (c1.ru_utime - c0.ru_utime) + (c1.ru_stime - c0.ru_stime), "phases": phases,
            "rest": wall - phases}


def piston_rod(repeat: int, before: Path | None = None) -> tuple[dict, list[float]]:
    """{checkout: median of each piston_rod_run figure}, this checkout and ``before`` alternately; the
    load averages seen."""
    roots = {"this": REPO} | ({"before": before.resolve()} if before else {})
    rows: dict[str, list[dict]] = {name: [] for name in roots}
    loads = [os.getloadavg()[0]]
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(repeat):
            for name, root in roots.items():
                rows[name].append(piston_rod_run(root, Path(tmp) / "piston_rod.sid.h5"))
            loads.append(os.getloadavg()[0])
    return {name: {key: statistics.median(r[key] for r in runs) for key in runs[0]} for name, runs in rows.items()}, loads


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--dof", type=int, nargs="*", default=[100_000, 250_000], help="DOF targets")
    ap.add_argument("--ccx", action="store_true", help="CalculiX beside sidprep modes (same mesh)")
    ap.add_argument("--no-reduce", action="store_true", help="modes only")
    ap.add_argument("--no-modes", action="store_true", help="reduce only")
    ap.add_argument("--mesh-first", action="store_true", help="mesh to .msh before the runs (module docstring)")
    ap.add_argument("--piston-rod", type=int, default=0, metavar="N", help="the piston rod's whole process, N runs")
    ap.add_argument("--before", type=Path, metavar="PATH", help="with --piston-rod: another checkout alternately")
    args = ap.parse_args(argv)
    print(f"load {os.getloadavg()[0]:.1f}")
    print("| DOF | command | wall s | peak MB | estimate MB | est/peak | backend | ccx wall s | ccx MB | time ratio | memory ratio |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        for dof in args.dof:
            h = bar_h(dof, free=args.mesh_first)
            geo = work / f"bar_{dof}.geo"
            geo.write_text(BAR_GEO.format(a=BOX[0], b=BOX[1], c=BOX[2], h=h))
            mesh = write_msh(geo) if args.mesh_first else geo
            if not args.no_modes:
                n, est = estimate_mb(mesh, 10, clamp=True)
                m = run_modes(mesh, work)
                ccx = run_calculix(h, work) if args.ccx else None
                cc = (f"{ccx['wall_s']:.1f} | {ccx['rss_mb']:.0f} | {m['wall_s'] / ccx['wall_s']:.2f} | "
                      f"{m['rss_mb'] / ccx['rss_mb']:.2f}") if ccx else "- | - | - | -"
                print(f"| {n} | modes | {m['wall_s']:.1f} | {m['rss_mb']:.0f} | {est:.0f} | {est / m['rss_mb']:.2f} | "
                      f"{m['choice']} | {cc} |", flush=True)
            if not args.no_reduce:
                est = reduce_estimate_mb(mesh)
                r = run_reduce(mesh, work)
                print(f"| {r['dof']} | reduce (CB, 2 RBE2, 30 modes + FRMs, checks {'passed' if r['passed'] else 'FAILED'}) | "
                      f"{r['wall_s']:.1f} | {r['rss_mb']:.0f} | {est:.0f} | {est / r['rss_mb']:.2f} | cholmod | - | - | - | - |",
                      flush=True)
    if args.piston_rod:
        medians, loads = piston_rod(args.piston_rod, args.before)
        print(f"\npiston rod `sidprep reduce`, whole process, medians of {args.piston_rod}, "
              f"load {min(loads):.1f}-{max(loads):.1f}")
        print("| checkout | wall s | CPU s | phases s | rest: start-up, imports, between the phases, exit s |")
        print("|---|---|---|---|---|")
        for name, m in medians.items():
            print(f"| {name} | {m['wall']:.2f} | {m['cpu']:.2f} | {m['phases']:.2f} | {m['rest']:.2f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
