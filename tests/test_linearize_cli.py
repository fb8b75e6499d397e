"""``sidprep linearize SCENE``: mechanism eigenfrequencies at the assembled start, table or JSON.

Reference: a rigid disc (I_zz = 0.03 kg m^2) on a revolute joint with a torsion spring
k = 50 N m/rad oscillates at f = sqrt(k / I_zz) / (2 pi) = 6.4975 Hz (closed form).
"""

import json
import math
from pathlib import Path

import numpy as np

from sidprep.cli.main import main

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "tests/data/scenes/torsion_oscillator.toml"
F_CLOSED_FORM_HZ = math.sqrt(50.0 / 0.03) / (2 * math.pi)
#: central differences of step 1e-6 on a linear spring: round-off only
FREQUENCY_RTOL = 1e-6


def run(capsys, *argv):
    code = main(list(map(str, argv)))
    out, err = capsys.readouterr()
    return code, out, err


def test_json_frequency_and_shape_against_the_closed_form(capsys):
    code, out, _ = run(capsys, "linearize", SCENE, "--json")
    data = json.loads(out)
    assert code == 0 and data["n_rigid"] == 0 and len(data["frequencies_hz"]) == 1
    assert abs(data["frequencies_hz"][0] / F_CLOSED_FORM_HZ - 1) < FREQUENCY_RTOL
    shape = np.array(data["shapes"][0])
    k = data["coordinates"].index(["disc", "omega.z"])
    assert abs(abs(shape[k]) - 1 / math.sqrt(0.03)) < 1e-6 * abs(shape[k])      # mass-normalised: I w^2 = 1
    assert np.sum(np.abs(shape) > 1e-9) == 1                                       # rotation about z only


def test_table(capsys):
    code, out, _ = run(capsys, "linearize", SCENE)
    assert code == 0 and f"{F_CLOSED_FORM_HZ:12.4f}" in out and "disc omega.z" in out


def test_bad_input_is_one_line(capsys, tmp_path):
    code, _, err = run(capsys, "linearize", ROOT / "examples/flexible_pendulum/bar.sid.h5")
    assert code == 2 and "not a scene file" in err
    code, _, err = run(capsys, "linearize", SCENE, "--count", "0")
    assert code == 2 and "--count 0" in err


def test_the_library_function_a_script_calls_gives_the_closed_form():
    import sidprep

    linearized = sidprep.linearize_scene(SCENE)
    assert linearized.modes.n_rigid == 0 and linearized.scene.path == SCENE
    assert abs(linearized.modes.frequencies_hz[0] / F_CLOSED_FORM_HZ - 1) < FREQUENCY_RTOL
