"""Options validated before the work, one-line errors, results on stdout and diagnostics on stderr,
the shipped job file of the README tour."""

import json
import time
from pathlib import Path

import pytest

from sidprep.cli.main import main

ROOT = Path(__file__).resolve().parents[1]
BAR = ROOT / "data" / "meshes" / "bar.msh"
#: "rejected at once": well below one reduction of the bar (which takes a few seconds)
AT_ONCE_S = 3.0


def one_line_error(capsys, argv, *needles):
    t0 = time.perf_counter()
    assert main(argv) == 2
    dt = time.perf_counter() - t0
    cap = capsys.readouterr()
    err = cap.err.strip().splitlines()[-1]
    assert err.startswith("sidprep: error:"), cap.err
    assert cap.out == ""
    for n in needles:
        assert n in err, err
    return dt


@pytest.mark.parametrize("damping, needle", [("-1", "--damping -1"), ("5", "--damping 5"), ("1", "--damping 1")])
def test_damping_outside_0_1_is_rejected(tmp_path, capsys, damping, needle):
    dt = one_line_error(capsys, ["reduce", str(BAR), "--damping", damping, "-o", str(tmp_path / "b.sid.h5")],
                        needle, "< 1")
    assert dt < AT_ONCE_S and not list(tmp_path.iterdir())


@pytest.mark.parametrize("output, needle", [("out.txt", "unknown file type"), (".", "is a folder"),
                                            ("/proc/x.sid.h5", "not writable")])
def test_bad_outputs_are_rejected_before_computing(tmp_path, capsys, monkeypatch, output, needle):
    monkeypatch.chdir(tmp_path)
    assert one_line_error(capsys, ["reduce", str(BAR), "-o", output], needle) < AT_ONCE_S


def test_too_many_modes_are_rejected_at_once(capsys):
    assert one_line_error(capsys, ["modes", str(BAR), "--count", "100000", "-q"], "--count 100000", "3372") < AT_ONCE_S
    assert one_line_error(capsys, ["reduce", str(BAR), "--modes", "100000", "-q"], "--modes 100000", "3372") < AT_ONCE_S


def test_job_file_errors_are_one_line(tmp_path, capsys):
    one_line_error(capsys, ["reduce", str(tmp_path / "missing.toml")], "job file not found")
    job = tmp_path / "job.toml"
    job.write_text(f'mesh = "{BAR}"\nmodes = "six"\n')
    one_line_error(capsys, ["reduce", str(job)], str(job), "modes = 'six': expected an integer")
    job.write_text('mesh = "bar.msh\n')
    one_line_error(capsys, ["reduce", str(job)], "invalid TOML")


def test_the_shipped_job_file_runs_and_resolves_paths_against_itself(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    job = ROOT / "examples" / "reduce_job" / "job.toml"
    assert main(["reduce", str(job), "--modes", "2", "--no-check-frequencies", "-q"]) == 0
    out = capsys.readouterr().out.split()
    assert [Path(p).parent for p in out] == [job.parent] * 3 and all(Path(p).is_file() for p in out)
    for p in out:
        Path(p).unlink()


def test_modes_notes_go_to_stderr_and_json_stays_parseable(capsys):
    assert main(["modes", str(BAR), "--count", "1"]) == 0
    cap = capsys.readouterr()
    assert "note:" not in cap.out and "note: material" in cap.err
    assert main(["modes", str(BAR), "--count", "1", "--json"]) == 0
    json.loads(capsys.readouterr().out)


def test_native_stdout_is_sent_to_stderr(capfd):
    from sidprep.cli.options import quiet_native_output

    import os
    with quiet_native_output():
        os.write(1, b"CHOLMOD warning: from a native library\n")
    cap = capfd.readouterr()
    assert cap.out == "" and "CHOLMOD warning" in cap.err


def test_a_disconnected_mesh_gets_advice_that_fits_the_free_frame(tmp_path, capsys):
    import meshio
    import numpy as np

    m = meshio.read(BAR)
    tets = next(c for c in m.cells if c.type.startswith("tetra"))
    shift = np.array([0.0, 1.0, 0.0])                                   # a second bar beside the first
    pts = np.vstack([m.points, m.points + shift])
    two = meshio.Mesh(pts, [(tets.type, np.vstack([tets.data, tets.data + len(m.points)]))])
    path = tmp_path / "two_bars.msh"
    meshio.write(path, two, file_format="gmsh22", binary=False)
    capsys.readouterr()
    assert main(["reduce", str(path), "-q", "-o", str(tmp_path / "t.sid.h5")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "2 disconnected parts" in err and "add an interface on each part" in err
    assert "free frame" not in err                                       # the free frame was in use


def test_a_mesh_given_as_a_scene_is_rejected_in_one_line():
    from sidprep.errors import InputError
    from sidprep.tables import require_toml

    with pytest.raises(InputError, match=r"bar.msh: not a scene file \(a .toml file\); reduce the mesh first"):
        require_toml(BAR, "scene file", "reduce the mesh first: sidprep reduce " + str(BAR))
