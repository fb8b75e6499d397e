"""`sidprep check` tests physical possibility of any SID (issue 14 item 2).

Reference: a lumped-mass body whose inertia about its CM is computed here in closed form
(sum m_i (|r_i|^2 E - r_i r_i^T)), and the third-party SID_FEM files, which must stay valid.
"""

import subprocess
import sys

import numpy as np
import pytest

from sidprep.checks import failed_checks, inertia_about_cm, physical_checks, sid_checks
from sidprep.errors import InputError
from sidprep.io.sid_fem import read_sid_fem, write_sid_fem
from sidprep.sid import sid_invariants

from test_sid_fem import REF as REFERENCE, ROOT


def lumped_body(seed=1, n=8, nq=2):
    """Lumped masses (kg) at random points (m), random mode shapes, Ke = diag(1..9)."""
    rng = np.random.default_rng(seed)
    X = rng.normal(size=(n, 3))
    m = rng.uniform(0.5, 2.0, n)
    Ms = np.diag(m)
    Phi = rng.normal(size=(3 * n, nq))
    nodes = [(1, X[0], Phi.reshape(n, 3, nq)[0], rng.normal(size=(3, nq)))]
    return sid_invariants(X, Ms, Phi, nodes, Ke=np.diag(rng.uniform(1, 9, nq)),
                          De=0.01 * np.eye(nq)), X, m


def test_inertia_about_cm_matches_closed_form():
    sid, X, m = lumped_body()
    r = X - (m @ X) / m.sum()
    closed = sum(mi * (ri @ ri * np.eye(3) - np.outer(ri, ri)) for mi, ri in zip(m, r))
    assert np.allclose(inertia_about_cm(sid), closed, rtol=1e-12, atol=1e-12)
    assert not failed_checks(physical_checks(sid))


def _cli_check(path):
    return subprocess.run([sys.executable, "-m", "sidprep.cli.main", "check", str(path)], cwd=ROOT,
                          capture_output=True, text=True)


def test_negative_jyy_fails_check_with_exit_1(tmp_path):
    sid, _, _ = lumped_body()
    good = write_sid_fem(sid, tmp_path / "good.SID_FEM")
    assert _cli_check(good).returncode == 0
    text = good.read_text().splitlines()
    # J is stored about the frame origin as [Ixx, Iyy, Izz, Ixy, Ixz, Iyz]: make Jyy negative
    in_j = False
    for k, line in enumerate(text):
        in_j = in_j or line.strip() == "J"
        if in_j and line.strip().startswith("m0( 2, 1)"):
            key, value = line.split("=")
            text[k] = f"{key}= {-abs(float(value.replace('D', 'E'))):.12e}"
            break
    else:
        pytest.fail("no m0( 2, 1) in J")
    bad = tmp_path / "bad.SID_FEM"
    bad.write_text("\n".join(text) + "\n")
    run = _cli_check(bad)
    assert run.returncode == 1, run.stdout + run.stderr
    assert "inertia about CM positive definite" in run.stdout


def test_deleted_jyy_line_fails_read(tmp_path):
    sid, _, _ = lumped_body()
    lines = write_sid_fem(sid, tmp_path / "good.SID_FEM").read_text().splitlines()
    start = lines.index(next(l for l in lines if l.strip() == "J"))
    k = next(i for i in range(start, len(lines)) if lines[i].strip().startswith("m0( 2, 1)"))
    (tmp_path / "bad.SID_FEM").write_text("\n".join(lines[:k] + lines[k + 1:]) + "\n")
    with pytest.raises(InputError, match=r"J lacks 1 of its \d+ entries \(first m0\(2,1\)\)"):
        read_sid_fem(tmp_path / "bad.SID_FEM")


def test_negative_stiffness_fails():
    sid, _, _ = lumped_body()
    sid.Ke.M0[0, 0] = -sid.Ke.M0[0, 0]
    assert "Ke positive semidefinite" in failed_checks(physical_checks(sid))


@pytest.mark.skipif(not REFERENCE.is_dir(), reason="third-party SID_FEM files (licensed) are in "
                    "../shared/reference/sid_fem, not in the repository")
@pytest.mark.parametrize("name", ["Beam_3m", "balken1m", "cartopPragV32"])
def test_real_files_are_physical(name):
    sid = read_sid_fem(REFERENCE / f"{name}.SID_FEM")
    assert not failed_checks(physical_checks(sid))
