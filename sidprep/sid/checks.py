"""Model checks of a SID: the self-consistency identities of sid-spec.md 4.8 and the modal data.

``sid_checks(sid)`` returns ``{name: Check}`` (sidprep.sid.check).
``value`` is a relative residual unless the description says otherwise.  Severity "error" marks an
identity every SID must satisfy; "warning" marks one that legitimately breaks (nodal rotary
inertia, geometric stiffening mixed into a sum, a third-party generator's known quirk).
Checks computed by the reduction against the full FE model (mass, CM, inertia, static
deflection, frequencies) arrive in ``sid.metadata["checks"]`` in their dict form and are merged.

Metadata keys read here: ``free_body`` (bool) and ``n_rigid_modes`` (int, zero-energy modes of
the unconstrained FE model).
"""

from __future__ import annotations

import numpy as np

from sidprep.sid.check import Check
from sidprep.sid.model import IDENTITY, SID, axial, ge_tensor, gr_tensor, inertia_matrix, skew

#: relative tolerance of exact identities (covers 12-digit ASCII rounding and round-off)
IDENTITY_RTOL = 1e-9
#: relative tolerance of ielastq label frequencies against sqrt(Ke/Me)/2pi (3 decimals in labels,
#: FE vs reduced eigenvalues)
LABEL_FREQUENCY_RTOL = 1e-3
#: relative off-diagonal size of Me / Ke tolerated for "eigen" coordinates
MODAL_DIAGONAL_RTOL = 1e-8
#: |Ct0_k| / sqrt(m Me_kk) (and the Cr0 analogue) tolerated for free-free modes (spec 4.7)
RIGID_ORTHOGONALITY_RTOL = 1e-6
#: expected zero-energy modes of an unconstrained body
FREE_BODY_RIGID_MODES = 6
#: smallest eigenvalue of Ke / largest |eigenvalue| tolerated below zero (round-off of a PSD matrix)
KE_PSD_RTOL = 1e-9
#: relative slack of the inertia triangle inequalities I_a + I_b >= I_c (a thin rod reaches equality)
TRIANGLE_RTOL = 1e-9
#: |AP0^T AP0 - E| and |det AP0 - 1| tolerated for a node orientation (6-decimal writers: welib %f)
ROTATION_TOL = 1e-5
#: size of a stored entry, relative to the scale of its identity, above which an exact 0 opposite it
#: counts as a zeroed entry; smaller entries are round-off (balken1m's Cr.M1 is ~1e-17 of Me)
ZEROED_ENTRY_RTOL = 1e-6


def _relative(residual: np.ndarray, reference: np.ndarray) -> float:
    """max |residual| / max |reference| (0 when both vanish, inf when only the reference does)."""
    r = float(np.max(np.abs(residual), initial=0.0))
    s = float(np.max(np.abs(reference), initial=0.0))
    return r / s if s > 0 else (0.0 if r == 0 else float("inf"))


def _m1(T, shape) -> np.ndarray:
    return np.zeros(shape) if T.M1 is None else T.M1


def node_identities(sid: SID) -> dict:
    """Identities 1-2 of sid-spec.md 4.8 over all nodes."""
    nq = sid.nq
    origin = [_relative(_m1(n.origin, (3, nq, 1))[:, :, 0] - n.phi.M0, n.phi.M0) for n in sid.nodes]
    ap = []
    for n in sid.nodes:
        ref = np.stack([skew(n.psi.M0[:, k]) @ n.AP.M0 for k in range(nq)], 1) if nq else np.zeros((3, 0, 3))
        ap.append(_relative(_m1(n.AP, (3, nq, 3)) - ref, ref))
    return {
        "origin.M1 = phi.M0": Check.measured(max(origin, default=0.0), IDENTITY_RTOL,
                                             "node positions move with the translational mode shapes (4.8 #1)"),
        "AP.M1 = skew(psi) AP0": Check.measured(max(ap, default=0.0), IDENTITY_RTOL,
                                                "node orientations turn with the rotational mode shapes (4.8 #2)"),
    }


