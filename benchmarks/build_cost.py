#!/usr/bin/env python3
"""What building and first running sidprep costs, in CPU s of every process involved (pip, its
isolated build environment, Cython, the C compiler; the first command): for this checkout and,
with ``--before PATH``, another checkout (e.g. the previous main), the two alternating so that the
pairs share the machine's load.

1. ``pip install --no-deps CHECKOUT`` into a fresh venv that sees the current environment's
   packages (a ``.pth`` file naming its site-packages: the dependencies are there), pip's isolated
   build environment included (setuptools, Cython and scipy installed into it from pip's index);
2. the first ``sidprep simulate`` of a bundled example from that install, with an empty user cache
   (``XDG_CACHE_HOME`` and ``NUMBA_CACHE_DIR`` in a new temporary folder);
3. with ``--editable``: ``pip install --no-deps -e`` of a fresh clone, then its first simulate.

    python benchmarks/build_cost.py --repeat 3
    python benchmarks/build_cost.py --before /work/main --repeat 1 --scene examples/slider_crank/scene.toml

Run from a venv that has sidprep's dependencies (pip needs network or a local index for the build
environment's setuptools and Cython).  Medians; the load average is printed.
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import sysconfig
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def children_cpu() -> float:
    """User + system CPU s of every waited-for child process so far."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def timed(command: list[str], env: dict | None = None, cwd: Path | None = None) -> float:
    """CPU s of ``command`` and all its children (it must succeed)."""
    before = children_cpu()
    subprocess.run(command, env=env, cwd=cwd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return children_cpu() - before


def fresh_clone(checkout: Path, folder: Path) -> Path:
    """A clone of ``checkout``'s committed HEAD in ``folder`` (no build products of the checkout)."""
    subprocess.run(["git", "clone", "-q", str(checkout), str(folder)], check=True)
    return folder


def install_and_run(checkout: Path, scene: str, editable: bool) -> tuple[float, float]:
    """(install CPU s, first simulate CPU s) of a fresh clone of ``checkout`` in a fresh venv."""
    with tempfile.TemporaryDirectory(prefix="sidprep-build-") as tmp:
        tmp = Path(tmp)
        clone = fresh_clone(checkout, tmp / "src")
        subprocess.run([sys.executable, "-m", "venv", str(tmp / "venv")], check=True)
        python = str(tmp / "venv" / "bin" / "python")
        site = subprocess.run([python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                              check=True, capture_output=True, text=True).stdout.strip()
        (Path(site) / "dependencies.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
        install = [python, "-m", "pip", "install", "-q", "--no-deps", *(["-e"] if editable else []), str(clone)]
        env = {**os.environ, "XDG_CACHE_HOME": str(tmp / "cache"), "NUMBA_CACHE_DIR": str(tmp / "cache" / "numba")}
        env.pop("PYTHONPATH", None)
        cpu_install = timed(install, env=env, cwd=tmp)
        run = [python, "-m", "sidprep.cli.main", "simulate", str(clone / scene), "-q", "-o", str(tmp / "out.results.h5")]
        cpu_run = timed(run, env=env, cwd=tmp)
        return cpu_install, cpu_run


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--before", type=Path, help="another checkout, measured alternately")
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--scene", default="examples/flexible_pendulum/scene.toml")
    parser.add_argument("--editable", action="store_true", help="pip install -e instead of a regular install")
    args = parser.parse_args()
    checkouts = {"this": ROOT, **({"before": args.before.resolve()} if args.before else {})}
    found: dict[str, list[tuple[float, float]]] = {name: [] for name in checkouts}
    loads = [os.getloadavg()[0]]
    for _ in range(args.repeat):
        for name, checkout in checkouts.items():
            found[name].append(install_and_run(checkout, args.scene, args.editable))
            loads.append(os.getloadavg()[0])
    kind = "pip install -e --no-deps" if args.editable else "pip install --no-deps"
    print(f"{kind}, then the first simulate of {args.scene} (empty user cache); CPU s, medians of {args.repeat}")
    for name, rows in found.items():
        install, run = np.median(np.array(rows), axis=0)
        print(f"  {name:7s} {checkouts[name]}: install {install:7.1f}   first simulate {run:6.2f}")
    print(f"  load average (1 min) {min(loads):.1f}-{max(loads):.1f}")


if __name__ == "__main__":
    main()
