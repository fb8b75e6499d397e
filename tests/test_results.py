"""Results files (HDF5 round trip, CSV, PNG) and the ParaView animation export.

References: the written arrays themselves (round trip must be bit-exact), and hand-computed
deformed surface points x = r + A (c + S q) for a 90-degree rotation (sid-spec 5.2 node kinematics).
"""

import csv
import json
from dataclasses import replace
import xml.etree.ElementTree as ET

import h5py
import meshio
import numpy as np
import pytest

from sidprep.errors import InputError
from sidprep.sid.io.obj import read_obj
from sidprep.sid.surface import Surface, rigid_surface
from sidprep.solver.animation import write_animation
from sidprep.solver.effects import EffectEntry, EffectsReport
from sidprep.solver.energy import balance_beyond
from sidprep.solver.results import BodySource, energy_summary, plot_signals, read_results, signal, signal_names, write_csv, write_results
from sidprep.solver.statistics import FLOATING_FRAME_STATISTICS, RunStatistics
from sidprep.solver import BodyHistory, JointHistory, Result

NT = 4
ROT_Z90 = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])


def make_result():
    t = np.linspace(0.0, 0.3, NT)
    rng = np.random.default_rng(1)

    def body(name, nq, rot):
        return BodyHistory(name, rng.normal(size=(NT, 3)), np.tile(rot, (NT, 1, 1)), rng.normal(size=(NT, 3)),
                           rng.normal(size=(NT, 3)), rng.normal(size=(NT, nq)), rng.normal(size=(NT, nq)),
                           rng.normal(size=(NT, 6 + nq)))

    hinge = JointHistory("hinge", "revolute", *(rng.normal(size=(NT, 3)) for _ in range(4)),
                         *(rng.normal(size=NT) for _ in range(3)))
    kinetic = np.array([0.0, 1.0, 2.0, 3.0])
    effects = EffectsReport({"bar": (EffectEntry("gravity", True, True, "gravity is set"),
                                     EffectEntry("coriolis", False, True, "named", 0.5, "max |Ge(w) qd| / max |Ke q|"))},
                            notes=("a note",))
    return Result(t=t, bodies={"bar": body("bar", 2, ROT_Z90), "box": body("box", 0, np.eye(3))},
                  joints={"hinge": hinge}, markers={"tip": rng.normal(size=(NT, 3))},
                  energy={"kinetic": kinetic, "gravity": -kinetic + 0.01 * t, "total": 0.01 * t},
                  constraint_error=np.full(NT, 1e-12), effects=effects,
                  stats=RunStatistics(method="genalpha", cpu_time=0.5, steps=30, rejected=0,
                                      dropped_constraint_rows=("hinge row 5",)))


def test_hdf5_round_trip_is_exact(tmp_path):
    res = make_result()
    scene = {"path": "scene.toml", "sha256": "00", "text": "x = 1"}
    kinds = {"bar": BodySource("flexible", "bar.sid.h5"), "box": BodySource("rigid", "box.obj")}
    back = read_results(write_results(res, tmp_path / "r.h5", scene=scene, bodies=kinds))
    r = back.result
    assert np.array_equal(r.t, res.t) and np.array_equal(r.constraint_error, res.constraint_error)
    for name, b in res.bodies.items():
        for qty in ("position", "rotation", "velocity", "omega", "q", "qd", "acceleration"):
            assert np.array_equal(getattr(r.bodies[name], qty), getattr(b, qty))
    for qty in ("force", "torque", "force_local", "torque_local", "coordinate", "rate", "effort"):
        assert np.array_equal(getattr(r.joints["hinge"], qty), getattr(res.joints["hinge"], qty))
    assert np.array_equal(r.markers["tip"], res.markers["tip"])
    assert r.effects.text() == res.effects.text() and r.effects.warnings == res.effects.warnings
    assert r.stats == res.stats and back.scene == scene and back.bodies == kinds
    assert [p.name for p in tmp_path.iterdir()] == ["r.h5"]          # no temporary left behind
    with pytest.raises(InputError, match="no such results file"):
        read_results(tmp_path / "missing.h5")


