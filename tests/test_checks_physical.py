"""`sidprep check` tests physical possibility of any SID.

Reference: a lumped-mass body whose inertia about its CM is computed here in closed form
(sum m_i (|r_i|^2 E - r_i r_i^T)), and the third-party SID_FEM files, which must stay valid.
"""

import re
import subprocess
import sys

import numpy as np
import pytest

from sidprep.sid.checks import INERTIA_CHECK, failed_checks, inertia_about_cm, physical_checks, sid_checks
from sidprep.errors import InputError
from sidprep.sid.io.sid_fem import format_sid_fem, parse_sid_fem, read_sid_fem, write_sid_fem
from sidprep.sid.model import sid_invariants

from test_sid_fem import REF as REFERENCE, ROOT, omit_zeros, without_largest_line


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
    assert INERTIA_CHECK in run.stdout


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


# ------------------------------------------------------------------------------------------------
# deleted lines refused by the reader where the writer writes zeros, found by
# `check` through the identities where it omits them
# ------------------------------------------------------------------------------------------------

BAR = ROOT / "data" / "meshes" / "bar.msh"
THIRD_PARTY = ["cartopPragV32", "Beam_3m", "balken1m"]

#: (member, entry kind) whose largest line deleted from a file that omits zeros fails the check named
DETECTED_IN_ZERO_OMITTING_FILES = [
    ("J", "m0", INERTIA_CHECK),         # Jxx, Jyy or Jzz
    ("origin", "m1", "origin.M1 = phi.M0"),
    ("phi", "m0", "origin.M1 = phi.M0"),
    ("psi", "m0", "AP.M1 = skew(psi) AP0"),
    ("AP", "m0", "node orientations AP0 are rotations"),
    ("AP", "m1", "AP.M1 = skew(psi) AP0"),
    ("mdCM", "m1", "mdCM.M1 = Ct.M0^T"),
    ("Ct", "m0", "mdCM.M1 = Ct.M0^T"),
    ("J", "m1", "no zeroed entry: J.M1 vs Oe0"),
    ("Oe", "m0", "no zeroed entry: J.M1 vs Oe0"),
    ("Gr", "m0", "no zeroed entry: Gr0 vs 2 J.M1 - Gr0^T"),
    ("Ke", "m0", "labels: f = sqrt(Ke/Me)/2pi"),
]
#: deletions no check can see in a file that omits zeros: a node's position (stored nowhere else)
#: and the damping De (no identity involves it), in every such file
UNDETECTABLE_IN_ZERO_OMITTING_FILES = [("origin", "m0"), ("De", "m0")]
#: ... and in the third-party files also Cr0 (their Gr0 - Gr0^T is not -2 skew(Cr0): nodal rotary
#: inertia, so Cr0 has no twin) and Oe.M1 (Kom + K0omega, non-symmetric in PY_SID: no twin)
UNDETECTABLE_IN_THIRD_PARTY_FILES = [("Cr", "m0"), ("Oe", "m1")]


@pytest.fixture(scope="module")
def bar_text(tmp_path_factory):
    """The SID_FEM text sidprep writes for the bundled bar (free-free, 3 modes + FRMs)."""
    import sidprep

    result = sidprep.reduce_model(BAR, sidprep.ReduceOptions(modes=3, check_frequencies=False))
    return write_sid_fem(result.sid, tmp_path_factory.mktemp("bar") / "bar.SID_FEM").read_text()


def source_text(source, bar_text):
    """The text of a file that omits zeros: a third-party file, or the bar's without its zeros."""
    if source == "sidprep bar, zeros omitted":
        return omit_zeros(bar_text)
    path = REFERENCE / f"{source}.SID_FEM"
    if not path.exists():
        pytest.skip(f"needs the third-party file {path.name} (licensed, ../shared/reference/sid_fem)")
    return path.read_text(encoding="latin-1")


