"""SID_FEM reader/writer: the three real files, round trips, dialects, malformed input.

References: the numbers written inside the real files (mass, labels, Ke), the invariant relations
of sid-spec.md 4.8 used for layout detection, and the exact 12-digit round trip.
"""

import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from sidprep.errors import InputError
from sidprep.sid.io.sid_fem import format_sid_fem, parse_sid_fem, read_sid_fem, write_sid_fem
from sidprep.sid.model import SYMMETRIC, Taylor, inertia_matrix, sid_invariants

ROOT = Path(__file__).resolve().parents[1]
#: the third-party files: ../shared/reference/sid_fem beside the checkout (or beside a worktree's folder)
REF = next((p / "shared" / "reference" / "sid_fem" for p in (ROOT.parent, ROOT.parent.parent)
            if (p / "shared" / "reference" / "sid_fem").is_dir()), ROOT.parent / "shared" / "reference" / "sid_fem")
MEMBERS = ("mdCM", "J", "Ct", "Cr", "Me", "Gr", "Ge", "Oe", "ksigma", "Ke", "De")
DIGITS_12 = 5e-12      # relative error of a %19.11E number (12 significant digits)
LABEL_ROUNDING = 1e-3  # labels carry 3 decimals of Hz; FE and reduced frequencies differ slightly

REAL = {  # file: (mass kg, node count, label frequencies Hz, dialect, Gr layout, Ge layout)
    "cartopPragV32": (9.0824, 9, [1.135, 2.557, 2.922], "native", "a-block", "a-block"),
    "Beam_3m": (706.5, 21, [9.089, 27.028, 56.638, 146.316], "PY_SID", "k-block", "a-block"),
    "balken1m": (0.784999999999, 3, [8.360], "native (Gr/Ge layouts coincide for nq < 2)",
                 "a-block", "a-block"),
}


def real(name):
    path = REF / f"{name}.SID_FEM"
    if not path.exists():
        pytest.skip(f"needs the third-party file {path.name} (licensed, ../shared/reference/sid_fem)")
    return read_sid_fem(path)


def taylor_pairs(a, b):
    for name in MEMBERS:
        yield name, getattr(a, name), getattr(b, name)
    for na, nb in zip(a.nodes, b.nodes):
        for member in ("origin", "phi", "psi", "AP"):
            yield f"node {na.node_id} {member}", getattr(na, member), getattr(nb, member)


def max_relative_difference(a, b):
    worst = 0.0
    for name, ta, tb in taylor_pairs(a, b):
        assert (ta.M1 is None) == (tb.M1 is None), name
        for x, y in ((ta.M0, tb.M0), (ta.M1, tb.M1)):
            if x is not None and x.size:
                assert x.shape == y.shape, name
                worst = max(worst, np.max(np.abs(x - y)) / max(np.max(np.abs(x)), 1e-300))
    return worst


@pytest.mark.parametrize("name", list(REAL))
def test_real_files_read(name):
    mass, n_nodes, freqs, dialect, gr, ge = REAL[name]
    sid = real(name)
    assert sid.mass == mass
    assert len(sid.nodes) == n_nodes and sid.nq == len(freqs)
    assert np.array_equal(sid.frequencies_hz, freqs)
    from_ke = np.sqrt(np.diag(sid.Ke.M0)) / (2 * np.pi)
    assert np.allclose(from_ke, freqs, rtol=LABEL_ROUNDING)
    assert np.allclose(sid.Me.M0, np.eye(sid.nq))
    d = sid.metadata["sid_fem_dialect"]
    assert (d["name"], d["Gr_layout"], d["Ge_layout"], d["J"]) == (dialect, gr, ge, "6x1")
    assert sid.mode_kinds == ("eigen",) * sid.nq


