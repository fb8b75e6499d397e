#!/usr/bin/env python3
"""The flexible pendulum as a user runs it once: a fresh process per solver, sidprep vs Exudyn 1.13.6
(the benchmark row "vs Exudyn, fresh process, h = 1e-3"), CPU seconds of the whole process.

The body and the scene are ``simulate.py``'s: the bundled bar (tet10) clamped at its hinge face and
reduced to ``--modes`` clamped eigenmodes by sidprep's FE side once, in this process; the child
processes get it from files (sidprep a ``.sid.h5``, Exudyn the node positions, M, K, modes and
eigenvalues as ``.npz``), build the pendulum (revolute about y, gravity, from rest) and integrate
1 s with generalised-alpha (rho_inf 0.9) at ``--h``.  A child's cost is its whole life, from the
interpreter's start to its exit: imports (sidprep's compiled core, Exudyn's C++ library), set-up, integration and, for sidprep, the post-processing of ``simulate``; measured as
the CPU time (user + system, every thread) the parent collects from the child.  sidprep runs twice:
as a script of its Python API ("sidprep API", the same calls as ``simulate.py``, doing first what
``sidprep simulate`` does to its process: sidprep/cli/options.py ``process_setup``) and as its command
on a scene file of the same pendulum ("sidprep simulate": parsing, the results file, the command's
exit); the Exudyn child is a plain user script.  With ``--before`` another checkout's sidprep runs too,
the children alternating so that they share the machine's load.  With ``--installed PYTHON``
that interpreter's installed sidprep runs too (no checkout on its path: the extension modules the
install built are what is measured).

    python benchmarks/fresh_process.py --exudyn-python /tmp/venv-exu/bin/python
    python benchmarks/fresh_process.py --exudyn-python /tmp/venv-exu/bin/python --installed /tmp/venv/bin/python
    python benchmarks/fresh_process.py --exudyn-python /tmp/venv-exu/bin/python --before /work/main --repeat 7

(``python -m venv --system-site-packages /tmp/venv-exu && /tmp/venv-exu/bin/pip install
exudyn==1.13.6``: Exudyn in a throw-away environment beside the project's packages.)  One warm-up
child per solver first brings the files into the page cache (not counted); the load average is printed.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import scipy.sparse

BENCHMARKS = Path(__file__).resolve().parent
ROOT = BENCHMARKS.parent
sys.path.insert(0, str(BENCHMARKS))

from simulate import Body, reduced_bar, sidprep_sid  # noqa: E402

#: the children: one run each, printing (angle at t_end, integration CPU s) as JSON
SIDPREP_CHILD = r"""
import json, sys
try:  # what `sidprep simulate` does to its process (absent in older checkouts)
    from sidprep.cli.options import process_setup
    process_setup()
except ImportError:
    pass
sys.path.insert(0, sys.argv[1])
from simulate import run_sidprep
from sidprep.sid.io import read_sid
angle, tip, cpu = run_sidprep(read_sid(sys.argv[2]), float(sys.argv[3]))
print(json.dumps([float(angle[-1]), cpu]))
"""
EXUDYN_CHILD = r"""
import json, sys
import numpy as np
import scipy.sparse
sys.path.insert(0, sys.argv[1])
from simulate import Body, run_exudyn
data = np.load(sys.argv[2])
body = Body(data["points"], None, scipy.sparse.load_npz(sys.argv[2] + ".M.npz"),
            scipy.sparse.load_npz(sys.argv[2] + ".K.npz"), data["Phi"], data["omega2"], int(data["tip"]),
            data["hinge_nodes"])