def inertia_identities(sid: SID) -> dict:
    """Identities 3-7 of sid-spec.md 4.8."""
    nq = sid.nq
    out = {"mdCM.M1 = Ct.M0^T": Check.measured(
        _relative(_m1(sid.mdCM, (3, nq, 1))[:, :, 0] - sid.Ct.M0.T, sid.Ct.M0), IDENTITY_RTOL,
        "the CM shift per mode is the modal momentum (4.8 #3)")}
    if nq == 0:
        return out
    G, J1, I1 = gyroscopic_and_inertia_change(sid)
    from_oe = inertia_change_from_oe(sid.Oe.M0)
    cr = np.stack([skew(c) for c in sid.Cr.M0])
    out["J.M1 = sym(Gr0)"] = Check.measured(_relative(0.5 * (G + G.transpose(0, 2, 1)) - I1, G), IDENTITY_RTOL,
                                            "inertia change per mode vs Gr (4.8 #4; rotary inertia breaks it)",
                                            "warning")
    out["J.M1 = -Oe0 (2xx,2yy,2zz,xy,xz,yz)"] = Check.measured(
        _relative(J1 - from_oe, from_oe), IDENTITY_RTOL,
        "inertia change per mode vs centrifugal term (4.8 #4; rotary inertia breaks it)", "warning")
    out["Gr0 - Gr0^T = -2 skew(Cr0)"] = Check.measured(
        _relative(G - G.transpose(0, 2, 1) + 2 * cr, G), IDENTITY_RTOL,
        "antisymmetric part of Gr vs Cr (4.8 #5; rotary inertia breaks it)", "warning")

    Ge = ge_tensor(sid.Ge.M0, nq)
    anti = lambda A: A - A.transpose(0, 2, 1)  # noqa: E731
    if "Kr" in sid.stiffening:
        kr = 2 * np.asarray(sid.stiffening["Kr"])
        out["Ge = 2 Kr"] = Check.measured(_relative(Ge - kr, kr), IDENTITY_RTOL,
                                          "Coriolis coupling of the elastic equation (4.8 #6)")
    else:
        cr1 = 2 * _m1(sid.Cr, (nq, nq, 3)).transpose(2, 0, 1)
        out["Ge = 2 Cr.M1 (antisymmetric parts)"] = Check.measured(
            _relative(anti(Ge) - anti(cr1), cr1), IDENTITY_RTOL,
            "Coriolis coupling vs the Kr part of Cr.M1 (4.8 #6)")
    out["Ge antisymmetric"] = Check.measured(_relative(Ge + Ge.transpose(0, 2, 1), Ge), IDENTITY_RTOL,
                                             "Ge_a = 2 Kr_a is antisymmetric (3.9); a symmetric part means "
                                             "Ge was built from Cr.M1 including K0r", "warning")
    if sid.Oe.M1 is not None:
        oe1 = sid.Oe.M1
        out["Oe.M1 symmetric"] = Check.measured(_relative(oe1 - oe1.transpose(1, 0, 2), oe1), IDENTITY_RTOL,
                                                "centrifugal mode coupling is symmetric per omega-hat slice "
                                                "(4.8 #7)", "warning")
        kom = np.asarray(sid.stiffening["Kom"]).transpose(1, 2, 0) if "Kom" in sid.stiffening else oe1
        out["Kom_xx + Kom_yy + Kom_zz = -2 Me"] = Check.measured(
            _relative(kom[:, :, 0] + kom[:, :, 1] + kom[:, :, 2] + 2 * sid.Me.M0, sid.Me.M0),
            IDENTITY_RTOL, "centrifugal softening trace (4.8 #7; needs Oe.M1 without K0omega)",
            "error" if "Kom" in sid.stiffening else "warning")
    return out