def test_cartop_details_and_layout_evidence():
    sid = real("cartopPragV32")
    assert [n.node_id for n in sid.nodes] == [1, 2, 12, 26, 78, 84, 107, 143, 149]
    assert sid.nodes[0].phi.order == 1 and not np.any(sid.nodes[0].phi.M1)  # order 1, no lines
    assert sid.Ke.structure == SYMMETRIC
    res = sid.metadata["sid_fem_dialect"]["Gr_layout_residuals"]
    assert res["a-block"] < 1e-10 < 0.1 < res["k-block"]
    # J about the corner origin: mdCM.M0 = m c_CM, and the inertia is positive definite
    assert np.all(np.linalg.eigvalsh(inertia_matrix(sid.J.M0)) > 0)


@pytest.mark.parametrize("name", list(REAL))
@pytest.mark.parametrize("layout", ["a-block", "k-block"])
def test_real_files_round_trip_exactly(tmp_path, name, layout):
    sid = real(name)
    again = read_sid_fem(write_sid_fem(sid, tmp_path / "x.SID_FEM", layout=layout))
    assert max_relative_difference(sid, again) == 0.0       # 12 digits in, the same 12 out
    assert again.labels == sid.labels and again.mass == sid.mass
    if sid.nq > 1:
        assert again.metadata["sid_fem_dialect"]["Gr_layout"] == layout


def random_sid(seed=0, n=9, nq=3, stiffening=False):
    rng = np.random.default_rng(seed)
    X = rng.normal(size=(n, 3))
    A = rng.normal(size=(n, n))
    Ms = A @ A.T / n + np.eye(n)
    Phi = rng.normal(size=(3 * n, nq))
    Phi3 = Phi.reshape(n, 3, nq)
    nodes = [(10 + i, X[i], Phi3[i], rng.normal(size=(3, nq))) for i in (0, 4)]
    parts = {}
    if stiffening:
        sym = lambda r: (lambda B: B + B.transpose(0, 2, 1))(rng.normal(size=(r, nq, nq)))  # noqa: E731
        parts = {"K0t": sym(3), "K0r": sym(3), "K0omega": sym(6), "K0F/1": sym(3)}
    return sid_invariants(X, Ms, Phi, nodes, Ke=np.diag(rng.uniform(1, 9, nq)),
                          De=0.01 * np.eye(nq), stiffening=parts)


@pytest.mark.parametrize("layout", ["a-block", "k-block"])
def test_computed_sid_round_trip_to_12_digits(tmp_path, layout):
    sid = random_sid(stiffening=True)
    path = write_sid_fem(sid, tmp_path / "body.SID_FEM", layout=layout)
    text = path.read_text()
    assert text.splitlines()[0].startswith("    2    3    :No. nodes, No. modes:")
    assert "Geo_Stiff= yes" in text.splitlines()[0]
    assert re.search(r"m0\( 1, 1\) += ?-?\d\.\d{11}D[-+]\d\d", text)
    again = read_sid_fem(path)
    assert again.metadata["geo_stiff"] and not real("balken1m").metadata["geo_stiff"]
    assert max_relative_difference(sid, again) <= DIGITS_12
    assert again.metadata["sid_fem_dialect"]["Gr_layout"] == layout
    assert again.metadata["sid_fem_dialect"]["Ge_layout"] == layout


def welib_style(sid):
    """Rewrite a file in the welib/FEMBeam dialect: J 3x3, m1(row, col, q), k-block Gr/Ge,
    nq = 0 in order-0 Me/Ge/Ke/De, 'new frame', written zeros (all of ksigma, structure 0),
    Ke lower triangle (structure 2)."""
    nq = sid.nq
    J3 = Taylor(inertia_matrix(sid.J.M0), np.stack([inertia_matrix(sid.J.M1[:, k, 0])
                                                    for k in range(nq)], 1))
    Ke = Taylor(sid.Ke.M0 + 0.1 * (np.ones((nq, nq)) - np.eye(nq)), None, SYMMETRIC)
    text = format_sid_fem(replace(sid, J=J3, Ke=Ke), layout="k-block")
    text = re.sub(r"m1\(\s*(\d+),\s*(\d+),\s*(\d+)\)", r"m1(\1,\3,\2)", text)
    text = text.replace("           frame\n", "           new frame\n")
    for member in ("Me", "Ge", "Ke", "De"):
        text = re.sub(rf"(\n\s+{member}\n(?:.*\n){{3}}\s+nq\s+=)\s+\d+", r"\1    0", text)
    head, ke, tail = re.split(r"(?<=\n)(\s+Ke\n(?:.*\n)*?\s+end Ke\n)", text)
    upper = re.compile(r".*m0\(\s*(\d+),\s*(\d+)\).*\n")
    ke = upper.sub(lambda m: "" if int(m.group(1)) < int(m.group(2)) else m.group(0), ke)
    zeros = "".join(f"                          m0({k + 1:2d}, 1)  = 0.0\n" for k in range(nq))
    text = re.sub(r"(\n\s+ksigma\n(?:.*\n){6})", lambda m: m.group(1) + zeros, head + ke + tail)
    return text, Ke


