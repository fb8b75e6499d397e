"""Options validated before the work, one-line errors, results on stdout and diagnostics on stderr,
the shipped job file of the README tour."""

import contextlib
import json
import re
import socket
import threading
import time
from pathlib import Path

import pytest

from sidprep.cli.main import main
from sidprep.errors import InputError

ROOT = Path(__file__).resolve().parents[1]
BAR = ROOT / "data" / "meshes" / "bar.msh"


@pytest.fixture
def not_assembled(monkeypatch):
    """The model's K and M fail the test if they are assembled: options are checked before the work."""
    def assembled(*args, **kwargs):
        raise AssertionError("the model was assembled before its options were checked")

    monkeypatch.setattr("sidprep.jobs.reduce.stiffness_matrix", assembled)
    monkeypatch.setattr("sidprep.jobs.modal.stiffness_and_mass", assembled)


def one_line_error(capsys, argv, *needles) -> None:
    assert main(argv) == 2
    cap = capsys.readouterr()
    err = cap.err.strip().splitlines()[-1]
    assert err.startswith("sidprep: error:"), cap.err
    assert cap.out == ""
    for n in needles:
        assert n in err, err


@pytest.mark.parametrize("damping, needle", [("-1", "--damping -1"), ("5", "--damping 5"), ("1", "--damping 1")])
def test_damping_outside_0_1_is_rejected(tmp_path, capsys, not_assembled, damping, needle):
    one_line_error(capsys, ["reduce", str(BAR), "--damping", damping, "-o", str(tmp_path / "b.sid.h5")], needle, "< 1")
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("output, needle", [("out.txt", "unknown file type"), (".", "is a folder"),
                                            ("/proc/x.sid.h5", "not writable")])
def test_bad_outputs_are_rejected_before_computing(tmp_path, capsys, monkeypatch, not_assembled, output, needle):
    monkeypatch.chdir(tmp_path)
    one_line_error(capsys, ["reduce", str(BAR), "-o", output], needle)


def test_too_many_modes_are_rejected_before_assembly(capsys, not_assembled):
    one_line_error(capsys, ["modes", str(BAR), "--count", "100000", "-q"], "--count 100000", "3372")
    one_line_error(capsys, ["reduce", str(BAR), "--modes", "100000", "-q"], "--modes 100000", "3372")


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


# ------------------------------------------------------------------------------------------------
# --scheduler: the address's form, and a Dask scheduler at it before distributed reads from it
# ------------------------------------------------------------------------------------------------

#: a silent peer is given up after this (the probe's own limit is PROBE_TIMEOUT_S)
SILENT_PEER_TIMEOUT_S = 0.5


@contextlib.contextmanager
def peer(first_bytes: bytes | None):
    """A TCP server on localhost that sends ``first_bytes`` to every connection (None: sends nothing)
    and keeps it open; yields its address."""
    server = socket.create_server(("127.0.0.1", 0))
    stop = threading.Event()

    def serve():
        server.settimeout(0.1)
        held = []
        while not stop.is_set():
            try:
                conn, _ = server.accept()
            except OSError:
                continue
            if first_bytes:
                conn.sendall(first_bytes)
            held.append(conn)
        for conn in held:
            conn.close()

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield f"tcp://127.0.0.1:{server.getsockname()[1]}"
    finally:
        stop.set()
        thread.join()
        server.close()


@pytest.mark.parametrize("address", ["http://10.0.0.5:8786", "tcp://host", "tcp://host:0", "tcp://host:70000",
                                     "tcp://:8786", "tcp://host:8786/path", "tcp://user@host:8786", "", "host:port"])
def test_malformed_scheduler_addresses_are_refused_by_their_form(address):
    from sidprep.jobs.scheduler_address import scheduler_address

    with pytest.raises(InputError, match=r"^--scheduler .*: (not a scheduler address|unknown scheme).*tcp://HOST:PORT"):
        scheduler_address(address)


def test_a_scheduler_address_gives_host_and_port():
    from sidprep.jobs.scheduler_address import scheduler_address

    assert scheduler_address("tcp://10.0.0.5:8786") == ("10.0.0.5", 8786)
    assert scheduler_address("node7:8786") == ("node7", 8786)
    assert scheduler_address("tcp://[::1]:8786") == ("::1", 8786)


