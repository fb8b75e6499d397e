#!/usr/bin/env python3
"""What loading the compiled kernels costs a warm process, entry point by entry point.

numba loads a cached kernel on its first call from Python: it unpickles the entry's cache file,
parses the LLVM bitcode of the entry's whole call tree (kept in the cache so that a later caller
could inline it), registers its symbols and links its object code.  This runs one scene once in a
fresh process (``--repeat`` processes, medians) and times every top-level load (``Dispatcher.compile``
finding the cached object) in CPU ms, with the part spent parsing bitcode and registering symbols,
and the size of the entry's cache file.  The first entry also pays numba's own first-use
initialisation (its typing and lowering registries), whatever its size.

    python benchmarks/kernel_loading.py examples/beam_slider_crank/scene.toml
    python benchmarks/kernel_loading.py examples/engine/scene.toml --repeat 3

Needs a warm kernel cache (run the scene once first).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

#: the child: the scene run once, every top-level kernel load timed (CPU s), printed as JSON
CHILD = r"""
import json, sys, time
from pathlib import Path
from sidprep.cli.options import process_setup
process_setup()
from sidprep.solver.scene import load_scene, simulate
from sidprep.solver.equations.kernel_cache import KERNEL_CACHE, NAMESPACE
from numba.core import codegen, dispatcher

spent = {"parse": 0.0, "symbols": 0.0}


def timed(key, fn):
    def wrapper(*args):
        start = time.process_time()
        try:
            return fn(*args)
        finally:
            spent[key] += time.process_time() - start
    return wrapper


codegen.ll.parse_bitcode = timed("parse", codegen.ll.parse_bitcode)
codegen.JitEngine._load_defined_symbols = timed("symbols", codegen.JitEngine._load_defined_symbols)
loads, depth, compile_ = [], [0], dispatcher.Dispatcher.compile


def compile(self, sig):
    depth[0] += 1
    before, start = dict(spent), time.process_time()
    try:
        return compile_(self, sig)
    finally:
        depth[0] -= 1
        if depth[0] == 0:
            f = self.py_func
            files = list((KERNEL_CACHE / NAMESPACE).rglob(f"*.{f.__name__}-{f.__code__.co_firstlineno}.*.nbc"))
            loads.append([f.__module__.rsplit(".", 1)[-1] + "." + f.__name__, time.process_time() - start,
                          spent["parse"] - before["parse"], spent["symbols"] - before["symbols"],
                          max((p.stat().st_size for p in files), default=0)])


dispatcher.Dispatcher.compile = compile
simulate(load_scene(sys.argv[1]))
print(json.dumps(loads))
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("scene", type=Path)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    scene = args.scene.resolve()
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    runs, loads = [], [os.getloadavg()[0]]
    for _ in range(args.repeat):
        out = subprocess.run([sys.executable, "-c", CHILD, str(scene)], env=env, cwd=scene.parent, check=True,
                             capture_output=True, text=True).stdout
        runs.append(json.loads(out.strip().splitlines()[-1]))
        loads.append(os.getloadavg()[0])
    print(f"{scene.name}: kernel loads of one run, medians of {args.repeat} fresh processes, load average "
          f"{min(loads):.1f}-{max(loads):.1f}; CPU ms")
    print("| entry (first call from Python) | load | of it bitcode parsing | symbols | cache file, MB |")
    print("|---|---|---|---|---|")
    total = np.zeros(3)
    for k, (name, *_, size) in enumerate(runs[0]):
        cost = np.median([[r[k][1], r[k][2], r[k][3]] for r in runs], axis=0) * 1e3
        total += cost
        print(f"| {name} | {cost[0]:.1f} | {cost[1]:.1f} | {cost[2]:.1f} | {size / 1e6:.2f} |")
    print(f"| all {len(runs[0])} | {total[0]:.1f} | {total[1]:.1f} | {total[2]:.1f} | |")


if __name__ == "__main__":
    main()
