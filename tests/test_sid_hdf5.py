"""SID HDF5 schema: exact round trip of every array, units, provenance, bad files; OBJ export.

References: bit-equality of what was written (HDF5 stores float64 exactly), the schema attributes
of docs/sid-hdf5.md, and trimesh reading the OBJ back (independent parser, closed-box volume).
"""

from dataclasses import replace

import h5py
import numpy as np
import pytest
import trimesh

from sidprep.errors import InputError
from sidprep.sid.io import read_sid
from sidprep.sid.io.obj import write_obj
from sidprep.sid.io.sid_hdf5 import read_checks, read_sid_hdf5, write_sid_hdf5
from sidprep.sid.model import SurfaceModes

from test_sid_fem import MEMBERS, real, random_sid


def assert_same_sid(a, b):
    assert a.mass == b.mass and a.labels == b.labels and a.mode_kinds == b.mode_kinds
    assert a.units == b.units and a.metadata == b.metadata
    assert np.array_equal(a.frequencies_hz, b.frequencies_hz, equal_nan=True)
    pairs = [(getattr(a, m), getattr(b, m)) for m in MEMBERS]
    assert len(a.nodes) == len(b.nodes)
    for na, nb in zip(a.nodes, b.nodes):
        assert (na.node_id, na.name) == (nb.node_id, nb.name)
        pairs += [(getattr(na, m), getattr(nb, m)) for m in ("origin", "phi", "psi", "AP")]
        assert (na.sigma is None) == (nb.sigma is None)
    for ta, tb in pairs:
        assert ta.structure == tb.structure
        assert np.array_equal(ta.M0, tb.M0)
        assert (ta.M1 is None and tb.M1 is None) or np.array_equal(ta.M1, tb.M1)
    assert set(a.stiffening) == set(b.stiffening)
    for key in a.stiffening:
        assert np.array_equal(a.stiffening[key], b.stiffening[key])
    assert (a.surface is None) == (b.surface is None)
    if a.surface is not None:
        for name in ("points", "triangles", "shapes", "node_ids"):
            assert np.array_equal(getattr(a.surface, name), getattr(b.surface, name))


def with_surface(sid):
    box = trimesh.creation.box(extents=(0.2, 0.1, 0.05))
    rng = np.random.default_rng(7)
    surface = SurfaceModes(box.vertices, box.faces.astype(np.int64),
                           rng.normal(size=(len(box.vertices), 3, sid.nq)),
                           np.arange(len(box.vertices), dtype=np.int64) + 100)
    meta = {"input": {"file": "rod.msh", "sha256": "ab" * 32}, "options": {"modes": 3, "fmax": None},
            "checks": {"mass vs FE": {"value": 1e-14, "tolerance": 1e-12, "passed": True}}}
    return replace(sid, surface=surface, metadata=meta)


def test_round_trip_is_exact_with_stiffening_and_surface(tmp_path):
    sid = with_surface(random_sid(stiffening=True))
    path = write_sid_hdf5(sid, tmp_path / "body.sid.h5")
    assert_same_sid(sid, read_sid_hdf5(path))
    assert_same_sid(sid, read_sid(path))
    assert not list(tmp_path.glob(".*part"))              # atomic: no temporary left


@pytest.mark.parametrize("name", ["Beam_3m", "balken1m"])
def test_other_real_files_round_trip(tmp_path, name):
    sid = real(name)
    assert_same_sid(sid, read_sid_hdf5(write_sid_hdf5(sid, tmp_path / "b.sid.h5")))


def test_real_file_round_trip_and_schema(tmp_path):
    sid = real("cartopPragV32")
    path = write_sid_hdf5(sid, tmp_path / "cartop.sid.h5")
    assert_same_sid(sid, read_sid_hdf5(path))
    with h5py.File(path) as f:
        assert f.attrs["format"] == "sidprep-sid" and f.attrs["version"] == 2
        assert f["units"].attrs["length"] == "m" and f["modal/J"].attrs["unit"] == "kg m^2"
        assert f["modal/J"].attrs["component_order"] == "xx,yy,zz,xy,xz,yz"
        assert f["modal/Oe"].attrs["omega_hat_order"] == "xx,yy,zz,xy,yz,xz"
        G0 = f["modal/Gr/G0"][()]
        assert G0.shape == (3, 3, 3) and f["modal/Ge/Ge"].shape == (3, 3, 3)
        # canonical Gr: sym(G0_k) = I1_k (sid-spec 3.4), independent of any column layout
        j1 = f["modal/J/M1"][:, 0, 0]
        assert np.isclose(G0[0, 0, 0], j1[0], rtol=1e-10) and np.isclose(G0[0, 1, 1], j1[1], rtol=1e-10)
        assert "numpy" in f["provenance"].attrs["libraries"]
    checks = read_checks(path)
    assert checks["origin.M1 = phi.M0"].passed


def test_bad_files(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        read_sid(tmp_path / "missing.sid.h5")
    with pytest.raises(InputError, match="unknown SID file type"):
        read_sid(tmp_path / "body.txt")
    junk = tmp_path / "junk.sid.h5"
    junk.write_text("not hdf5")
    with pytest.raises(InputError, match="not a readable HDF5"):
        read_sid_hdf5(junk)
    other = tmp_path / "other.sid.h5"
    with h5py.File(other, "w") as f:
        f.attrs["format"] = "something"
    with pytest.raises(InputError, match="not a sidprep SID"):
        read_sid_hdf5(other)
    future = write_sid_hdf5(random_sid(), tmp_path / "future.sid.h5")
    with h5py.File(future, "a") as f:
        f.attrs["version"] = 99
    with pytest.raises(InputError, match="version 99"):
        read_sid_hdf5(future)


def test_failed_write_leaves_no_file(tmp_path):
    sid = replace(random_sid(), metadata={"bad": object()})
    with pytest.raises(TypeError):
        write_sid_hdf5(sid, tmp_path / "x.sid.h5")
    assert list(tmp_path.iterdir()) == []


def test_obj_export_reads_back(tmp_path):
    box = trimesh.creation.box(extents=(1.0, 2.0, 3.0))
    path = write_obj(tmp_path / "body.obj", box.vertices, box.faces)
    text = path.read_text()
    assert text.startswith("# sidprep surface, body frame K, units: m")
    mesh = trimesh.load(path, process=False)
    assert np.array_equal(mesh.faces, box.faces)
    assert np.allclose(mesh.vertices, box.vertices, rtol=0, atol=1e-12)
    assert mesh.is_watertight and mesh.volume == pytest.approx(6.0, rel=1e-12)
    with pytest.raises(InputError, match="outside"):
        write_obj(tmp_path / "bad.obj", box.vertices, box.faces + 100)