@pytest.mark.parametrize("first_bytes", [
    b"\xff" * 8,                                          # "allocate 1.8e19 bytes" to distributed's reader
    b"SSH-2.0-OpenSSH_9.6\r\n",                           # another service that speaks first
    (58).to_bytes(8, "little") + bytes(58),               # a plausible length, then no frames
    b"\x10\x00\x00\x00\x00\x00\x00\x00" + b"HTTP/1.1",    # 16 bytes announced, 8 sent, then silence
], ids=["huge_length", "ssh", "zeros", "short"])
def test_a_peer_that_is_not_a_dask_scheduler_is_refused_in_bounded_time(first_bytes):
    from sidprep.jobs.scheduler_address import probe_scheduler

    with peer(first_bytes) as address:
        t0 = time.perf_counter()
        with pytest.raises(InputError, match=r"is not a Dask scheduler|cannot reach"):
            probe_scheduler(address, timeout=SILENT_PEER_TIMEOUT_S)
        assert time.perf_counter() - t0 < 5 * SILENT_PEER_TIMEOUT_S


def test_a_silent_peer_and_a_closed_port_are_refused():
    from sidprep.jobs.scheduler_address import probe_scheduler

    with peer(None) as address:
        with pytest.raises(InputError, match=r"is not a Dask scheduler|cannot reach the scheduler \(timed out\)"):
            probe_scheduler(address, timeout=SILENT_PEER_TIMEOUT_S)
    with pytest.raises(InputError, match=r"cannot reach the scheduler \(Connection refused\)"):
        probe_scheduler(address, timeout=SILENT_PEER_TIMEOUT_S)


def test_a_dask_scheduler_passes_the_probe():
    """The handshake layout read by the probe is that of the installed distributed."""
    from distributed import LocalCluster

    from sidprep.jobs.scheduler_address import probe_scheduler

    with LocalCluster(n_workers=0, processes=False, protocol="tcp", dashboard_address=None) as cluster:
        assert probe_scheduler(cluster.scheduler_address) == cluster.scheduler_address


# ------------------------------------------------------------------------------------------------
# solver settings that cannot mean what they say, and signals without values
# ------------------------------------------------------------------------------------------------

PENDULUM = ROOT / "examples" / "flexible_pendulum" / "scene.toml"


@pytest.mark.parametrize("overrides, needle", [
    ({"h": 2.0}, "step = 2 s is longer than t_end = 1 s"),
    ({"h": 1e300}, "step = 1e+300 s is longer than t_end = 1 s"),
    ({"method": "rk4", "rtol": 1e-6}, "rtol = 1e-06: rk4 steps at the fixed step h"),
])
def test_settings_that_cannot_apply_are_refused_before_the_run(overrides, needle):
    from sidprep.solver.scene import load_scene, simulate

    with pytest.raises(InputError, match=re.escape(needle)):
        simulate(load_scene(PENDULUM), **overrides)


@pytest.mark.parametrize("signal_name, needle", [
    ("hinge.effort", "joint 'hinge' has no effort of its own"),
])
def test_signals_that_would_be_all_nan_are_refused_at_scene_load(tmp_path, signal_name, needle):
    from sidprep.solver.scene import load_scene

    for f in PENDULUM.parent.iterdir():
        (tmp_path / f.name).symlink_to(f)
    scene = tmp_path / "s.toml"
    scene.write_text(PENDULUM.read_text().replace('signals = ["', f'signals = ["{signal_name}", "'))
    with pytest.raises(InputError, match=re.escape(needle)):
        load_scene(scene)


def test_a_joint_without_a_coordinate_has_no_coordinate_signal():
    from sidprep.solver.model.system import System
    from sidprep.solver.model.bodies import RigidBody
    from sidprep.solver.model.joints import Spherical
    from sidprep.solver.scene import _undefined_joint_signal

    system = System()
    body = system.add(RigidBody(1.0, [0, 0, 0], [1.0, 1.0, 1.0], name="ball")) or system.bodies[-1]
    system.add(Spherical(system.ground.marker(name="o"), body.marker(name="c"), name="socket"))
    assert "has no coordinate" in _undefined_joint_signal("socket.coordinate", system)
    assert _undefined_joint_signal("socket.force_local", system) is None