def test_welib_dialect_is_read(tmp_path):
    sid = random_sid(1)
    text, Ke = welib_style(sid)
    path = tmp_path / "welib.SID_FEM"
    path.write_text(text)
    got = read_sid_fem(path)
    d = got.metadata["sid_fem_dialect"]
    assert (d["name"], d["m1_index_order"], d["J"]) == ("welib/FEMBeam", "row,col,q", "3x3")
    assert (d["Gr_layout"], d["Ge_layout"]) == ("k-block", "k-block")
    assert np.allclose(got.J.M0, sid.J.M0, rtol=DIGITS_12) and np.allclose(got.J.M1, sid.J.M1, rtol=1e-11)
    assert np.allclose(got.Gr.M0, sid.Gr.M0, rtol=1e-11) and np.allclose(got.Ge.M0, sid.Ge.M0, rtol=1e-11)
    assert np.allclose(got.Ke.M0, Ke.M0, rtol=1e-11)            # mirrored upper triangle
    assert np.allclose(got.Cr.M1, sid.Cr.M1, rtol=1e-11)


ENTRY_LINE = re.compile(r"^\s*m[01]\(.*=\s*(\S+)\s*$")


def omit_zeros(text):
    """``text`` as a writer that omits zero entries (the native dialect) would have written it."""
    kept = [line for line in text.splitlines()
            if not ((m := ENTRY_LINE.match(line)) and float(m.group(1).replace("D", "E")) == 0.0)]
    return "\n".join(kept).replace(", all entries written", "") + "\n"


def without_largest_line(text, block, kind):
    """``text`` without the ``kind`` ("m0" / "m1") entry line of largest |value| in the member
    ``block`` (over all nodes for origin, phi, psi, AP); None when the member has no such line."""
    lines = text.splitlines(keepends=True)
    inside, best = False, None
    for k, line in enumerate(lines):
        words = line.split()
        inside = (inside or words == [block]) and words != ["end", block]
        if inside and line.strip().startswith(kind + "("):
            size = abs(float(line.rpartition("=")[2].replace("D", "E")))
            best = max(best or (size, k), (size, k))
    return None if best is None else "".join(lines[:best[1]] + lines[best[1] + 1:])


def test_every_deleted_entry_line_of_a_sidprep_file_is_refused():
    """sidprep writes every entry, zeros included: any one entry line deleted is damage, refused
    with one line naming the block, its lines and the fix."""
    text = format_sid_fem(random_sid(stiffening=True))
    assert "all entries written" in text.splitlines()[0]
    lines = text.splitlines(keepends=True)
    entries = [k for k, line in enumerate(lines) if ENTRY_LINE.match(line)]
    assert len(entries) > 400
    for k in entries:
        with pytest.raises(InputError) as err:
            parse_sid_fem("".join(lines[:k] + lines[k + 1:]), "cut.SID_FEM")
        message = str(err.value)
        assert re.match(r"cut\.SID_FEM:\d+-\d+: (node \d+ )?\w+ lacks 1 of its \d+ entries \(first m[01]\(", message)
        assert message.endswith("the file is truncated or edited; re-export it") and "\n" not in message


