"""``sidprep simulate``: the JSON contract, the files it writes, the report, and its errors."""

import gc
import json
import os
import subprocess
import sys
import xml.etree.ElementTree as ET

import meshio
import numpy as np
import pytest

from sidprep.cli.main import main
from sidprep.sid.io.sid_hdf5 import write_sid_hdf5
from sidprep.solver.results import read_results
from test_scene import TINY_SCENE, tiny_sid


@pytest.fixture
def scene(tmp_path):
    write_sid_hdf5(tiny_sid(), tmp_path / "tiny.sid.h5")
    path = tmp_path / "scene.toml"
    path.write_text(TINY_SCENE)
    return path


def test_json_summary_is_one_object_with_the_contract_keys(scene, tmp_path, capsys):
    out = tmp_path / "run" / "r.h5"
    assert main(["simulate", str(scene), "-o", str(out), "--t-end", "0.03", "--json", "-q"]) == 0
    captured = capsys.readouterr()
    summary = json.loads(captured.out)                     # the whole of stdout is one JSON object
    assert captured.err == ""
    for key in ("steps", "cpu_s", "energy", "effects", "bodies", "outputs"):
        assert key in summary
    assert summary["steps"] == 30 and summary["t_end"] == pytest.approx(0.03)
    assert set(summary["energy"]) == {"initial", "final", "max_rel_drift", "balance_error", "tolerance", "warning"}
    assert summary["energy"]["balance_error"] <= summary["energy"]["tolerance"] == 1e-3
    assert summary["energy"]["warning"] is None
    assert set(summary["effects"]) >= {"included", "left_out", "warnings"}
    result = read_results(out).result
    final = summary["bodies"]["bar"]
    assert np.allclose(final["position"], result.bodies["bar"].position[-1], rtol=0, atol=0)
    assert np.allclose(final["rotation"], result.bodies["bar"].rotation[-1], rtol=0, atol=0)
    assert summary["outputs"] == {"results": str(out)}


BOX = """
[bodies.box]
type = "rigid"
mass = 1.0
inertia = [0.1, 0.1, 0.1]
obj = "box.obj"
position = [0, 0, -2]
[markers.box_o]
body = "box"
[markers.floor]
body = "ground"
position = [0, 0, -2]
[joints.weld]
type = "fixed"
markers = ["floor", "box_o"]
"""


