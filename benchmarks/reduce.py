"""Speed and memory of ``sidprep reduce`` and of its Craig-Bampton step (run on demand).

    python benchmarks/reduce.py [--repeat 3] [--big-size 0.01] [--cb-size 0.0088] [--skip-scipy]

1. ``sidprep reduce data/meshes/piston_rod.msh`` end to end (a fresh process: imports, mesh, assembly,
   reduction, checks, three files), median of --repeat runs, phases from the JSON summary.
2. The same on a generated >= 100k-DOF bar (1.0 x 0.05 x 0.08 m, tet10, element size --big-size).
3. Craig-Bampton alone at ~150k DOF (--cb-size): sidprep.reduction.craig_bampton.craig_bampton (CHOLMOD, K_ii
   factorised once and reused for the constraint modes and the shift-invert Lanczos) vs plain scipy
   (one SuperLU factorisation of K_ii reused the same way, ``eigsh``), same mesh, same 20 modes.

Targets: piston rod end to end <= 1 s (not met, docs/performance.md); CB >= 5x faster than plain scipy at 150k DOF.
The machine is shared: the load average is printed with every row.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
BAR_GEO = """SetFactory("OpenCASCADE");
Box(1) = {{0, 0, 0, 1.0, 0.05, 0.08}};
Mesh.MeshSizeMin = {h};
Mesh.MeshSizeMax = {h};
Physical Volume("bar") = {{1}};
Physical Surface("fixed_end") = {{1}};
Physical Surface("free_end") = {{2}};
"""
CB_MODES = 20


def load() -> str:
    return "%.1f" % os.getloadavg()[0]


def children_cpu_s() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run_reduce(mesh: Path, repeat: int, extra=()) -> dict:
    """Median wall and CPU time of ``sidprep reduce MESH`` in a fresh process, plus the last summary."""
    walls, cpus, summary = [], [], None
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(repeat):
            t0, c0 = time.perf_counter(), children_cpu_s()
            out = subprocess.run([sys.executable, "-m", "sidprep.cli.main", "reduce", str(mesh), "-q", "--json", *extra],
                                 cwd=tmp, env={**os.environ, "PYTHONPATH": str(ROOT)},
                                 capture_output=True, text=True, check=True)
            walls.append(time.perf_counter() - t0)
            cpus.append(children_cpu_s() - c0)
            summary = json.loads(out.stdout)
    return {"wall_s": float(np.median(walls)), "cpu_s": float(np.median(cpus)), "summary": summary, "load": load()}


def bar_mesh(h: float, folder: Path):
    from sidprep.fe.mesh import read_mesh

    geo = folder / f"bar_h{h:g}.geo"
    geo.write_text(BAR_GEO.format(h=h))
    return geo, read_mesh(geo)


def cb_inputs(mesh):
    """Model matrices of the bar with RBE2 masters on both end faces, and the boundary DOFs."""
    from sidprep.fe.assemble import mass_matrix, stiffness_matrix
    from sidprep.reduction.interfaces import interface_model, make_interface
    from sidprep.fe.material import builtin_material

    steel = builtin_material("steel")
    im = interface_model(mesh.n_nodes, [make_interface(mesh, "fixed_end"), make_interface(mesh, "free_end")],
                         mesh.points)
    return im.project(stiffness_matrix(mesh, steel)), im.project(mass_matrix(mesh, steel)), im.master_dofs.ravel()


def plain_scipy_cb(K, M, b, n_modes):
    """Craig-Bampton the textbook way: one SuperLU factorisation of K_ii, eigsh shift-invert at 0."""
    import scipy.sparse.linalg as spla

    from sidprep.reduction.craig_bampton import split_dofs

    b, i = split_dofs(K.shape[0], b)
    K_ii, M_ii = K[i][:, i].tocsc(), M[i][:, i].tocsr()
    lu = spla.splu(K_ii)
    Psi = lu.solve(-K[i][:, b].toarray())
    op = spla.LinearOperator(K_ii.shape, matvec=lu.solve, dtype=float)
    lam, Phi = spla.eigsh(K_ii, k=n_modes, M=M_ii, sigma=0.0, OPinv=op)
    return np.sqrt(np.sort(lam)) / (2 * np.pi), Psi, Phi


def timed(fn, *args, **kw):
    """(result, wall s, CPU s of this process, peak RSS MB)."""
    from sidprep.progress import peak_memory_mb

    t0, c0 = time.perf_counter(), time.process_time()
    out = fn(*args, **kw)
    return out, time.perf_counter() - t0, time.process_time() - c0, peak_memory_mb()


def cb_comparison(h: float, folder: Path, skip_scipy: bool) -> dict:
    """sidprep CB vs plain scipy CB; each in a fresh process so that peak memory is its own."""
    code = f"""