angle, tip, cpu = run_exudyn(body, float(sys.argv[3]))
print(json.dumps([float(angle[-1]), cpu]))
"""


#: the pendulum of ``simulate.run_sidprep`` as a scene file (the SID's node 1 is the hinge, 2 the tip)
SCENE = """
[scene]
gravity = [0.0, 0.0, -9.81]
[solver]
t_end = 1.0
step = {h!r}
rho_inf = 0.9
[output]
rate = 25
[bodies.bar]
type = "flexible"
sid = "bar.sid.h5"
[markers.pivot]
body = "ground"
z_axis = [0.0, 1.0, 0.0]
[markers.hinge]
body = "bar"
node = 1
z_axis = [0.0, 1.0, 0.0]
[markers.tip]
body = "bar"
node = 2
[joints.revolute]
type = "revolute"
markers = ["pivot", "hinge"]
"""


def write_inputs(body: Body, folder: Path, h: float) -> tuple[Path, Path, Path]:
    """The body as each solver reads it: (SID file, its scene file, npz file with M and K beside it)."""
    from sidprep.sid.io import write_sid

    sid_file = write_sid(sidprep_sid(body), folder / "bar.sid.h5")
    scene = folder / "pendulum.toml"
    scene.write_text(SCENE.format(h=h))
    npz = folder / "bar.npz"
    np.savez(npz, points=body.points, Phi=body.Phi, omega2=body.omega2, tip=body.tip, hinge_nodes=body.hinge_nodes)
    scipy.sparse.save_npz(str(npz) + ".M.npz", body.M.tocsr())
    scipy.sparse.save_npz(str(npz) + ".K.npz", body.K.tocsr())
    return sid_file, scene, npz


def child_cost(argv: list[str], source: Path, folder: Path) -> dict:
    """Whole-process CPU s (user + system of the child) and, from a script child (``-c``), its
    pendulum angle at t_end and integration CPU s (NaN for the command); ``source`` None: the
    interpreter's installed sidprep."""
    env = {**os.environ, "PYTHONPATH": str(source)} if source else \
        {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    out = subprocess.run(argv, env=env, check=True, capture_output=True, text=True, cwd=folder).stdout
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    script = argv[1] == "-c"
    angle, integration = json.loads(out.strip().splitlines()[-1]) if script else (float("nan"), float("nan"))
    return {"process": (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime),
            "integration": integration, "angle": angle}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--mesh", type=Path, default=ROOT / "data/meshes/bar.msh")
    p.add_argument("--modes", type=int, default=16)
    p.add_argument("--h", type=float, default=1e-3, help="step, s")
    p.add_argument("--repeat", type=int, default=5)
    p.add_argument("--exudyn-python", default=sys.executable, help="a Python with exudyn==1.13.6 installed")
    p.add_argument("--before", type=Path, help="another checkout's sidprep, run side by side (e.g. /work/main)")
    p.add_argument("--installed", help="a Python whose installed sidprep runs side by side (a venv of a wheel)")
    args = p.parse_args()
    body = reduced_bar(args.mesh, args.modes)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        sid_file, scene, npz = write_inputs(body, folder, args.h)
        checkouts = {"": ROOT} | ({" (before)": args.before.resolve()} if args.before else {})
        api = [sys.executable, "-c", SIDPREP_CHILD, str(BENCHMARKS), str(sid_file), repr(args.h)]
        cli = [sys.executable, "-m", "sidprep.cli.main", "simulate", str(scene), "-q", "-o", "r.results.h5"]
        runs = {f"sidprep API{tag}": (api, source) for tag, source in checkouts.items()}
        runs |= {f"sidprep simulate{tag}": (cli, source) for tag, source in checkouts.items()}
        if args.installed:
            runs["sidprep API (installed)"] = ([args.installed, *api[1:]], None)
            runs["sidprep simulate (installed)"] = ([args.installed, *cli[1:]], None)
        runs["Exudyn"] = ([args.exudyn_python, "-c", EXUDYN_CHILD, str(BENCHMARKS), str(npz), repr(args.h)], ROOT)
        for argv, source in runs.values():  # warm-up: files in the page cache
            child_cost(argv, source, folder)
        rows = {name: [] for name in runs}
        loads = [os.getloadavg()[0]]
        for _ in range(args.repeat):
            for name, (argv, source) in runs.items():
                rows[name].append(child_cost(argv, source, folder))
            loads.append(os.getloadavg()[0])
    print(f"{args.mesh.name}: {body.M.shape[0]} DOF, {args.modes} clamped modes, h = {args.h:g} s, 1 s; medians of "
          f"{args.repeat} fresh processes each, load average {min(loads):.1f}-{max(loads):.1f}, CPU s")
    print("| solver | whole process | integration | rest of the process | angle at 1 s, rad | process / Exudyn's |")
    print("|---|---|---|---|---|---|")
    exudyn = float(np.median([r["process"] for r in rows["Exudyn"]]))
    for name, rs in rows.items():
        whole, integration = (float(np.median([r[k] for r in rs])) for k in ("process", "integration"))
        print(f"| {name} | {whole:.3f} | {integration:.3f} | {whole - integration:.3f} | {rs[0]['angle']:.6f} "
              f"| {whole / exudyn:.2f} |".replace("nan", "-"))


if __name__ == "__main__":
    main()