def gyroscopic_and_inertia_change(sid: SID) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The canonical Gr0 tensor (nq, 3, 3), J.M1 as stored (6, nq) and as 3x3 matrices (nq, 3, 3)."""
    J1 = _m1(sid.J, (6, sid.nq, 1))[:, :, 0]
    return gr_tensor(sid.Gr.M0, sid.nq), J1, np.stack([inertia_matrix(J1[:, k]) for k in range(sid.nq)])


def inertia_change_from_oe(oe: np.ndarray) -> np.ndarray:
    """J.M1 (6, nq) the centrifugal term Oe0 (nq, 6) implies: -[2xx, 2yy, 2zz, xy, xz, yz] (4.8 #4)."""
    return -np.stack([2 * oe[:, 0], 2 * oe[:, 1], 2 * oe[:, 2], oe[:, 3], oe[:, 5], oe[:, 4]])


def zeroed_entries(stored: np.ndarray, twin: np.ndarray, scale: float, mirrored: bool = False) -> int | None:
    """How many entries of ``stored`` are exactly 0 where ``twin`` is not, or the reverse: the mark
    of a deleted line in a file that omits zero entries.

    Parameters
    ----------
    stored : ndarray
        Entries as stored.
    twin : ndarray, same shape
        What an identity of sid-spec.md 4.8 says they are, from other stored members.
    scale : float
        Size of the quantity (a physical bound, or its largest entry); entries below
        ZEROED_ENTRY_RTOL * scale are round-off and not counted.
    mirrored : bool
        The twin of entry [..., i, j] is made from stored[..., j, i]: the mirror of a lone zero is
        then not held against the identity.

    Returns
    -------
    int or None
        The number of lone zeros; None when the identity fails (beyond IDENTITY_RTOL * scale) where
        both are nonzero, for then a lone zero may be legitimate (nodal rotary inertia, stiffening
        terms, a generator's convention).
    """
    if scale <= 0:
        return None
    lone = ((stored == 0) != (twin == 0)) & (np.abs(stored - twin) > ZEROED_ENTRY_RTOL * scale)
    mirror_of_lone = lone.swapaxes(-1, -2) if mirrored else np.zeros_like(lone)
    both = (stored != 0) & (twin != 0) & ~mirror_of_lone
    if np.max(np.abs(stored - twin)[both], initial=0.0) > IDENTITY_RTOL * scale:
        return None
    return int(np.count_nonzero(lone))


def zeroed_entry_checks(sid: SID) -> dict:
    """Deleted lines of a file that omits zeros, found through stored twins (sid-spec.md 4.8).

    Where an identity holds at every entry stored on both sides, an entry read as exactly 0 while
    its twin is not was deleted: J.M1 vs Oe0 (#4), Gr0 vs 2 J.M1 - Gr0^T (#4, sym Gr0 = I1),
    Cr0 vs the axial vector of Gr0 / 2 (#5), Ge vs 2 Cr.M1 (#6, no stiffening), Oe.M1 vs its
    transpose in the two modal indices (#7).  A check is listed only where its identity holds.
    """
    nq = sid.nq
    if nq == 0:
        return {}
    G, J1, I1 = gyroscopic_and_inertia_change(sid)
    oe1 = _m1(sid.Oe, (nq, nq, 6))
    # Cauchy-Schwarz bounds: |int phi_k,a phi_j,b dm| <= max Me_kk, |int c_a phi_k,b dm| <= sqrt(int |c|^2 dm max Me_kk)
    modal = float(np.max(np.abs(np.diag(sid.Me.M0))))
    moment = float(np.sqrt(0.5 * abs(np.trace(inertia_matrix(sid.J.M0))) * modal))
    pairs = {   # name: (stored, twin, scale bound, twin built from the stored entry's mirror)
        "J.M1 vs Oe0": (J1, inertia_change_from_oe(sid.Oe.M0), moment, False),
        "Gr0 vs 2 J.M1 - Gr0^T": (G, 2 * I1 - G.transpose(0, 2, 1), moment, True),
        "Cr0 vs axial(Gr0)/2": (sid.Cr.M0, 0.5 * axial(G), moment, False),
        "Ge vs 2 Cr.M1": (ge_tensor(sid.Ge.M0, nq), 2 * _m1(sid.Cr, (nq, nq, 3)).transpose(2, 0, 1), modal, False),
        "Oe.M1 vs its transpose": (oe1, oe1.transpose(1, 0, 2), modal, False),
    }
    out = {}
    for name, (stored, twin, bound, mirrored) in pairs.items():
        scale = max(bound, float(np.max(np.abs(stored), initial=0.0)), float(np.max(np.abs(twin), initial=0.0)))
        count = zeroed_entries(stored, twin, scale, mirrored)
        if count is not None:
            out[f"no zeroed entry: {name}"] = Check.measured(
                count, 0, "entries exactly 0 where the identity's other side is not (a deleted line "
                          "of a file that omits zeros); value = their number")
    return out


def file_notes(sid: SID) -> dict:
    """Entries a SID_FEM file did not write (metadata ``sid_fem_entries`` of the reader), as a note."""
    meta = sid.metadata if isinstance(sid.metadata, dict) else {}
    entries = meta.get("sid_fem_entries")
    if not isinstance(entries, dict):
        return {}
    how = ("the file writes its zeros: none may be missing" if entries["zeros_written"] else
           "read as 0: the file's writer omits zeros, so a deleted line there is told from a zero "
           "only by the identities")
    return {"SID_FEM entries not written": Check.note(
        entries["omitted_entries"],
        f"{entries['omitted_entries']} of {entries['omitted_entries'] + entries['written_entries']} entries; {how}")}


def modal_checks(sid: SID) -> dict:
    """Me, Ke and the ielastq labels (sid-spec.md 3.7, 3.12, 4.8 #8)."""
    nq = sid.nq
    Me, Ke = sid.Me.M0, sid.Ke.M0
    out = {
        "Me symmetric positive definite": Check.measured(
            0.0 if nq == 0 else (_relative(Me - Me.T, Me) if np.all(np.linalg.eigvalsh(0.5 * (Me + Me.T)) > 0)
                                 else float("inf")), IDENTITY_RTOL, "modal mass matrix"),
        "Ke symmetric": Check.measured(_relative(Ke - Ke.T, Ke), IDENTITY_RTOL, "modal stiffness matrix"),
    }
    if sid.Me.structure == IDENTITY:
        out["Me = E (structure 4)"] = Check.measured(_relative(Me - np.eye(nq), np.eye(nq)), IDENTITY_RTOL,
                                                     "structure 4 promises mass-orthonormal coordinates")
    eigen = [k for k in range(nq) if sid.mode_kinds[k:k + 1] == ("eigen",)]
    if eigen:
        sub = np.ix_(eigen, eigen)
        off = lambda A: A - np.diag(np.diag(A))  # noqa: E731
        diagonal = Check.measured(max(_relative(off(Me[sub]), Me[sub]), _relative(off(Ke[sub]), Ke[sub])),
                                  MODAL_DIAGONAL_RTOL, "eigen-type coordinates are M- and K-orthogonal", "warning")
        out["Me, Ke diagonal for eigen modes"] = diagonal
        # every coordinate whose label gives a frequency: eigenmodes and the (orthonormalised)
        # frequency-response modes, whose labels carry theirs too
        labelled = [k for k in range(nq) if sid.mode_kinds[k:k + 1] in (("eigen",), ("frm",))]
        lab = np.ix_(labelled, labelled)
        lab_diagonal = max(_relative(off(Me[lab]), Me[lab]), _relative(off(Ke[lab]), Ke[lab])) <= MODAL_DIAGONAL_RTOL
        out["labels: f = sqrt(Ke/Me)/2pi"] = Check.measured(
            label_frequency_deviation(np.asarray(sid.frequencies_hz, dtype=float)[labelled], Me[lab], Ke[lab],
                                      lab_diagonal), LABEL_FREQUENCY_RTOL,
            "label frequencies vs the modal stiffness (4.8 #8): per coordinate sqrt(Ke_ii/Me_ii)/2pi, "
            "or, where Me and Ke are not diagonal, the sorted generalized eigenfrequencies")
    return out


def label_frequency_deviation(f: np.ndarray, Me: np.ndarray, Ke: np.ndarray, diagonal: bool) -> float:
    """Largest relative deviation of label frequencies from those of Ke and Me.

    Parameters
    ----------
    f : (n,) ndarray
        Label frequencies, Hz (NaN or <= 0 where a label has none).
    Me, Ke : (n, n) ndarray
        Modal mass and stiffness of the labelled coordinates.
    diagonal : bool
        Me and Ke are diagonal: compare coordinate by coordinate with sqrt(Ke_ii/Me_ii)/2pi; else
        compare the sorted labels with the sorted generalized eigenfrequencies of (Ke, Me) (only
        when every label carries a frequency; inf when Me is not positive definite).

    Returns
    -------
    float
        max |f_Ke - f| / f.
    """
    ok = np.isfinite(f) & (f > 0)
    if diagonal:
        f_ke = np.sqrt(np.clip(np.diag(Ke) / np.diag(Me), 0, None)) / (2 * np.pi)
        return float(np.max(np.abs(f_ke[ok] - f[ok]) / f[ok], initial=0.0))
    if not ok.all():
        return 0.0
    try:
        L = np.linalg.cholesky(0.5 * (Me + Me.T))
    except np.linalg.LinAlgError:
        return float("inf")
    A = np.linalg.solve(L, np.linalg.solve(L, 0.5 * (Ke + Ke.T)).T)
    f_ke = np.sqrt(np.clip(np.linalg.eigvalsh(A), 0, None)) / (2 * np.pi)
    return float(np.max(np.abs(f_ke - np.sort(f)) / np.sort(f)))


def inertia_about_cm(sid: SID) -> np.ndarray:
    """3x3 inertia (kg m^2) about the centre of mass: J - m (|c|^2 E - c c^T), c = mdCM / m."""
    c = np.ravel(sid.mdCM.M0) / sid.mass
    return inertia_matrix(sid.J.M0) - sid.mass * (c @ c * np.eye(3) - np.outer(c, c))


def member_shapes(nq: int) -> dict:
    """{member: M0 shape} of a SID with nq modal coordinates (sid-spec.md section 3; the SID
    docstring); M1 is (nrow, nq, ncol).  Node members are prefixed "node "."""
    return {"mdCM": (3, 1), "J": (6, 1), "Ct": (nq, 3), "Cr": (nq, 3), "Me": (nq, nq), "Gr": (3, 3 * nq),
            "Ge": (nq, 3 * nq), "Oe": (nq, 6), "ksigma": (nq, 1), "Ke": (nq, nq), "De": (nq, nq),
            "node origin": (3, 1), "node phi": (3, nq), "node psi": (3, nq), "node AP": (3, 3), "node sigma": (6, 1)}


def structure_problem(sid: SID) -> str | None:
    """What makes ``sid`` not a SID at all (a member of the wrong shape or not numbers, labels or
    paths not matching nq), or None.  Checked by every reader before any other check."""
    nq = len(sid.labels)
    shapes = member_shapes(nq)
    members = [(m, getattr(sid, m)) for m in TAYLOR_MEMBERS]
    members += [(f"node {m}", getattr(n, m)) for n in sid.nodes for m in ("origin", "phi", "psi", "AP", "sigma")
                if getattr(n, m) is not None]
    if not isinstance(sid.mass, (int, float, np.number)) or isinstance(sid.mass, bool):
        return f"mass is {sid.mass!r}, not a number"
    for name, T in members:
        for part, value, shape in (("M0", T.M0, shapes[name]),
                                   ("M1", T.M1, (shapes[name][0], nq, shapes[name][1]))):
            if part == "M1" and value is None:
                continue
            a = np.asarray(value)
            if not np.issubdtype(a.dtype, np.number):
                return f"{name}.{part} holds {a.dtype} values, not numbers"
            if a.shape != shape:
                return f"{name}.{part} is {a.shape}, expected {shape} for {nq} modal coordinates"
    if len(np.atleast_1d(sid.frequencies_hz)) != nq or len(sid.mode_kinds) != nq:
        return f"{nq} labels but {len(np.atleast_1d(sid.frequencies_hz))} frequencies and {len(sid.mode_kinds)} mode kinds"
    for key, value in sid.stiffening.items():
        a = np.asarray(value)
        if not np.issubdtype(a.dtype, np.number) or a.ndim != 3 or a.shape[1:] != (nq, nq):
            return f"stiffening part {key} is {a.shape} {a.dtype}, expected (k, {nq}, {nq}) numbers"
    if sid.stress is not None:
        problem = stress_problem(sid.stress, nq)
        if problem:
            return problem
    for name, p in sid.paths.items():
        arrays = [np.asarray(getattr(p, m)) for m in ("s", "points", "phi", "psi")]
        n = arrays[0].shape[0] if arrays[0].ndim == 1 else -1
        if n < 2 or any(not np.issubdtype(a.dtype, np.number) for a in arrays) or \
                [a.shape for a in arrays[1:]] != [(n, 3), (n, 3, nq), (n, 3, nq)] or not np.all(np.diff(arrays[0]) > 0):
            return f"path {name} is not n >= 2 increasing arc lengths with (n, 3) points and (n, 3, {nq}) shapes"
    return None


#: scopes of the modal stresses (sidprep.sid.stress.StressModes.scope)
STRESS_SCOPES = ("surface", "all")


def stress_problem(stress, nq: int) -> str | None:
    """What makes the modal stresses (the /stress group) not those of a SID with nq modal
    coordinates: node_ids (ns,) distinct integers, points (ns, 3) and modes (ns, 6, nq) numbers,
    ns >= 1, a known scope; or None."""
    ids, points, modes = (np.asarray(a) for a in (stress.node_ids, stress.points, stress.modes))
    ns = points.shape[0] if points.ndim == 2 else -1
    if ns < 1 or points.shape != (ns, 3) or not np.issubdtype(points.dtype, np.number):
        return f"stress points are {points.shape} {points.dtype}, expected (ns, 3) numbers with ns >= 1"
    if ids.shape != (ns,) or not np.issubdtype(ids.dtype, np.integer) or len(np.unique(ids)) != ns:
        return f"stress node_ids are {ids.shape} {ids.dtype}, expected {ns} distinct integers (one per stress point)"
    if modes.shape != (ns, 6, nq) or not np.issubdtype(modes.dtype, np.number):
        return f"stress modes are {modes.shape} {modes.dtype}, expected ({ns}, 6, {nq}) numbers"
    if stress.scope not in STRESS_SCOPES:
        return f"stress scope {stress.scope!r}, expected one of {', '.join(STRESS_SCOPES)}"
    return None


def finite_entries(sid: SID) -> dict:
    """Every number of the SID is finite (``non_finite_entries``; a NaN or inf makes every other
    check meaningless)."""
    bad = non_finite_entries(sid)
    shown = f" ({', '.join(bad[:3])}{' ...' if len(bad) > 3 else ''})" if bad else ""
    return {"entries finite": Check.measured(len(bad), 0,
                                             f"members with NaN or inf entries{shown}; value = their number")}


#: the check of the principal moments of inertia (physical_checks)
INERTIA_CHECK = "inertia about CM positive definite or a line body"


def inertia_defects(sid: SID) -> tuple[np.ndarray, float, float]:
    """The rule for the inertia about the centre of mass, shared by ``sidprep check``
    (physical_checks) and the solver (physical_problems): principal moments I1 <= I2 <= I3 >= 0
    with the triangle inequality I3 <= I1 + I2, each within TRIANGLE_RTOL I3.  One zero moment
    is a line body (point masses on a line, a beam SID without rotary inertia, the thin-rod
    limit): the triangle inequality then forces I2 = I3; two zeros (a point mass) are refused,
    for a body then has no inertia against turning about two axes.

    Returns
    -------
    p : (3,) principal moments, kg m^2, ascending
    negative : -I1 / I3 (0 when I1 >= 0; inf when I2 <= 0), compared with TRIANGLE_RTOL
    triangle : (I3 - I1 - I2) / I3 (0 when it holds), compared with TRIANGLE_RTOL
    """
    j_cm = inertia_about_cm(sid)
    p = np.sort(np.linalg.eigvalsh(0.5 * (j_cm + j_cm.T)))
    scale = max(abs(p[-1]), 1e-300)
    negative = max(-p[0] / scale, 0.0) if p[1] > 0 else float("inf")
    return p, negative, max((p[2] - p[0] - p[1]) / scale, 0.0)


def physical_checks(sid: SID) -> dict:
    """Is the SID physically possible?  Mass, inertia about the CM, Ke, node orientations (any SID,
    any generator).

    A deleted or zeroed data line (a damaged file) typically breaks one of these: the principal
    moments of inertia about the CM must be positive and satisfy I_a + I_b >= I_c; Ke must be
    positive semidefinite (Me positive definite is checked in :func:`modal_checks`); each node's
    AP0 must be a rotation.
    """
    mass = float(sid.mass)
    out = {"mass > 0": Check.measured(0.0 if mass > 0 else float("inf"), 0.0,
                                      f"rigid-body mass m = {mass:.6g} kg (value 0 when positive)")}
    if not mass > 0:
        return out
    p, negative, triangle = inertia_defects(sid)
    out[INERTIA_CHECK] = Check.measured(
        negative, TRIANGLE_RTOL,
        f"principal moments about the CM {p[0]:.6g}, {p[1]:.6g}, {p[2]:.6g} kg m^2 (value -min/max; inf when "
        "two are 0: one zero moment only for a line body)")
    out["inertia triangle inequalities"] = Check.measured(
        triangle, TRIANGLE_RTOL, "largest principal moment <= sum of the other two (value (I3 - I1 - I2)/I3)")
    if sid.nq:
        Ke = 0.5 * (sid.Ke.M0 + sid.Ke.M0.T)
        ev = np.linalg.eigvalsh(Ke)
        out["Ke positive semidefinite"] = Check.measured(
            max(-ev[0], 0.0) / max(abs(ev).max(), 1e-300), KE_PSD_RTOL,
            "modal stiffness has no negative eigenvalue (value -min/max)")
    if sid.nodes:
        out["node orientations AP0 are rotations"] = Check.measured(
            max(rotation_defect(n.AP.M0) for n in sid.nodes), ROTATION_TOL,
            "AP0 maps node-frame to body-frame components (3.2): value max |AP0^T AP0 - E|, |det - 1|")
    return out


#: the SID members a solver integrates with, in file order (sid-spec 3)
TAYLOR_MEMBERS = ("mdCM", "J", "Ct", "Cr", "Me", "Gr", "Ge", "Oe", "ksigma", "Ke", "De")
#: J components as the SID_FEM file orders them (sid-spec 3.5)
J_NAMES = ("Jxx", "Jyy", "Jzz", "Jxy", "Jxz", "Jyz")


def _first_non_finite(name: str, array) -> str | None:
    """'name[i, j] = value' of the first non-finite entry of ``array``, or None."""
    a = np.asarray(array, dtype=float)
    bad = np.argwhere(~np.isfinite(a))
    if not bad.size:
        return None
    index = tuple(int(i) for i in bad[0])
    return f"{name}{list(index)} = {a[index]}"


def non_finite_entries(sid: SID) -> list[str]:
    """The first non-finite entry of every SID member that has one ('Ke.M0[2, 3] = inf')."""
    found = [_first_non_finite("mass", [sid.mass])]
    for name in TAYLOR_MEMBERS:
        t = getattr(sid, name)
        found += [_first_non_finite(f"{name}.M0", t.M0), None if t.M1 is None else _first_non_finite(f"{name}.M1", t.M1)]
    for n in sid.nodes:
        for part in ("origin", "phi", "psi", "AP"):
            t = getattr(n, part)
            found += [_first_non_finite(f"node {n.node_id} {part}.M0", t.M0),
                      None if t.M1 is None else _first_non_finite(f"node {n.node_id} {part}.M1", t.M1)]
    if sid.stress is not None:
        found += [_first_non_finite("stress points", sid.stress.points),
                  _first_non_finite("stress modes", sid.stress.modes)]
    return [f for f in found if f]


def physical_problems(sid: SID) -> list[str]:
    """What makes ``sid`` physically impossible for a simulation, one phrase each naming the
    entry (empty when it is possible): non-finite numbers; mass <= 0; inertia about the centre
    of mass with a negative principal moment, two zero ones, or breaking the triangle inequalities
    (one zero moment is the limit of a thin rod, point masses on a line); Me not symmetric
    positive definite; Ke not symmetric positive semidefinite (tolerances IDENTITY_RTOL,
    KE_PSD_RTOL, TRIANGLE_RTOL).  Shared by the solver (refuses to load), ``sidprep check``
    and the viewers' warnings."""
    bad = non_finite_entries(sid)
    if bad:
        return [f"non-finite number {b}" for b in bad]
    problems = []
    if not sid.mass > 0:
        return [f"mass = {sid.mass:.6g} kg (must be > 0)"]
    p, negative, triangle = inertia_defects(sid)
    diagonal = ", ".join(f"{n} {v:.6g}" for n, v in zip(J_NAMES[:3], np.diag(inertia_about_cm(sid))))
    if negative > TRIANGLE_RTOL:
        problems.append(f"inertia about the centre of mass not positive definite (J.M0 with mdCM: {diagonal}; "
                        f"principal moments {p[0]:.6g}, {p[1]:.6g}, {p[2]:.6g} kg m^2; one zero moment only for a "
                        "line body)")
    elif triangle > TRIANGLE_RTOL:
        problems.append(f"inertia about the centre of mass physically impossible (J.M0 with mdCM: principal "
                        f"moments {p[0]:.6g} + {p[1]:.6g} < {p[2]:.6g} kg m^2, triangle inequality)")
    if sid.nq:
        me, ke = np.asarray(sid.Me.M0, float), np.asarray(sid.Ke.M0, float)
        if _relative(me - me.T, me) > IDENTITY_RTOL:
            problems.append(f"Me.M0 not symmetric (max |Me - Me^T| / max |Me| = {_relative(me - me.T, me):.3g})")
        elif not np.all(np.linalg.eigvalsh(me) > 0):
            k = int(np.argmin(np.diag(me)))
            problems.append(f"Me.M0 not positive definite (smallest eigenvalue {np.linalg.eigvalsh(me)[0]:.6g}; "
                            f"Me[{k}, {k}] = {me[k, k]:.6g})")
        if _relative(ke - ke.T, ke) > IDENTITY_RTOL:
            problems.append(f"Ke.M0 not symmetric (max |Ke - Ke^T| / max |Ke| = {_relative(ke - ke.T, ke):.3g})")
        else:
            ev = np.linalg.eigvalsh(ke)
            if -ev[0] > KE_PSD_RTOL * max(abs(ev).max(), 1e-300):
                k = int(np.argmin(np.diag(ke)))
                problems.append(f"Ke.M0 not positive semidefinite (smallest eigenvalue {ev[0]:.6g}; "
                                f"Ke[{k}, {k}] = {ke[k, k]:.6g})")
    return problems


def rotation_defect(A: np.ndarray) -> float:
    """How far a 3x3 matrix is from a rotation: max(|A^T A - E|, |det A - 1|)."""
    return max(float(np.max(np.abs(A.T @ A - np.eye(3)))), abs(float(np.linalg.det(A)) - 1.0))


def _reduction_report(meta) -> dict:
    """``metadata["checks"]`` when written as one flat report (scalars + a "passed" flag)."""
    report = meta.get("checks") if isinstance(meta, dict) else None
    return report if isinstance(report, dict) and isinstance(report.get("passed"), bool) else {}


def free_body_checks(sid: SID) -> dict:
    """Six zero-energy modes of the FE model and free-free modes orthogonal to them (spec 4.7).

    A free body is flagged by ``metadata["free_body"]`` or by a reduction report expecting 6
    zero-energy modes; their count comes from ``n_rigid_modes`` or the report's ``zero_energy_modes``.
    """
    meta = sid.metadata if isinstance(sid.metadata, dict) else {}
    report = _reduction_report(meta)
    free = meta.get("free_body", report.get("zero_energy_modes_expected") == FREE_BODY_RIGID_MODES)
    if not free:
        return {}
    out = {}
    n = meta.get("n_rigid_modes", report.get("zero_energy_modes"))
    if n is not None:
        out["6 zero-energy modes"] = Check.measured(abs(int(n) - FREE_BODY_RIGID_MODES), 0,
                                                    f"the unconstrained FE model has {n} zero-energy modes "
                                                    f"(value = |n - 6|)")
    if sid.nq:
        me = np.sqrt(np.abs(np.diag(sid.Me.M0)))
        i_max = max(np.max(np.linalg.eigvalsh(inertia_matrix(sid.J.M0))), 1e-300)
        ct = np.linalg.norm(sid.Ct.M0, axis=1) / (np.sqrt(sid.mass) * me)
        cr = np.linalg.norm(sid.Cr.M0, axis=1) / (np.sqrt(i_max) * me)
        out["free modes orthogonal to rigid motion"] = Check.measured(
            max(ct.max(), cr.max()), RIGID_ORTHOGONALITY_RTOL,
            "|Ct0_k|/sqrt(m Me_kk), |Cr0_k|/sqrt(I Me_kk): no rigid motion in the basis")
    return out


def normalise_external(checks) -> dict:
    """Checks from ``metadata["checks"]`` as ``{name: Check}``.

    Two forms are accepted: ``{name: {value, tolerance, passed|pass|ok, ...}}`` (or ``{name: Check}``), or one flat report
    of the reduction (scalars plus an overall ``passed`` flag): the flag becomes the check
    "FE comparison", each scalar an "info" entry.
    """
    checks = dict(checks or {})
    if isinstance(checks.get("passed"), bool):
        scalars = {k: v for k, v in checks.items()
                   if isinstance(v, (int, float)) and not isinstance(v, bool)}
        out = {"FE comparison": Check(float(not checks["passed"]), 0.0, checks["passed"], "error",
                                      "reduction vs full FE model (mass, CM, inertia, zero-energy modes, "
                                      "static deflection)")}
        out.update({f"FE {k}": Check.note(v, "reported by the reduction") for k, v in scalars.items()})
        return out
    out = {}
    for name, c in checks.items():
        if isinstance(c, Check):
            out[str(name)] = c
        elif isinstance(c, dict):
            passed = c.get("passed", c.get("pass", c.get("ok")))
            if passed is None and "value" in c and "tolerance" in c:
                passed = float(c["value"]) <= float(c["tolerance"])
            out[str(name)] = Check(c.get("value"), c.get("tolerance"), bool(passed), c.get("severity", "error"),
                                   c.get("description", ""))
    return out


def sid_checks(sid: SID) -> dict:
    """All checks of ``sid``: identities, modal data, free-body checks, and the FE comparisons.

    A SID with NaN or inf entries gets only "entries finite" (and the file notes): the other
    checks would compare NaNs.  Overflow in a check makes its value inf (a failure), silently.
    """
    meta = sid.metadata if isinstance(sid.metadata, dict) else {}
    finite = finite_entries(sid)
    if not finite["entries finite"].passed:
        return {**file_notes(sid), **finite}
    with np.errstate(all="ignore"):
        return {**file_notes(sid), **finite, **physical_checks(sid), **node_identities(sid),
                **inertia_identities(sid), **zeroed_entry_checks(sid), **modal_checks(sid),
                **free_body_checks(sid), **normalise_external(meta.get("checks"))}


def failed_checks(checks: dict) -> list[str]:
    """Names of the failed checks of severity "error"."""
    return [name for name, c in checks.items() if not c.passed and c.severity == "error"]


def checks_summary(checks: dict) -> str:
    """One line counting the lines of ``format_checks``: "all 30 checks passed (and 1 info line)",
    or the failed checks (errors) and the warnings by name."""
    tested = {n: c for n, c in checks.items() if c.severity != "info"}
    failed = failed_checks(checks)
    warned = [n for n, c in tested.items() if not c.passed and c.severity != "error"]
    info = len(checks) - len(tested)
    notes = f" ({info} info line{'s' * (info != 1)})" if info else ""
    if failed:
        return f"{len(failed)} of {len(tested)} checks failed: {', '.join(failed)}{notes}"
    if warned:
        return f"{len(tested) - len(warned)} of {len(tested)} checks passed, {len(warned)} warned: {', '.join(warned)}{notes}"
    return f"all {len(tested)} checks passed{notes}"


def format_checks(checks: dict) -> str:
    """One line per check: status, name, value, tolerance (counts as integers, none as '-')."""
    def number(v):
        if isinstance(v, int) and not isinstance(v, bool):
            return f"{v:10d}"
        return f"{v:10.3e}" if isinstance(v, float) else f"{'-' if v is None else str(v):>10s}"

    lines = []
    for name, c in checks.items():
        flag = ("info" if c.severity == "info" else "ok  " if c.passed
                else "FAIL" if c.severity == "error" else "warn")
        lines.append(f"  {flag} {name:<42s} {number(c.value)} (tol {number(c.tolerance)})")
    return "\n".join(lines)
