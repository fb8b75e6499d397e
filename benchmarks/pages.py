"""CPU time and size of a mechanism page (``sidprep animate``) against the run's length: a
4000-point surface with 20 modes over 1000 to 10000 output samples.

Target: at most 1 CPU-s per 1000 samples of a 4k-point surface, and at most 5 MB per page.
Each size is written ``--repeat`` times in this process; the median CPU time is printed with the
load average (the machine is shared).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from sidprep.sid.io import read_sid, write_sid  # noqa: E402
from sidprep.sid.model import SurfaceModes  # noqa: E402
from sidprep.view.mechanism import write_mechanism_page  # noqa: E402
from test_view_pages import pendulum_results  # noqa: E402

BAR_SID = ROOT / "examples" / "flexible_pendulum" / "bar.sid.h5"
POINTS = 4000


def large_sid(folder: Path) -> Path:
    """The bundled bar's SID with a random 4000-point surface (shapes of its own modes' size)."""
    rng = np.random.default_rng(0)
    sid = read_sid(BAR_SID)
    surface = SurfaceModes(points=rng.uniform(0.0, 1.0, (POINTS, 3)), triangles=rng.integers(0, POINTS, (2 * POINTS, 3)),
                           shapes=1e-3 * rng.normal(size=(POINTS, 3, sid.nq)), node_ids=np.arange(POINTS))
    path = folder / "large.sid.h5"
    write_sid(replace(sid, surface=surface), path)
    return path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--samples", type=int, nargs="+", default=[1000, 3000, 10000])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    folder = Path(tempfile.mkdtemp())
    sid = large_sid(folder)
    print(f"load average {os.getloadavg()[0]:.2f}")
    print(f"{'samples':>8} {'CPU-s (median)':>15} {'CPU-s per 1000':>15} {'page MB':>8}")
    for n in args.samples:
        results = pendulum_results(folder, n, sid)
        times = []
        for _ in range(args.repeat):
            start = time.process_time()
            page = write_mechanism_page(results, folder / f"page{n}.html")
            times.append(time.process_time() - start)
        cpu = statistics.median(times)
        print(f"{n:>8} {cpu:>15.2f} {1000 * cpu / n:>15.3f} {page.stat().st_size / 1e6:>8.2f}")
    print(f"load average {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
