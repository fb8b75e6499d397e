"""The ParaView series stays compact: a 10 s run at 100 samples/s (1001 samples) gives at most
MAX_VTU_FILES files, the first and last time included, each at the closed-form rigid position."""

import xml.etree.ElementTree as ET

import meshio
import numpy as np

from sidprep.sid.surface import Surface
from sidprep.solver.animation import MAX_VTU_FILES, write_animation
from sidprep.solver.effects import EffectsReport
from sidprep.solver import Result
from test_view_animate import RATE, history, rz


def test_long_run_writes_few_files(tmp_path):
    t = np.linspace(0, 10, 1001)
    result = Result(t=t, bodies={"block": history("block", t, 0, [0, 0.3, 0])}, joints={}, markers={},
                    energy={"total": np.zeros_like(t)}, constraint_error=np.zeros_like(t),
                    effects=EffectsReport(bodies={}, notes=()))
    p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.0]])
    pvd = write_animation(result, {"block": Surface(p, np.array([[0, 1, 2]]), np.zeros((3, 3, 0)))},
                          tmp_path / "a.pvd")
    sets = list(ET.parse(pvd).getroot().iter("DataSet"))
    assert len(sets) <= MAX_VTU_FILES and len(list((tmp_path / "a_vtu").iterdir())) == len(sets)
    times = [float(d.get("timestep")) for d in sets]
    assert times[0] == 0 and times[-1] == 10.0
    last = meshio.read(tmp_path / sets[-1].get("file"))
    assert np.allclose(last.points, [0, 0.3, 0] + p @ rz(RATE * 10.0).T, rtol=0, atol=1e-12)