def test_plot_csv_animation_and_report(scene, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "box.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    scene.write_text(TINY_SCENE + BOX)
    assert main(["simulate", str(scene), "--t-end", "0.02", "--plot", "--csv", "--animate"]) == 0
    captured = capsys.readouterr()
    assert "body 'bar':" in captured.out and "included" in captured.out and "left out" in captured.out
    assert "simulate" in captured.err                      # progress lines go to stderr
    stem = tmp_path.name                                   # a scene.toml is named after its folder
    for suffix in (".results.h5", ".png", ".csv", ".pvd"):
        assert (tmp_path / (stem + suffix)).is_file(), suffix
    header = (tmp_path / (stem + ".csv")).read_text().splitlines()[0]
    assert header == "time [s],tip.position.z [m],hinge.coordinate [rad],energy.total [J],bar.q.2 [1]"
    frames = [d.get("file") for d in ET.parse(tmp_path / (stem + ".pvd")).getroot().iter("DataSet")]
    assert len(frames) == 3 and all((tmp_path / f).is_file() for f in frames)     # 100 samples/s, 0..0.02 s
    last = meshio.read(tmp_path / frames[-1])
    box = np.concatenate(last.cell_data["body"]) == 1                             # bodies in scene order
    assert [c.type for c in last.cells] == ["vertex", "triangle"] and box.sum() == 1
    assert np.allclose(last.points[-3:], [[0, 0, -2], [1, 0, -2], [0, 1, -2]], atol=1e-9)   # the welded OBJ


@pytest.mark.parametrize("argv_tail, words", [
    (["--t-end", "-1"], ["[solver] t_end", "> 0"]),
    ([], ["[bodies.bar] sid", "not found", "python make_tiny.py"]),
])
def test_errors_are_one_line_with_exit_code_2(scene, tmp_path, capsys, argv_tail, words):
    if not argv_tail:
        (tmp_path / "tiny.sid.h5").unlink()
    assert main(["simulate", str(scene), "-o", str(tmp_path / "r.h5"), "-q", *argv_tail]) == 2
    err = capsys.readouterr().err
    assert err.startswith("sidprep: error: ") and err.count("\n") == 1
    assert all(w in err for w in words), err
    assert not (tmp_path / "r.h5").exists()


def test_list_signals_names_every_signal_without_simulating(scene, tmp_path, capsys):
    assert main(["simulate", str(scene), "--list-signals", "-q", "-o", str(tmp_path / "r.h5")]) == 0
    names = capsys.readouterr().out.split()
    assert {"bar.q.2", "tip.position.z", "hinge.force.x", "hinge.coordinate", "energy.total"} <= set(names)
    assert not (tmp_path / "r.h5").exists()


def test_missing_scene_file(tmp_path, capsys):
    assert main(["simulate", str(tmp_path / "none.toml")]) == 2
    assert "scene file not found" in capsys.readouterr().err


RIGID_ROD_TIED_TOO_FAR = """
[solver]
t_end = 0.01
[bodies.rod]
type = "rigid"
mass = 1.0
inertia = [0.1, 0.1, 0.1]
[markers.a]
body = "rod"
[markers.b]
body = "rod"
position = [1, 0, 0]
[markers.p]
body = "ground"
[markers.q]
body = "ground"
position = [5, 0, 0]
[joints.ja]
type = "spherical"
markers = ["p", "a"]
[joints.jb]
type = "spherical"
markers = ["q", "b"]
"""


def test_solver_errors_name_the_scene_file(tmp_path, capsys):
    scene = tmp_path / "rod.toml"
    scene.write_text(RIGID_ROD_TIED_TOO_FAR)                 # a 1 m rod between points 5 m apart
    code = main(["simulate", str(scene), "-o", str(tmp_path / "r.h5"), "-q"])
    err = capsys.readouterr().err
    assert (code, err.count("\n")) == (2, 1) and err.startswith(f"sidprep: error: {scene}: "), err



PROCESS = """
import gc, json, os, sys
from sidprep.cli.options import process_setup
process_setup()
import numpy, scipy.linalg
from threadpoolctl import threadpool_info
print(json.dumps([os.environ.get("OPENBLAS_NUM_THREADS"), [p["num_threads"] for p in threadpool_info()
                                                           if p["internal_api"] == "openblas"], gc.isenabled()]))
"""


@pytest.mark.parametrize("user, threads", [(None, "1"), ("2", "2")])
def test_simulate_process_starts_one_blas_thread_unless_the_user_sets_it(user, threads):
    """The command's process: BLAS pools with one thread (their idle threads cost 0.2 CPU-s of every
    process, sidprep/cli/options.py SOLVER_THREADS; the user's own OPENBLAS_NUM_THREADS wins) and no
    cyclic garbage collector."""
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"} | (
        {"OPENBLAS_NUM_THREADS": user} if user else {})
    out = subprocess.run([sys.executable, "-c", PROCESS], env=env, capture_output=True, text=True, check=True)
    setting, pools, collector = json.loads(out.stdout)
    assert setting == threads
    assert pools and all(n <= int(threads) for n in pools)
    assert collector is False


def test_main_called_from_python_leaves_the_process_alone(scene, tmp_path, monkeypatch):
    """``main`` in a Python session (not the command's own process) changes neither the BLAS
    setting its child processes would inherit nor the garbage collector."""
    monkeypatch.delenv("OPENBLAS_NUM_THREADS", raising=False)
    assert main(["simulate", str(scene), "-o", str(tmp_path / "r.h5"), "--t-end", "0.01", "-q"]) == 0
    assert "OPENBLAS_NUM_THREADS" not in os.environ
    assert gc.isenabled()


def test_results_are_named_after_the_scene_and_a_replaced_file_of_another_scene_is_a_note(scene, tmp_path, capsys,
                                                                                          monkeypatch):
    """[scene] name names the outputs; a results file another scene wrote is replaced with a note."""
    monkeypatch.chdir(tmp_path)
    other = tmp_path / "other.toml"
    other.write_text(TINY_SCENE.replace("[scene]", '[scene]\nname = "tiny"', 1) if "[scene]" in TINY_SCENE
                     else '[scene]\nname = "tiny"\n' + TINY_SCENE)
    named = tmp_path / "named.toml"
    named.write_text(other.read_text())
    assert main(["simulate", str(other), "--t-end", "0.01", "-q"]) == 0
    assert capsys.readouterr().out.split() == ["tiny.results.h5"]      # -q: only the files written
    assert main(["simulate", str(other), "--t-end", "0.01"]) == 0      # the same scene again: no note
    assert "note:" not in capsys.readouterr().err
    assert main(["simulate", str(named), "--t-end", "0.01"]) == 0
    err = capsys.readouterr().err
    assert [line for line in err.splitlines() if line.startswith("note:")] == [
        f"note: tiny.results.h5: replaced the results of {other} (another scene; name the output with -o)"]


def test_quiet_prints_no_report(scene, tmp_path, capsys):
    out = tmp_path / "q.results.h5"
    assert main(["simulate", str(scene), "--t-end", "0.01", "-q", "-o", str(out)]) == 0
    captured = capsys.readouterr()
    assert captured.out.split() == [str(out)] and captured.err == ""
