"""``sidprep info`` and ``sidprep check`` on real and computed SID files; exit codes.

References: the real cartop file's own numbers (mass 9.0824 kg, 3 modes) and the parallel-axis
theorem (inertia about the CM from the inertia about the origin, checked by recomputing I_O).
"""

import json
import re
from dataclasses import replace

import numpy as np
import pytest

from sidprep.cli.main import main
from sidprep.sid.io.sid_fem import write_sid_fem
from sidprep.sid.io.sid_hdf5 import write_sid_hdf5
from sidprep.sid.model import Taylor

from test_sid_fem import REF, random_sid

CARTOP = REF / "cartopPragV32.SID_FEM"


def run(capsys, *argv):
    code = main(list(map(str, argv)))
    out, err = capsys.readouterr()
    return code, out, err


def test_info_json_of_real_file(capsys):
    if not CARTOP.exists():
        pytest.skip("needs the third-party file cartopPragV32.SID_FEM (licensed, ../shared/reference/sid_fem)")
    code, out, _ = run(capsys, "info", CARTOP, "--json")
    assert code == 0
    info = json.loads(out)
    assert info["mass_kg"] == 9.0824 and info["n_modes"] == 3
    assert info["frequencies_hz"] == [1.135, 2.557, 2.922]
    assert info["mode_kinds"] == ["eigen"] * 3
    assert [n["id"] for n in info["nodes"]][:3] == [1, 2, 12]
    assert info["nodes"][1]["position"] == [1.0, 0.0, 0.0]
    assert info["units"] == "SI" and info["sid_fem_dialect"]["name"] == "native"
    m, c = info["mass_kg"], np.array(info["center_of_mass"])
    I_cm = np.array(info["inertia"]["about_center_of_mass"])
    I_o = np.array(info["inertia"]["about_origin"])
    assert np.allclose(I_cm + m * (c @ c * np.eye(3) - np.outer(c, c)), I_o, rtol=1e-12, atol=0)
    assert all({"value", "tolerance", "passed"} <= set(v) for v in info["checks"].values())
    note = info["checks"]["SID_FEM entries not written"]      # the file omits zeros: a note, no failure
    assert note["severity"] == "info" and note["value"] > 0 and "omits zeros" in note["description"]


def test_info_table_and_check_pass(tmp_path, capsys):
    path = write_sid_hdf5(random_sid(), tmp_path / "body.sid.h5")
    code, out, _ = run(capsys, "info", path)
    assert code == 0 and "centre of mass" in out and "checks:" in out
    code, out, _ = run(capsys, "check", path)
    lines = out.splitlines()
    ok, info = sum(line.startswith("  ok ") for line in lines), sum(line.startswith("  info ") for line in lines)
    summary = f"all {ok} checks passed" + (f" ({info} info line{'s' * (info != 1)})" if info else "")
    assert code == 0 and lines[-1] == f"{path}: {summary}"       # the count is the count of the lines
    code, out, _ = run(capsys, "check", write_sid_fem(random_sid(), tmp_path / "body.SID_FEM"))
    assert code == 0 and re.search(r"info SID_FEM entries not written +0 ", out)


def test_check_fails_on_inconsistent_sid(tmp_path, capsys):
    sid = random_sid()
    node = sid.nodes[0]
    broken = replace(node, AP=Taylor(node.AP.M0, -node.AP.M1, node.AP.structure))
    bad = replace(sid, nodes=(broken,) + sid.nodes[1:])
    code, out, _ = run(capsys, "check", write_sid_hdf5(bad, tmp_path / "bad.sid.h5"))
    assert code == 1 and "AP.M1 = skew(psi) AP0" in out and "FAIL" in out


REPORT = {"mass_rel_error": 1e-16, "zero_energy_modes": 6, "zero_energy_modes_expected": 0,
          "static_deflection_rel_error_by_interface": {"end": 0.003}}


@pytest.mark.parametrize("checks,name", [
    ({"mass vs FE": {"value": 0.1, "tolerance": 1e-9, "passed": False}}, "mass vs FE"),
    ({**REPORT, "passed": False}, "FE comparison"),          # the flat report of sidprep reduce
])
def test_check_fails_on_failed_fe_comparison(tmp_path, capsys, checks, name):
    sid = replace(random_sid(), metadata={"checks": checks})
    code, out, _ = run(capsys, "check", write_sid_hdf5(sid, tmp_path / "fe.sid.h5"))
    assert code == 1 and f"FAIL {name}" in out
    sid = replace(random_sid(), metadata={"checks": {**REPORT, "passed": True}})
    code, out, _ = run(capsys, "check", write_sid_hdf5(sid, tmp_path / "ok.sid.h5"))
    assert code == 0 and "info FE mass_rel_error" in out


@pytest.mark.parametrize("name", ["missing.sid.h5", "missing.SID_FEM", "body.xyz"])
def test_missing_or_unknown_file_is_one_line_error(tmp_path, capsys, name):
    for command in ("info", "check"):
        code, out, err = run(capsys, command, tmp_path / name)
        assert code == 2 and out == ""
        assert err.count("\n") == 1 and err.startswith("sidprep: error: ")


def test_free_body_checks():
    """Modes made M-orthogonal to the rigid-body fields St, Sr (spec 4.3) pass; raw random ones fail."""
    from sidprep.sid.checks import sid_checks
    from sidprep.sid.model import sid_invariants, skew

    rng = np.random.default_rng(3)
    n, nq = 8, 3
    X = rng.normal(size=(n, 3))
    A = rng.normal(size=(n, n))
    Ms = A @ A.T / n + np.eye(n)
    M = np.kron(Ms, np.eye(3))
    R = np.hstack([np.tile(np.eye(3), (n, 1)), np.vstack([-skew(x) for x in X])])
    Phi = rng.normal(size=(3 * n, nq))
    free_phi = Phi - R @ np.linalg.solve(R.T @ M @ R, R.T @ M @ Phi)
    meta = {"free_body": True, "n_rigid_modes": 6}
    good = sid_checks(sid_invariants(X, Ms, free_phi, [], Ke=np.eye(nq), metadata=meta))
    raw = sid_checks(sid_invariants(X, Ms, Phi, [], Ke=np.eye(nq), metadata=meta))
    name = "free modes orthogonal to rigid motion"
    assert good[name].passed and good["6 zero-energy modes"].passed
    assert not raw[name].passed
    five = sid_checks(sid_invariants(X, Ms, free_phi, [], Ke=np.eye(nq),
                                     metadata={"free_body": True, "n_rigid_modes": 5}))
    assert not five["6 zero-energy modes"].passed


def test_sid_fem_keeps_the_kind_of_every_mode(tmp_path, capsys):
    """A reduction with frequency-response modes: `info` of the .SID_FEM labels them as the
    .sid.h5 does (all 20 were "eigen")."""
    from pathlib import Path

    from sidprep.sid.io import read_sid

    mesh = Path(__file__).resolve().parents[1] / "data/meshes/bar.msh"
    assert main(["reduce", str(mesh), "-o", str(tmp_path / "bar.sid.h5"), "--modes", "4", "--no-obj", "-q"]) == 0
    capsys.readouterr()
    h5, fem = read_sid(tmp_path / "bar.sid.h5"), read_sid(tmp_path / "bar.SID_FEM")
    assert "frm" in h5.mode_kinds and fem.mode_kinds == h5.mode_kinds
    code, out, _ = run(capsys, "info", tmp_path / "bar.SID_FEM", "--json")
    assert code == 0 and json.loads(out)["mode_kinds"] == list(h5.mode_kinds)
