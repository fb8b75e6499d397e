"""A scene body of `type = "beam"`: the analytical Euler-Bernoulli Beam declared inline."""

import numpy as np
import pytest

from sidprep.errors import InputError
from sidprep.solver.results import signal
from sidprep.solver.scene import load_scene, simulate

#: steel (sidprep.fe.material "steel") and the beam-buckling example's section: L = 1.69 m, 22.9 mm square
E, RHO, L, SIDE = 210e9, 7850.0, 1.69, 0.0229

SCENE = """
[scene]
gravity = [0.0, 0.0, 0.0]
[solver]
t_end = 0.02
step = 1e-3
[bodies.beam]
type = "beam"
length = 1.69
section = "rectangle:0.0229,0.0229"
material = "steel"
bc = "pinned-pinned"
modes = "xz:1-3"
damping = 0.02
{extra}
[markers.anchor]
body = "ground"
[markers.frame]
body = "beam"
[joints.clamp]
type = "fixed"
markers = ["anchor", "frame"]
"""


def test_inline_beam_has_the_closed_form_frequencies(tmp_path):
    path = tmp_path / "scene.toml"
    path.write_text(SCENE.format(extra=""))
    scene = load_scene(path)
    sid = scene.system.bodies[-1].sid
    EI, rhoA = E * SIDE**4 / 12, RHO * SIDE**2
    f_ref = np.array([n**2 * np.pi / (2 * L**2) * np.sqrt(EI / rhoA) for n in (1, 2, 3)])  # pinned-pinned
    f = np.sqrt(np.diag(sid.Ke.M0) / np.diag(sid.Me.M0)) / (2 * np.pi)
    assert np.allclose(f, f_ref, rtol=1e-8)
    assert scene.sources["beam"].kind == "beam"
    result = simulate(scene)                     # clamped frame, no load: stays at rest
    assert np.abs(signal(result, "beam.q.1")[0]).max() < 1e-12


def test_inline_beam_errors_name_the_table(tmp_path):
    path = tmp_path / "scene.toml"
    path.write_text(SCENE.format(extra='colour = "red"'))
    with pytest.raises(InputError, match=r"\[bodies.beam\]"):
        load_scene(path)