def failures_after_deleting(text, block, kind):
    """Failed checks after deleting the largest ``kind`` line of ``block``; None if it has none."""
    bad = without_largest_line(text, block, kind)
    return None if bad is None else failed_checks(sid_checks(parse_sid_fem(bad, "damaged.SID_FEM")))


@pytest.mark.parametrize("block,kind", [("J", "m0(2,1)"), ("origin", "m0(1,1)"), ("origin", "m1"),
                                        ("Ke", "m0"), ("phi", "m0"), ("AP", "m1"), ("Oe", "m1")])
def test_deleted_line_of_a_sidprep_file_is_refused(bar_text, block, kind):
    """Jyy, a node's x (0 for the bar's end nodes: written as 0), its m1, Ke, phi: all refused."""
    lines = bar_text.splitlines(keepends=True)
    inside = False
    for k, line in enumerate(lines):
        inside = (inside or line.split() == [block]) and line.split() != ["end", block]
        if inside and line.replace(" ", "").startswith(kind.replace(" ", "")):
            break
    else:
        pytest.fail(f"no {kind} line in {block}")
    if (block, kind) == ("origin", "m0(1,1)"):
        assert float(lines[k].rpartition("=")[2].replace("D", "E")) == 0.0      # a written zero
    with pytest.raises(InputError) as err:
        parse_sid_fem("".join(lines[:k] + lines[k + 1:]), "bar.SID_FEM")
    assert re.match(rf"bar\.SID_FEM:\d+-\d+: (node \d+ )?{block} lacks 1 of its \d+ entries", str(err.value))
    assert str(err.value).endswith("re-export it")


def test_cli_exit_2_on_a_damaged_sidprep_file(bar_text, tmp_path):
    bad = tmp_path / "bad.SID_FEM"
    bad.write_text(without_largest_line(bar_text, "origin", "m1"))
    run = _cli_check(bad)
    assert run.returncode == 2 and run.stdout == ""
    assert run.stderr.count("\n") == 1 and "origin lacks 1 of its" in run.stderr and "re-export it" in run.stderr


SOURCES = ["sidprep bar, zeros omitted"] + THIRD_PARTY


@pytest.mark.parametrize("source", SOURCES)
def test_untouched_files_pass_every_check(bar_text, source):
    text = source_text(source, bar_text)
    checks = sid_checks(parse_sid_fem(text, "x.SID_FEM"))
    assert failed_checks(checks) == []
    assert checks["SID_FEM entries not written"].value > 0
    assert failed_checks(sid_checks(parse_sid_fem(bar_text, "bar.SID_FEM"))) == []


@pytest.mark.parametrize("source", SOURCES)
@pytest.mark.parametrize("block,kind,check", DETECTED_IN_ZERO_OMITTING_FILES)
def test_deleted_line_of_a_zero_omitting_file_fails_check(bar_text, source, block, kind, check):
    failed = failures_after_deleting(source_text(source, bar_text), block, kind)
    assert failed is not None and check in failed


@pytest.mark.parametrize("source", SOURCES)
def test_deletions_that_stay_undetectable(bar_text, source):
    """The limits, stated: these deletions pass every check (when the member has such a line)."""
    text = source_text(source, bar_text)
    blind = UNDETECTABLE_IN_ZERO_OMITTING_FILES + (UNDETECTABLE_IN_THIRD_PARTY_FILES
                                                   if source in THIRD_PARTY else [])
    for block, kind in blind:
        assert failures_after_deleting(text, block, kind) in (None, []), (block, kind)


def test_cr_deletion_shows_where_gr_carries_cr():
    """Without nodal rotary inertia Cr0 = axial(Gr0)/2 (4.8 #5), so a deleted Cr0 line shows
    (the bar's free-free Cr0 is round-off, hence the lumped body with its Cr0 of order 1)."""
    text = omit_zeros(format_sid_fem(lumped_body()[0]))
    assert "no zeroed entry: Cr0 vs axial(Gr0)/2" in failures_after_deleting(text, "Cr", "m0")