def test_a_file_that_omits_zeros_reads_the_same_and_counts_them():
    sid = random_sid(3)
    full, sparse = parse_sid_fem(format_sid_fem(sid)), parse_sid_fem(omit_zeros(format_sid_fem(sid)))
    assert max_relative_difference(full, sparse) == 0.0
    assert full.metadata["sid_fem_entries"]["omitted_entries"] == 0
    entries = sparse.metadata["sid_fem_entries"]
    assert not entries["zeros_written"] and entries["omitted_entries"] > 0
    assert entries["omitted_entries"] + entries["written_entries"] == full.metadata["sid_fem_entries"]["written_entries"]


BLOCK_ERRORS = [  # (substitution on a sidprep file, with or without its zeros; words of the message)
    ((r"(\n(\s+)m0\( 1, 1\)( += .*)\n)", r"\1\2m0( 1, 1)\3\n"), "is written twice"),
    ((r"(\n +ksigma\n(?:.*\n){5}\s+structure\s+=)\s+0\n", r"\1    0\n                          m0( 1, 1) = 1.0D+00\n"),
     "contradicts structure 0 of ksigma"),
    ((r"(\n +Ke\n(?:.*\n){6})", r"\1                          m0( 1, 2) = 1.0D+00\n"),
     "contradicts structure 1 of Ke"),
    ((r"(\n +De\n(?:.*\n){6})", r"\1                          m0( 4, 4) = 1.0D+00\n"), "is outside"),
    ((r"\n +ncol += +1\n", "\n"), "lacks its header line(s) ncol"),
]


@pytest.mark.parametrize("zeros", ["written", "omitted"])
@pytest.mark.parametrize("sub,words", BLOCK_ERRORS)
def test_block_errors_in_both_kinds_of_file(sub, words, zeros):
    text = format_sid_fem(random_sid(4))
    text = text if zeros == "written" else omit_zeros(text)
    bad = re.sub(sub[0], sub[1], text, count=1)
    assert bad != text
    with pytest.raises(InputError, match=re.escape(words)):
        parse_sid_fem(bad, "bad.SID_FEM")


def test_header_lines_other_than_the_size_are_required_where_zeros_are_written():
    """A file that writes its zeros follows the writer rules (all six header lines): a missing one is
    damage; a file that omits zeros may leave out order, nq, nqn, structure (defaults 0, nelastq, 0, 3)."""
    text = format_sid_fem(random_sid(5))
    cut = re.compile(r"\n +nqn += +0\n")
    with pytest.raises(InputError, match=re.escape("lacks its header line(s) nqn")):
        parse_sid_fem(cut.sub("\n", text, count=1), "bad.SID_FEM")
    sparse = omit_zeros(text)
    assert max_relative_difference(parse_sid_fem(cut.sub("\n", sparse)), parse_sid_fem(sparse)) == 0.0


MALFORMED = [  # (substitution on a valid file, expected words in the message)
    ((r"mass +=.*", "mass = 9.0x8"), "not a number"),
    ((r"end Ct\b", "end Cx"), "end Ct"),
    ((r"^    9    3", "   10    3"), "announces 10 nodes"),
    ((r"m0\( 1, 1\)(\s+)= 1\.00000000000D\+00", r"m0( 7, 1)\1= 1.0D+00"), "outside"),
    ((r"\n +Oe\n", "\n           Oops\n"), "unexpected"),
]


@pytest.mark.parametrize("sub,words", MALFORMED)
def test_malformed_file_names_file_and_line(tmp_path, sub, words):
    sid = real("cartopPragV32")
    text = format_sid_fem(sid)
    bad = re.sub(sub[0], sub[1], text, count=1, flags=re.M)
    assert bad != text
    path = tmp_path / "bad.SID_FEM"
    path.write_text(bad)
    with pytest.raises(InputError) as err:
        read_sid_fem(path)
    message = str(err.value)
    assert "\n" not in message and words in message
    assert re.match(rf"{re.escape(str(path))}:\d+: ", message)


