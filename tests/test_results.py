"""Results files (HDF5 round trip, CSV, PNG) and the ParaView animation export.

References: the written arrays themselves (round trip must be bit-exact), and hand-computed
deformed surface points x = r + A (c + S q) for a 90-degree rotation (sid-spec 5.2 node kinematics).
"""

import csv
import xml.etree.ElementTree as ET

import meshio
import numpy as np
import pytest

from sidprep.errors import InputError
from solver.animation import Surface, obj_surface, write_animation
from solver.results import (BodyTrack, Results, energy_summary, plot_signals, read_results, signal,
                            signal_names, write_csv, write_results)

NT = 4
ROT_Z90 = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])


def make_results():
    t = np.linspace(0.0, 0.3, NT)
    rng = np.random.default_rng(1)
    bar = BodyTrack("flexible", rng.normal(size=(NT, 3)), np.tile(ROT_Z90, (NT, 1, 1)), rng.normal(size=(NT, 3)),
                    rng.normal(size=(NT, 3)), rng.normal(size=(NT, 2)), rng.normal(size=(NT, 2)), "bar.sid.h5")
    box = BodyTrack("rigid", np.zeros((NT, 3)), np.tile(np.eye(3), (NT, 1, 1)), np.zeros((NT, 3)), np.zeros((NT, 3)),
                    np.zeros((NT, 0)), np.zeros((NT, 0)), "box.obj")
    kinetic = np.array([0.0, 1.0, 2.0, 3.0])
    return Results(time=t, bodies={"bar": bar, "box": box}, markers={"tip": rng.normal(size=(NT, 3))},
                   joints={"hinge": {"force": rng.normal(size=(NT, 3)), "torque": rng.normal(size=(NT, 3))}},
                   energy={"kinetic": kinetic, "potential": -kinetic + 0.01 * t, "total": 0.01 * t},
                   effects={"included": ["gravity"], "left_out": ["geometric stiffening"], "warnings": []},
                   stats={"steps": 30, "cpu_s": 0.5}, scene={"path": "scene.toml", "sha256": "00", "text": "x = 1"})


def test_hdf5_round_trip_is_exact(tmp_path):
    res = make_results()
    back = read_results(write_results(res, tmp_path / "r.h5"))
    assert np.array_equal(back.time, res.time)
    for name, b in res.bodies.items():
        for qty in ("position", "rotation", "velocity", "angular_velocity", "q", "qd"):
            assert np.array_equal(getattr(back.bodies[name], qty), getattr(b, qty))
        assert back.bodies[name].kind == b.kind and back.bodies[name].source == b.source
    assert np.array_equal(back.markers["tip"], res.markers["tip"])
    assert np.array_equal(back.joints["hinge"]["torque"], res.joints["hinge"]["torque"])
    assert back.effects == res.effects and back.stats == res.stats and back.scene == res.scene
    assert [p.name for p in tmp_path.iterdir()] == ["r.h5"]          # no temporary left behind


def test_energy_summary_scales_by_kinetic_energy_when_total_starts_at_zero():
    s = energy_summary(make_results())
    assert s["initial"] == 0.0 and s["final"] == pytest.approx(0.003)
    assert s["max_rel_drift"] == pytest.approx(0.003 / 3.0)


def test_signals_csv_and_plot(tmp_path):
    res = make_results()
    assert "bar.q.2" in signal_names(res) and "box.q.1" not in signal_names(res)
    values, unit = signal(res, "bar.q.2")
    assert unit == "1" and np.array_equal(values, res.bodies["bar"].q[:, 1])
    names = ["tip.position.z", "hinge.force.y", "energy.total"]
    rows = list(csv.reader(open(write_csv(res, names, tmp_path / "s.csv"))))
    assert rows[0] == ["time [s]", "tip.position.z [m]", "hinge.force.y [N]", "energy.total [J]"]
    assert float(rows[2][1]) == res.markers["tip"][1, 2] and float(rows[3][2]) == res.joints["hinge"]["force"][2, 1]
    png = plot_signals(res, names, tmp_path / "s.png")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    for bad in ("bar.q.3", "bar.spin.x", "nobody.position.x", "energy"):
        with pytest.raises(InputError, match="unknown signal"):
            signal(res, bad)


def test_animation_points_follow_rigid_motion_plus_modes(tmp_path):
    res = make_results()
    c = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    shapes = np.zeros((3, 3, 2))
    shapes[1, 2, 0] = 0.5        # mode 1 lifts point 1 in z
    shapes[2, 0, 1] = 2.0        # mode 2 moves point 2 in x
    obj = tmp_path / "box.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv 0 0 1\nf 1 2 3\n")
    surfaces = {"bar": Surface(c, np.array([[0, 1, 2]]), shapes), "box": obj_surface(obj)}
    pvd = write_animation(res, surfaces, tmp_path / "anim.pvd")
    files = [d.get("file") for d in ET.parse(pvd).getroot().iter("DataSet")]
    assert len(files) == NT
    i = 2
    mesh = meshio.read(tmp_path / files[i])
    b = res.bodies["bar"]
    q = b.q[i]
    local = c + np.array([[0, 0, 0], [0, 0, 0.5 * q[0]], [2.0 * q[1], 0, 0]])
    expected_bar = b.position[i] + local @ ROT_Z90.T
    assert np.allclose(mesh.points[:3], expected_bar, rtol=0, atol=1e-12)
    assert np.allclose(mesh.point_data["displacement"][:3], (local - c) @ ROT_Z90.T, atol=1e-12)
    assert np.allclose(mesh.points[3:], [[0, 0, 0], [1, 0, 0], [0, 0, 1]], atol=1e-12)   # box at rest
    assert np.concatenate(mesh.cell_data["body"]).tolist() == [0, 1]