def test_label_frequencies_against_generalized_eigenvalues():
    """Eigen-labelled coordinates whose Me, Ke are not diagonal (a rotated eigenbasis): the labels
    are the generalized eigenfrequencies of (Ke, Me); zeroing Ke's coupling entry changes them."""
    from dataclasses import replace

    from sidprep.sid.checks import modal_checks
    from sidprep.sid.model import SYMMETRIC, Taylor

    w = 2 * np.pi * np.array([3.0, 7.0])                     # rad/s
    c, s = np.cos(0.4), np.sin(0.4)
    R = np.array([[c, -s], [s, c]])
    Me = np.diag([2.0, 0.5])                                  # kg
    root = np.diag(np.sqrt(np.diag(Me)))
    Ke = root @ R.T @ np.diag(w ** 2) @ R @ root              # eigenvalues of (Ke, Me): w^2
    sid = replace(lumped_body()[0], Me=Taylor(Me, None, SYMMETRIC), Ke=Taylor(Ke, None, SYMMETRIC),
                  frequencies_hz=w / (2 * np.pi), mode_kinds=("eigen", "eigen"))
    name = "labels: f = sqrt(Ke/Me)/2pi"
    checks = modal_checks(sid)
    assert not checks["Me, Ke diagonal for eigen modes"].passed and checks[name].value < 1e-14
    uncoupled = Taylor(np.diag(np.diag(Ke)), None, SYMMETRIC)   # the off-diagonal lines deleted
    assert name in failed_checks(modal_checks(replace(sid, Ke=uncoupled)))


def line_body(points):
    """Lumped masses 1, 2, 1 kg at ``points`` (3, 3) m, two random modes, Ke = diag(1e6, 4e6)."""
    rng = np.random.default_rng(2)
    Phi = rng.normal(size=(9, 2))
    nodes = [(1, points[0], Phi[:3], rng.normal(size=(3, 2)))]
    return sid_invariants(points, np.diag([1.0, 2.0, 1.0]), Phi, nodes, Ke=np.diag([1e6, 4e6]))


def test_a_line_body_passes_check_and_the_solver_alike():
    """Issue 22 item 6: one rule for `sidprep check` and the solver (checks.inertia_defects):
    principal moments about the CM >= 0 with the triangle inequality, so one zero moment only
    for a line body.  Masses on the x axis (moments 0, 1, 1 kg m^2 about the CM): check passes,
    FlexibleBody accepts it and a hinge about y swings it; masses at one point and a negative
    Jyy fail both."""
    from dataclasses import replace

    from sidprep.sid.checks import INERTIA_CHECK, inertia_defects, physical_problems
    from sidprep.solver import FlexibleBody, Revolute, System, simulate

    line = line_body(np.array([[0.0, 0, 0], [0.5, 0, 0], [1.0, 0, 0]]))
    p, negative, triangle = inertia_defects(line)
    np.testing.assert_allclose(p, [0.0, 0.5, 0.5], atol=1e-12)          # sum m x^2 about the CM
    assert negative == 0.0 and triangle == 0.0
    assert not failed_checks(sid_checks(line)) and physical_problems(line) == []
    s = System(gravity=(0.0, 0.0, -9.81))
    bar = s.add(FlexibleBody(line, name="line"))
    y_axis = np.array([[0.0, 1, 0], [0, 0, 1], [1, 0, 0]])              # marker z along y
    s.add(Revolute(s.ground.marker(rotation=y_axis), bar.node_marker(0, rotation=y_axis)))
    r = simulate(s, 0.2, h=1e-3)
    assert r.t[-1] == pytest.approx(0.2) and np.all(np.isfinite(r.bodies["line"].q))

    point = line_body(np.zeros((3, 3)))
    j = line.J.M0.copy()
    j[1, 0] = -j[1, 0]
    for bad in (point, replace(line, J=replace(line.J, M0=j))):
        assert INERTIA_CHECK in failed_checks(sid_checks(bad))
        assert "not positive definite" in physical_problems(bad)[0]