def test_truncated_and_missing_files(tmp_path):
    text = format_sid_fem(random_sid(2))
    with pytest.raises(InputError, match="unexpected end of file"):
        parse_sid_fem(text[: text.rindex("\n", 0, len(text) // 2) + 1], "half.SID_FEM")
    with pytest.raises(InputError, match="cannot read"):
        read_sid_fem(tmp_path / "nope.SID_FEM")


def test_rigid_body_sid_without_modes(tmp_path):
    """nq = 0: a rigid body still has mass, CM and inertia; both formats carry it."""
    from sidprep.sid.io.sid_hdf5 import read_sid_hdf5, write_sid_hdf5
    X = np.random.default_rng(4).normal(size=(6, 3))
    sid = sid_invariants(X, np.eye(6), np.zeros((18, 0)), [(1, X[0], np.zeros((3, 0)))],
                         Ke=np.zeros((0, 0)))
    for again in (read_sid_fem(write_sid_fem(sid, tmp_path / "r.SID_FEM")),
                  read_sid_hdf5(write_sid_hdf5(sid, tmp_path / "r.sid.h5"))):
        assert again.nq == 0 and again.mass == 6.0
        assert np.allclose(again.J.M0, sid.J.M0, rtol=DIGITS_12, atol=0)
        assert again.Gr.M0.shape == (3, 0)


#: the SID_FEM skeleton of docs/sid-spec.md section 7.3 (its code block, copied verbatim)
SPEC_SKELETON = Path(__file__).resolve().parent / "data" / "sid_spec_7_3_skeleton.txt"
SPEC_DIGITS = 3e-10    # the skeleton's numbers are accurate to about 10 digits


def spec_skeleton_text():
    return SPEC_SKELETON.read_text()


def test_spec_skeleton_equals_sid_of_its_lumped_model():
    """sid-spec 7.3: 4 lumped masses, modes ~ x^2 in z and y, mass-normalised, 4.2 / 6.0 Hz,
    zeta = 0.02; its annotated file (read with '#' comment lines) equals what we compute to the
    accuracy of its hand-made numbers (1.10940039231 vs 1/sqrt(0.8125) = 1.10940039245)."""
    spec = parse_sid_fem(spec_skeleton_text(), "sid-spec.md")
    X = np.array([[0, 0, 0], [0.5, 0, 0], [1, 0, 0], [1, 0.1, 0]])
    m = np.array([0.5, 1, 0.5, 0.25])
    c = 1 / np.sqrt(np.sum(m * X[:, 0] ** 4))
    Phi = np.zeros((4, 3, 2))
    Phi[:, 2, 0] = Phi[:, 1, 1] = c * X[:, 0] ** 2
    slope = 2 * c * 1.0                                  # d(c x^2)/dx at x = 1
    psi3 = np.array([[0, 0], [-slope, 0], [0, slope]])  # rotation about -y (mode 1), +z (mode 2)
    f = np.array([4.2, 6.0])
    w = 2 * np.pi * f
    sid = sid_invariants(X, np.diag(m), Phi.reshape(12, 2),
                         [(1, X[0], Phi[0], np.zeros((3, 2))), (3, X[2], Phi[2], psi3)],
                         labels=[f"Eigen Mode {k:4d} : {fk:12.3f} Hz" for k, fk in zip((7, 8), f)],
                         frequencies_hz=f, De=np.diag(2 * 0.02 * w))
    assert spec.labels == sid.labels and spec.mass == sid.mass
    assert np.allclose(spec.De.M0, sid.De.M0, rtol=1e-9)     # De is written with 9 digits there
    for name, a, b in taylor_pairs(replace(spec, De=sid.De), sid):
        assert np.allclose(a.M0, b.M0, rtol=SPEC_DIGITS, atol=SPEC_DIGITS), name
        if a.M1 is not None or b.M1 is not None:
            assert np.allclose(a.M1 if a.M1 is not None else 0, b.M1, rtol=SPEC_DIGITS,
                               atol=SPEC_DIGITS), name
