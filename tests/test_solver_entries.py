"""The compiled entries a run calls from Python, docs/performance.md "Allocation-free step"):
a process loads each entry's whole call tree from the kernel cache, so the evaluation's tree is
reached through as few entries as possible.  A generalised-alpha or RK4 run calls the start's one
entry (``state_equations``) and the loop (which computes its samples' outputs too), never
``evaluate_into``, ``markers_into``, ``index1_accelerations`` or ``sample_outputs`` directly."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from sidprep.solver.equations.aot import SWITCH

ROOT = Path(__file__).resolve().parents[1]
#: kernels whose call tree holds the evaluation and that a compiled-loop run must not call from Python
NOT_FROM_PYTHON = ("evaluate_into", "markers_into", "index1_accelerations", "sample_outputs")

#: the child: ten steps of the flexible pendulum; the kernels that have a signature in this process
CHILD = r"""
import json, sys
from sidprep.solver.scene import load_scene, simulate
import sidprep.solver.equations.assemble as assemble
import sidprep.solver.integrators.base as base
import sidprep.solver.integrators.explicit as explicit
import sidprep.solver.integrators.genalpha as genalpha
import sidprep.solver.integrators.outputs as outputs
h = float(sys.argv[3])
simulate(load_scene(sys.argv[1]), t_end=10 * h, method=sys.argv[2], h=h)
kernels = {"evaluate_into": assemble.evaluate_into, "markers_into": assemble.markers_into,
           "index1_accelerations": base.index1_accelerations, "sample_outputs": outputs.sample_outputs,
           "state_equations": base.state_equations, "ga_loop": genalpha.ga_loop, "rk4_loop": explicit.rk4_loop}
print(json.dumps({name: len(fn.signatures) for name, fn in kernels.items()}))
"""


def loaded_entries(method: str, h: float) -> dict:
    """{kernel: number of signatures} after a run in a fresh process with a warm kernel cache (a
    first process fills it: compiling an entry compiles its callees' signatures too); numba's
    dispatchers only (an installed ahead-of-time extension would serve the entries unseen)."""
    env = {**os.environ, "PYTHONPATH": str(ROOT), SWITCH: "0"}
    scene = str(ROOT / "examples/flexible_pendulum/scene.toml")
    for _ in range(2):
        out = subprocess.run([sys.executable, "-c", CHILD, scene, method, repr(h)], env=env, check=True, capture_output=True,
                             text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


@pytest.mark.parametrize("method, h, loop", [("genalpha", 1e-3, "ga_loop"), ("rk4", 1e-5, "rk4_loop")])
def test_a_run_reaches_the_evaluation_through_the_start_entry_and_the_loop(method, h, loop):
    entries = loaded_entries(method, h)
    assert entries["state_equations"] >= 1 and entries[loop] >= 1
    assert {name: entries[name] for name in NOT_FROM_PYTHON} == dict.fromkeys(NOT_FROM_PYTHON, 0)
