#!/usr/bin/env python3
"""Import cost: K and M read from CalculiX's files vs sidprep's own assembly of the same mesh.

The tet10 bar of benchmarks/scale.py (1.0 x 0.05 x 0.08 m, h for the DOF target; h = 0.01 m ~ 107k
DOF) is written as a CalculiX deck (sidprep.fe.matrices.calculix.tet_deck) and run once by ``ccx``
with ``*FREQUENCY, SOLVER=MATRIXSTORAGE`` (bar.sti / .mas / .dof).  Then, side by side in this
process, alternating, ``--repeat`` times each:

* assembly: what ``sidprep reduce`` does in its "assemble" phase (block pattern, K, scalar mass Ms,
  M = Ms (x) E3; sidprep.jobs.reduce);
* import: what it does in its "import" phase with ``--matrices bar.sti`` (read the three files,
  map onto the mesh's DOFs, all checks: symmetry, definiteness, mass, isotropy, rigid-body energy;
  sidprep.fe.matrices.onto_model.imported_model);
* with ``--eig``: the same from the binary ``bar_eig.eig`` of a ``*FREQUENCY, STORAGE=YES`` run
  (structure rebuilt from the deck; ccx's eigen solve makes that run slow: ~1 min at 100k DOF).

Both start from the mesh in memory (reading MODEL is the same for both).  Medians and their ratio,
with the 1-minute load average (the machine is shared).  Issue 25's target: import <= 1.2x assembly
at 100k DOF.  The first import warms up (page cache, first calls): not timed.

    python benchmarks/import_matrices.py --dof 100000 --repeat 5
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

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "benchmarks"))

from scale import BAR_GEO, BOX, bar_h, write_msh  # noqa: E402  (the bar of the scaling table)


def assemble(mesh, material):
    from sidprep.fe.assemble import block_pattern, scalar_mass_matrix, stiffness_matrix, vector_mass

    pattern = block_pattern(mesh.cells, mesh.n_nodes)
    K = stiffness_matrix(mesh, material, pattern)
    Ms = scalar_mass_matrix(mesh, material.rho, pattern)
    return K, vector_mass(Ms)


def main() -> None:
    from sidprep.fe.linalg import single_threaded_blas
    from sidprep.fe.material import builtin_material, unit_system
    from sidprep.fe.matrices.calculix import tet_deck
    from sidprep.fe.matrices.onto_model import imported_model
    from sidprep.fe.mesh import read_mesh

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dof", type=int, default=100_000)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--eig", action="store_true", help="also import the binary .eig of a STORAGE=YES run")
    args = ap.parse_args()
    if shutil.which("ccx") is None:
        sys.exit("ccx not found: apt-get install calculix-ccx")
    steel, si = builtin_material("steel"), unit_system("si")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        geo = tmp / "bar.geo"
        a, b, c = BOX
        geo.write_text(BAR_GEO.format(a=a, b=b, c=c, h=bar_h(args.dof, free=True)))
        mesh = read_mesh(write_msh(geo))
        tet_deck(mesh, tmp / "bar.inp", steel)
        env = dict(os.environ, OMP_NUM_THREADS="1", CCX_NPROC_STIFFNESS="1", CCX_NPROC_EQUATION_SOLVER="1")
        t = time.perf_counter()
        subprocess.run(["ccx", "bar"], cwd=tmp, env=env, check=True, capture_output=True)
        ccx_s = time.perf_counter() - t
        sizes = sum((tmp / f"bar{s}").stat().st_size for s in (".sti", ".mas", ".dof")) / 2 ** 20
        sources = {"import": tmp / "bar.sti"}
        if args.eig:
            tet_deck(mesh, tmp / "bar_eig.inp", steel, step="*FREQUENCY, STORAGE=YES\n10")
            subprocess.run(["ccx", "bar_eig"], cwd=tmp, env=env, check=True, capture_output=True)
            sources["import .eig"] = tmp / "bar_eig.eig"
        for source in sources.values():
            imported_model(mesh, source, si)                        # warm-up: page cache, first calls
        times = {"assemble": [], **{k: [] for k in sources}}
        with single_threaded_blas():
            for _ in range(args.repeat):
                t = time.perf_counter()
                K, M = assemble(mesh, steel)
                times["assemble"].append(time.perf_counter() - t)
                del K, M
                for key, source in sources.items():
                    t = time.perf_counter()
                    fe = imported_model(mesh, source, si)
                    times[key].append(time.perf_counter() - t)
                    del fe
    med = {k: statistics.median(v) for k, v in times.items()}
    print("| DOF | source | ASCII files MB | ccx writes s | assemble s | import s | ratio | load (1 min) |")
    print("|---|---|---|---|---|---|---|---|")
    for key, source in sources.items():
        print(f"| {mesh.n_dof} | {source.name} | {sizes:.0f} | {ccx_s:.1f} | {med['assemble']:.2f} | {med[key]:.2f} | "
              f"**{med[key] / med['assemble']:.2f}** | {os.getloadavg()[0]:.1f} |")
    print("all runs:", {k: [round(x, 2) for x in v] for k, v in times.items()})


if __name__ == "__main__":
    main()