def test_statistics_of_a_file_written_as_a_dict_read_into_the_record(tmp_path):
    """/stats holds the record's dict (its keys in file order); a file whose /stats is the plain dict an
    older writer stored, with a key this version does not know, reads into the same record."""
    path = write_results(make_result(), tmp_path / "r.h5")
    with h5py.File(path, "r") as f:
        written = json.loads(f["stats"].attrs["json"])
    assert list(written) == list(FLOATING_FRAME_STATISTICS) and written["dropped_constraint_rows"] == ["hinge row 5"]
    with h5py.File(path, "r+") as f:
        f["stats"].attrs["json"] = json.dumps({"steps": 30, "rejected": 0, "method": "genalpha", "cpu_time": 0.5,
                                               "dropped_constraint_rows": ["hinge row 5"], "retired_counter": 7,
                                               "energy_balance": {"balance_error": 1e-4, "exchanged": 2.0,
                                                                  "change": -2e-4, "tolerance": 1e-3}})
    stats = read_results(path).result.stats
    assert replace(stats, energy_balance=None) == make_result().stats
    balance = stats.energy_balance                 # books without excursion, worst and floor
    assert (balance.balance_error, balance.exchanged, balance.tolerance, balance.warning) == (1e-4, 2.0, 1e-3, None)
    assert balance_beyond(balance, 0.5e-4) and not balance_beyond(balance, 1e-3)


def test_energy_summary_scales_by_the_largest_energy_range_when_total_starts_at_zero():
    s = energy_summary(make_result())            # kinetic 0 .. 3 J, gravity -0 .. -2.997 J, total 0 .. 0.003 J
    assert s["initial"] == 0.0 and s["final"] == pytest.approx(0.003)
    assert s["max_rel_drift"] == pytest.approx(0.003 / 3.0)


def test_signals_csv_and_plot(tmp_path):
    res = make_result()
    assert "bar.q.2" in signal_names(res) and "box.q.1" not in signal_names(res)
    assert all(signal(res, n)[0].shape == (NT,) for n in signal_names(res))
    values, unit = signal(res, "bar.q.2")
    assert unit == "1" and np.array_equal(values, res.bodies["bar"].q[:, 1])
    names = ["tip.position.z", "hinge.force.y", "hinge.coordinate", "energy.total"]
    rows = list(csv.reader(open(write_csv(res, names, tmp_path / "s.csv"))))
    assert rows[0] == ["time [s]", "tip.position.z [m]", "hinge.force.y [N]", "hinge.coordinate [rad]",
                       "energy.total [J]"]
    assert float(rows[2][1]) == res.markers["tip"][1, 2] and float(rows[3][2]) == res.joints["hinge"].force[2, 1]
    png = plot_signals(res, names, tmp_path / "s.png", title="test")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    for bad in ("bar.q.3", "bar.q.0", "bar.spin.x", "nobody.position.x", "energy", "hinge.force"):
        with pytest.raises(InputError, match="unknown signal"):
            signal(res, bad)


def test_animation_points_follow_rigid_motion_plus_modes(tmp_path):
    res = make_result()
    c = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    shapes = np.zeros((3, 3, 2))
    shapes[1, 2, 0] = 0.5        # mode 1 lifts point 1 in z
    shapes[2, 0, 1] = 2.0        # mode 2 moves point 2 in x
    obj = tmp_path / "box.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv 0 0 1\nf 1 2 3\n")
    surfaces = {"bar": Surface(c, np.array([[0, 1, 2]]), shapes), "box": rigid_surface(*read_obj(obj))}
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
    box_points = np.array([[0, 0, 0], [1, 0, 0], [0, 0, 1.0]])                          # A = E: shifted only
    assert np.allclose(mesh.points[3:], res.bodies["box"].position[i] + box_points, atol=1e-12)
    assert np.concatenate(mesh.cell_data["body"]).tolist() == [0, 1]
