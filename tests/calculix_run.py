"""Running the real CalculiX (``ccx``) in tests and reading its results (Debian calculix-ccx; .ci/run
installs it, the tests that need it skip with the reason without it)."""

import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

CCX = shutil.which("ccx")
needs_ccx = pytest.mark.skipif(CCX is None, reason="CalculiX (ccx) is not installed: apt-get install calculix-ccx "
                                                   "(.ci/run does); these tests run the real code")


def run_ccx(deck: Path) -> None:
    """Run ccx on ``deck`` (one thread) in its directory; fails the test on an error."""
    env = {**os.environ, "OMP_NUM_THREADS": "1", "CCX_NPROC_STIFFNESS": "1", "CCX_NPROC_EQUATION_SOLVER": "1"}
    done = subprocess.run([CCX, deck.stem], cwd=deck.parent, env=env, capture_output=True, text=True, timeout=600,
                          check=False)
    assert done.returncode == 0 and "*ERROR" not in done.stdout, done.stdout[-2000:]


def frd_block(path: Path, name: str, index: int = 0) -> dict:
    """{node: values} of the ``index``-th nodal result block ``name`` (DISP: 3 values, STRESS: 6, xx yy
    zz xy yz zx; a frequency step writes one block per mode) of a CalculiX .frd file (short format:
    node number in columns 4-13, values 12 wide)."""
    lines = path.read_text().splitlines()
    start = [k for k, line in enumerate(lines) if line.startswith(f" -4  {name}")][index]
    width = 3 if name == "DISP" else 6
    out = {}
    for line in lines[start + 1:]:
        if line.startswith(" -3"):
            break
        if line.startswith(" -1"):
            out[int(line[3:13])] = np.array([float(line[13 + 12 * j:25 + 12 * j]) for j in range(width)])
    return out
