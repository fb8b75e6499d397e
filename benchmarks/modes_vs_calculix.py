#!/usr/bin/env python3
"""``sidprep modes`` vs CalculiX 2.20 (C3D10, SPOOLES + ARPACK) on the same bar meshes.

Both tools run in their own subprocess under GNU ``/usr/bin/time -v`` (wall time and peak RSS of
the whole process, Python start-up and mesh reading included), single-threaded solvers:
CalculiX as in ../shared/validation/run_ccx_case.sh (OMP_NUM_THREADS=1, 2 element threads),
sidprep with OMP_NUM_THREADS = OPENBLAS_NUM_THREADS = 1.  Meshes are generated with the
validation's ``mesh_gen.py`` (gmsh, same sha1 as the validation meshes; %.12e coordinates, since
ccx silently truncates longer fields).  Cases: cantilever (NX0 clamped, 10 modes) and free-free
(20 modes = 6 rigid + 14 elastic; sidprep --count 14).

Prints a table (medians over --repeat runs) and the K-assembly time of sidprep vs plain
scikit-fem (linear_elasticity + asm) on the h = 0.01 (~101k DOF) P2 mesh.

    python benchmarks/modes_vs_calculix.py                      # h = 0.02, 0.01; 3 runs each
    python benchmarks/modes_vs_calculix.py --h 0.007 --repeat 1 # the 262k-DOF level
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
VALIDATION = REPO / ".." / "shared" / "validation"
BOX = ("1.0", "0.05", "0.08")
CASES = {"cantilever": {"ccx_modes": 10, "args": ["--clamp", "NX0", "--count", "10"], "rigid": 0},
         "freefree": {"ccx_modes": 20, "args": ["--count", "14"], "rigid": 6}}
SINGLE_THREAD = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def make_mesh(h: float, workdir: Path) -> Path:
    """The validation bar mesh of size h (CalculiX .inp; node sets NX0, ...), generated once."""
    inp = workdir / "meshes" / f"bar_h{h}_mesh.inp"
    if not inp.exists():
        subprocess.run([sys.executable, str(VALIDATION / "scripts" / "mesh_gen.py"), "--name", f"bar_h{h}",
                        "--box", *BOX, "--h", str(h), "--out", str(workdir / "meshes"), "--no-msh"],
                       check=True, capture_output=True)
    return inp


def gnu_time(cmd: list[str], env: dict, cwd: Path) -> tuple[str, float, float]:
    """Run ``cmd`` under /usr/bin/time -v; returns (stdout, wall s, peak RSS MiB)."""
    log = cwd / "time.log"
    t0 = time.perf_counter()
    proc = subprocess.run(["/usr/bin/time", "-v", "-o", str(log), *cmd], env=env, cwd=cwd,
                          capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"{cmd[0]} failed: {proc.stderr[-2000:]}")
    rss_kb = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", log.read_text()).group(1))
    return proc.stdout, wall, rss_kb / 1024.0


def run_ccx(case: str, mesh: Path, workdir: Path) -> dict:
    deck_dir = workdir / f"ccx_{case}_{mesh.stem}"
    deck_dir.mkdir(parents=True, exist_ok=True)
    deck = deck_dir / "job.inp"
    subprocess.run([sys.executable, str(VALIDATION / "scripts" / "make_deck.py"), case, str(mesh), str(deck)],
                   check=True)
    env = dict(os.environ, OMP_NUM_THREADS="1", CCX_NPROC_EQUATION_SOLVER="1", CCX_NPROC_STIFFNESS="2")
    _, wall, rss = gnu_time(["ccx", "-i", "job"], env, deck_dir)
    text = (deck_dir / "job.dat").read_text()
    table = text.split("E I G E N V A L U E   O U T P U T")[1].split("P A R T I C I P A T I O N")[0]
    freqs = [float(line.split()[3]) for line in table.splitlines()
             if len(line.split()) == 5 and line.split()[0].isdigit()]
    return {"wall_s": wall, "rss_mb": rss, "freqs_hz": freqs}


def run_sidprep(case: str, mesh: Path, workdir: Path) -> dict:
    env = dict(os.environ, **SINGLE_THREAD)
    cmd = [sys.executable, "-m", "sidprep.cli.main", "modes", str(mesh), "--material", "steel", "--json", "-q",
           *CASES[case]["args"]]
    env["PYTHONPATH"] = str(REPO) + os.pathsep + env.get("PYTHONPATH", "")
    out, wall, rss = gnu_time(cmd, env, workdir)
    summary = json.loads(out)
    return {"wall_s": wall, "rss_mb": rss, "freqs_hz": summary["frequencies_hz"], "n_dof": summary["n_dof"],
            "timings_s": summary["timings_s"], "rigid": summary["rigid_modes"]}


def median_run(fn, repeat: int) -> dict:
    runs = [fn() for _ in range(repeat)]
    best = dict(runs[0])
    best["wall_s"] = statistics.median(r["wall_s"] for r in runs)
    best["rss_mb"] = statistics.median(r["rss_mb"] for r in runs)
    best["walls"] = [round(r["wall_s"], 2) for r in runs]
    if "timings_s" in runs[0]:
        best["timings_s"] = {k: round(statistics.median(r["timings_s"][k] for r in runs), 2) for k in runs[0]["timings_s"]}
    return best


def assembly_comparison(mesh_inp: Path, repeat: int) -> dict:
    """Median wall time of K for the P2 mesh: sidprep.fe.assemble vs scikit-fem linear_elasticity + asm."""
    from skfem import Basis, ElementTetP2, ElementVector, MeshTet, asm
    from skfem.models.elasticity import lame_parameters, linear_elasticity

    from sidprep.fe.assemble import stiffness_matrix
    from sidprep.fe.material import builtin_material
    from sidprep.fe.mesh import read_mesh

    mesh = read_mesh(mesh_inp)
    steel = builtin_material("steel")

    def timed(fn):
        t0 = time.perf_counter()
        fn()
        return time.perf_counter() - t0

    ours = statistics.median(timed(lambda: stiffness_matrix(mesh, steel)) for _ in range(repeat))
    corners = np.unique(mesh.cells[:, :4])
    index = np.full(mesh.n_nodes, -1)
    index[corners] = np.arange(len(corners))
    skmesh = MeshTet(mesh.points[corners].T.copy(), index[mesh.cells[:, :4]].T.copy())
    form = linear_elasticity(*lame_parameters(steel.E, steel.nu))
    plain = statistics.median(timed(lambda: asm(form, Basis(skmesh, ElementVector(ElementTetP2()))))
                              for _ in range(repeat))
    return {"n_dof": mesh.n_dof, "sidprep_s": ours, "skfem_s": plain}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--h", type=float, nargs="+", default=[0.02, 0.01], help="mesh sizes (0.02, 0.01, 0.007)")
    ap.add_argument("--case", nargs="+", default=list(CASES), choices=list(CASES))
    ap.add_argument("--repeat", type=int, default=3, help="runs per tool and level (median reported)")
    ap.add_argument("--workdir", type=Path, default=Path(tempfile.gettempdir()) / "sidprep_bench_modes")
    ap.add_argument("--no-assembly", action="store_true", help="skip the K assembly vs scikit-fem timing")
    ap.add_argument("--json", type=Path, help="also write all results to this JSON file")
    a = ap.parse_args()
    a.workdir.mkdir(parents=True, exist_ok=True)
    have_ccx = shutil.which("ccx") is not None
    if not have_ccx:
        print("note: ccx not found (apt-get install calculix-ccx); CalculiX columns are empty", file=sys.stderr)
    if not Path("/usr/bin/time").exists():
        print("error: GNU time (/usr/bin/time, Debian package 'time') is needed for peak memory", file=sys.stderr)
        return 2
    rows = []
    for h in a.h:
        mesh = make_mesh(h, a.workdir)
        for case in a.case:
            print(f"h = {h}, {case} ...", file=sys.stderr, flush=True)
            ours = median_run(lambda: run_sidprep(case, mesh, a.workdir), a.repeat)
            ccx = median_run(lambda: run_ccx(case, mesh, a.workdir), a.repeat) if have_ccx else None
            row = {"h": h, "case": case, "n_dof": ours["n_dof"], "sidprep": ours, "ccx": ccx}
            if ccx:
                f_ccx = np.array(ccx["freqs_hz"][CASES[case]["rigid"]:])
                row["max_rel_diff"] = float(np.max(np.abs(np.array(ours["freqs_hz"]) / f_ccx - 1)))
            rows.append(row)
    print(f"\n{'case':<11}{'DOF':>8}{'ccx s':>9}{'sidprep s':>11}{'time ratio':>11}{'ccx MB':>9}"
          f"{'sidprep MB':>12}{'mem ratio':>10}{'max rel df':>12}  sidprep phases (s)")
    for r in rows:
        s, c = r["sidprep"], r["ccx"]
        phases = " ".join(f"{k} {v:.2f}" for k, v in s["timings_s"].items())
        if c:
            print(f"{r['case']:<11}{r['n_dof']:>8}{c['wall_s']:>9.2f}{s['wall_s']:>11.2f}{s['wall_s'] / c['wall_s']:>11.2f}"
                  f"{c['rss_mb']:>9.0f}{s['rss_mb']:>12.0f}{s['rss_mb'] / c['rss_mb']:>10.2f}{r['max_rel_diff']:>12.1e}  {phases}")
        else:
            print(f"{r['case']:<11}{r['n_dof']:>8}{'-':>9}{s['wall_s']:>11.2f}{'-':>11}{'-':>9}{s['rss_mb']:>12.0f}"
                  f"{'-':>10}{'-':>12}  {phases}")
    result = {"rows": rows, "repeat": a.repeat}
    if not a.no_assembly:
        h_asm = 0.01
        asm_row = assembly_comparison(make_mesh(h_asm, a.workdir), a.repeat)
        result["assembly"] = asm_row
        print(f"\nK assembly, P2, {asm_row['n_dof']} DOF (median of {a.repeat}): sidprep {asm_row['sidprep_s']:.2f} s, "
              f"scikit-fem linear_elasticity+asm {asm_row['skfem_s']:.2f} s "
              f"(ratio {asm_row['skfem_s'] / asm_row['sidprep_s']:.1f}x)")
    if a.json:
        a.json.write_text(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