import json, sys
sys.path.insert(0, {str(ROOT)!r}); sys.path.insert(0, {str(ROOT / 'benchmarks')!r})
from pathlib import Path
import reduce as bench
from sidprep.reduction.craig_bampton import craig_bampton
geo, mesh = bench.bar_mesh({h}, Path({str(folder)!r}))
K, M, b = bench.cb_inputs(mesh)
if sys.argv[1] == "sidprep":
    r, t, cpu, mem = bench.timed(craig_bampton, K, M, b, n_modes={CB_MODES})
    f = r.fixed_interface_hz
else:
    (f, _, _), t, cpu, mem = bench.timed(bench.plain_scipy_cb, K, M, b, {CB_MODES})
from sidprep.fe.linalg import fast_blas
print(json.dumps({{"dof": int(K.shape[0]), "time_s": t, "cpu_s": cpu, "peak_mb": mem, "f_hz": [float(x) for x in f],
                  "blas": Path(fast_blas()).name if sys.argv[1] == "sidprep" else "scipy-openblas (SuperLU)"}}))
"""
    out = {}
    for which in ("sidprep",) + (() if skip_scipy else ("scipy",)):
        res = subprocess.run([sys.executable, "-c", code, which], capture_output=True, text=True, check=True,
                             env={**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"})
        out[which] = {**json.loads(res.stdout.strip().splitlines()[-1]), "load": load()}
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--big-size", type=float, default=0.01, help="element size of the >= 100k-DOF bar (m)")
    ap.add_argument("--cb-size", type=float, default=0.0088, help="element size of the ~150k-DOF CB bar (m)")
    ap.add_argument("--skip-scipy", action="store_true", help="skip the (slow, memory-hungry) plain scipy CB")
    args = ap.parse_args()
    rows = []
    rod = run_reduce(ROOT / "data" / "meshes" / "piston_rod.msh", args.repeat)
    rows.append(("piston_rod.msh", rod))
    with tempfile.TemporaryDirectory() as tmp:
        geo, _ = bar_mesh(args.big_size, Path(tmp))
        big = run_reduce(geo, max(1, args.repeat // 2))
        rows.append((f"bar h={args.big_size:g}", big))
        cb = cb_comparison(args.cb_size, Path(tmp), args.skip_scipy)
    phases = list(rod["summary"]["timings_s"])
    print("| model | DOF | wall s (median) | CPU s | " + " | ".join(phases) + " | peak MB | load |")
    print("|---|---|---|---|" + "---|" * len(phases) + "---|---|")
    for name, r in rows:
        s = r["summary"]
        print(f"| {name} | {s['dof']} | {r['wall_s']:.2f} | {r['cpu_s']:.2f} | "
              + " | ".join(f"{s['timings_s'].get(p, 0.0):.2f}" for p in phases)
              + f" | {s['peak_memory_mb']:.0f} | {r['load']} |")
    print()
    print("| Craig-Bampton, 20 modes | DOF | wall s | CPU s | peak MB | f1 Hz | BLAS | load |")
    print("|---|---|---|---|---|---|---|---|")
    for which, r in cb.items():
        print(f"| {which} | {r['dof']} | {r['time_s']:.2f} | {r['cpu_s']:.2f} | {r['peak_mb']:.0f} | "
              f"{r['f_hz'][0]:.3f} | {r['blas']} | {r['load']} |")
    if "scipy" in cb:
        print(f"\nsidprep vs plain scipy: {cb['scipy']['time_s'] / cb['sidprep']['time_s']:.1f}x wall, "
              f"{cb['scipy']['cpu_s'] / cb['sidprep']['cpu_s']:.1f}x CPU, "
              f"memory ratio {cb['scipy']['peak_mb'] / cb['sidprep']['peak_mb']:.1f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
