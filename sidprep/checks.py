"""Model checks of a SID: the self-consistency identities of sid-spec.md 4.8 and the modal data.

``sid_checks(sid)`` returns ``{name: {"value", "tolerance", "passed", "severity", "description"}}``.
``value`` is a relative residual unless the description says otherwise.  Severity "error" marks an
identity every SID must satisfy; "warning" marks one that legitimately breaks (nodal rotary
inertia, geometric stiffening mixed into a sum, a third-party generator's known quirk).
Checks computed by the reduction against the full FE model (mass, CM, inertia, static
deflection, frequencies) arrive in ``sid.metadata["checks"]`` in the same form and are merged.

Metadata keys read here: ``free_body`` (bool) and ``n_rigid_modes`` (int, zero-energy modes of
the unconstrained FE model).
"""

from __future__ import annotations

import numpy as np

from sidprep.sid import IDENTITY, SID, ge_tensor, gr_tensor, inertia_matrix, skew

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


def _relative(residual: np.ndarray, reference: np.ndarray) -> float:
    """max |residual| / max |reference| (0 when both vanish, inf when only the reference does)."""
    r = float(np.max(np.abs(residual), initial=0.0))
    s = float(np.max(np.abs(reference), initial=0.0))
    return r / s if s > 0 else (0.0 if r == 0 else float("inf"))


def _entry(value: float, tolerance: float, description: str, severity: str = "error") -> dict:
    return {"value": float(value), "tolerance": float(tolerance), "passed": bool(value <= tolerance),
            "severity": severity, "description": description}


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
        "origin.M1 = phi.M0": _entry(max(origin, default=0.0), IDENTITY_RTOL,
                                     "node positions move with the translational mode shapes (4.8 #1)"),
        "AP.M1 = skew(psi) AP0": _entry(max(ap, default=0.0), IDENTITY_RTOL,
                                        "node orientations turn with the rotational mode shapes (4.8 #2)"),
    }


def inertia_identities(sid: SID) -> dict:
    """Identities 3-7 of sid-spec.md 4.8."""
    nq = sid.nq
    out = {"mdCM.M1 = Ct.M0^T": _entry(
        _relative(_m1(sid.mdCM, (3, nq, 1))[:, :, 0] - sid.Ct.M0.T, sid.Ct.M0), IDENTITY_RTOL,
        "the CM shift per mode is the modal momentum (4.8 #3)")}
    if nq == 0:
        return out
    G = gr_tensor(sid.Gr.M0, nq)
    J1 = _m1(sid.J, (6, nq, 1))[:, :, 0]
    I1 = np.stack([inertia_matrix(J1[:, k]) for k in range(nq)])
    oe = sid.Oe.M0
    from_oe = -np.stack([2 * oe[:, 0], 2 * oe[:, 1], 2 * oe[:, 2], oe[:, 3], oe[:, 5], oe[:, 4]])
    cr = np.stack([skew(c) for c in sid.Cr.M0])
    out["J.M1 = sym(Gr0)"] = _entry(_relative(0.5 * (G + G.transpose(0, 2, 1)) - I1, G), IDENTITY_RTOL,
                                    "inertia change per mode vs Gr (4.8 #4; rotary inertia breaks it)",
                                    "warning")
    out["J.M1 = -Oe0 (2xx,2yy,2zz,xy,xz,yz)"] = _entry(
        _relative(J1 - from_oe, from_oe), IDENTITY_RTOL,
        "inertia change per mode vs centrifugal term (4.8 #4; rotary inertia breaks it)", "warning")
    out["Gr0 - Gr0^T = -2 skew(Cr0)"] = _entry(
        _relative(G - G.transpose(0, 2, 1) + 2 * cr, G), IDENTITY_RTOL,
        "antisymmetric part of Gr vs Cr (4.8 #5; rotary inertia breaks it)", "warning")

    Ge = ge_tensor(sid.Ge.M0, nq)
    anti = lambda A: A - A.transpose(0, 2, 1)  # noqa: E731
    if "Kr" in sid.stiffening:
        kr = 2 * np.asarray(sid.stiffening["Kr"])
        out["Ge = 2 Kr"] = _entry(_relative(Ge - kr, kr), IDENTITY_RTOL,
                                  "Coriolis coupling of the elastic equation (4.8 #6)")
    else:
        cr1 = 2 * _m1(sid.Cr, (nq, nq, 3)).transpose(2, 0, 1)
        out["Ge = 2 Cr.M1 (antisymmetric parts)"] = _entry(
            _relative(anti(Ge) - anti(cr1), cr1), IDENTITY_RTOL,
            "Coriolis coupling vs the Kr part of Cr.M1 (4.8 #6)")
    out["Ge antisymmetric"] = _entry(_relative(Ge + Ge.transpose(0, 2, 1), Ge), IDENTITY_RTOL,
                                     "Ge_a = 2 Kr_a is antisymmetric (3.9); a symmetric part means "
                                     "Ge was built from Cr.M1 including K0r", "warning")
    if sid.Oe.M1 is not None:
        oe1 = sid.Oe.M1
        out["Oe.M1 symmetric"] = _entry(_relative(oe1 - oe1.transpose(1, 0, 2), oe1), IDENTITY_RTOL,
                                        "centrifugal mode coupling is symmetric per omega-hat slice "
                                        "(4.8 #7)", "warning")
        kom = np.asarray(sid.stiffening["Kom"]).transpose(1, 2, 0) if "Kom" in sid.stiffening else oe1
        out["Kom_xx + Kom_yy + Kom_zz = -2 Me"] = _entry(
            _relative(kom[:, :, 0] + kom[:, :, 1] + kom[:, :, 2] + 2 * sid.Me.M0, sid.Me.M0),
            IDENTITY_RTOL, "centrifugal softening trace (4.8 #7; needs Oe.M1 without K0omega)",
            "error" if "Kom" in sid.stiffening else "warning")
    return out


def modal_checks(sid: SID) -> dict:
    """Me, Ke and the ielastq labels (sid-spec.md 3.7, 3.12, 4.8 #8)."""
    nq = sid.nq
    Me, Ke = sid.Me.M0, sid.Ke.M0
    out = {
        "Me symmetric positive definite": _entry(
            0.0 if nq == 0 else (_relative(Me - Me.T, Me) if np.all(np.linalg.eigvalsh(0.5 * (Me + Me.T)) > 0)
                                 else float("inf")), IDENTITY_RTOL, "modal mass matrix"),
        "Ke symmetric": _entry(_relative(Ke - Ke.T, Ke), IDENTITY_RTOL, "modal stiffness matrix"),
    }
    if sid.Me.structure == IDENTITY:
        out["Me = E (structure 4)"] = _entry(_relative(Me - np.eye(nq), np.eye(nq)), IDENTITY_RTOL,
                                             "structure 4 promises mass-orthonormal coordinates")
    eigen = [k for k in range(nq) if sid.mode_kinds[k:k + 1] == ("eigen",)]
    if eigen:
        sub = np.ix_(eigen, eigen)
        off = lambda A: A - np.diag(np.diag(A))  # noqa: E731
        out["Me, Ke diagonal for eigen modes"] = _entry(
            max(_relative(off(Me[sub]), Me[sub]), _relative(off(Ke[sub]), Ke[sub])),
            MODAL_DIAGONAL_RTOL, "eigen-type coordinates are M- and K-orthogonal", "warning")
        f = np.asarray(sid.frequencies_hz, dtype=float)[eigen]
        lam = np.diag(Ke)[eigen] / np.diag(Me)[eigen]
        f_ke = np.sqrt(np.clip(lam, 0, None)) / (2 * np.pi)
        ok = np.isfinite(f) & (f > 0)
        dev = float(np.max(np.abs(f_ke[ok] - f[ok]) / f[ok], initial=0.0))
        out["labels: f = sqrt(Ke/Me)/2pi"] = _entry(dev, LABEL_FREQUENCY_RTOL,
                                                    "label frequencies vs the modal stiffness (4.8 #8)")
    return out


def inertia_about_cm(sid: SID) -> np.ndarray:
    """3x3 inertia (kg m^2) about the centre of mass: J - m (|c|^2 E - c c^T), c = mdCM / m."""
    c = np.ravel(sid.mdCM.M0) / sid.mass
    return inertia_matrix(sid.J.M0) - sid.mass * (c @ c * np.eye(3) - np.outer(c, c))


def physical_checks(sid: SID) -> dict:
    """Is the SID physically possible?  Mass, inertia about the CM, Ke (any SID, any generator).

    A deleted or zeroed data line (a damaged file) typically breaks one of these: the principal
    moments of inertia about the CM must be positive and satisfy I_a + I_b >= I_c; Ke must be
    positive semidefinite (Me positive definite is checked in :func:`modal_checks`).
    """
    mass = float(sid.mass)
    out = {"mass > 0": _entry(0.0 if mass > 0 else float("inf"), 0.0,
                              f"rigid-body mass m = {mass:.6g} kg (value 0 when positive)")}
    if not mass > 0:
        return out
    p = np.sort(np.linalg.eigvalsh(inertia_about_cm(sid)))
    scale = max(abs(p[-1]), 1e-300)
    out["inertia about CM positive definite"] = _entry(
        max(-p[0] / scale, 0.0) if p[0] > 0 else float("inf"), 0.0,
        f"principal moments about the CM {p[0]:.6g}, {p[1]:.6g}, {p[2]:.6g} kg m^2 "
        "(value -min/max, inf when one is <= 0)")
    out["inertia triangle inequalities"] = _entry(
        max((p[2] - p[0] - p[1]) / scale, 0.0), TRIANGLE_RTOL,
        "largest principal moment <= sum of the other two (value (I3 - I1 - I2)/I3)")
    if sid.nq:
        Ke = 0.5 * (sid.Ke.M0 + sid.Ke.M0.T)
        ev = np.linalg.eigvalsh(Ke)
        out["Ke positive semidefinite"] = _entry(
            max(-ev[0], 0.0) / max(abs(ev).max(), 1e-300), KE_PSD_RTOL,
            "modal stiffness has no negative eigenvalue (value -min/max)")
    return out


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
        out["6 zero-energy modes"] = _entry(abs(int(n) - FREE_BODY_RIGID_MODES), 0,
                                            f"the unconstrained FE model has {n} zero-energy modes "
                                            f"(value = |n - 6|)")
    if sid.nq:
        me = np.sqrt(np.abs(np.diag(sid.Me.M0)))
        i_max = max(np.max(np.linalg.eigvalsh(inertia_matrix(sid.J.M0))), 1e-300)
        ct = np.linalg.norm(sid.Ct.M0, axis=1) / (np.sqrt(sid.mass) * me)
        cr = np.linalg.norm(sid.Cr.M0, axis=1) / (np.sqrt(i_max) * me)
        out["free modes orthogonal to rigid motion"] = _entry(
            max(ct.max(), cr.max()), RIGID_ORTHOGONALITY_RTOL,
            "|Ct0_k|/sqrt(m Me_kk), |Cr0_k|/sqrt(I Me_kk): no rigid motion in the basis")
    return out


def normalise_external(checks) -> dict:
    """Checks from ``metadata["checks"]`` in the common form.

    Two forms are accepted: ``{name: {value, tolerance, passed|pass|ok, ...}}``, or one flat report
    of the reduction (scalars plus an overall ``passed`` flag): the flag becomes the check
    "FE comparison", each scalar an "info" entry.
    """
    checks = dict(checks or {})
    if isinstance(checks.get("passed"), bool):
        scalars = {k: v for k, v in checks.items()
                   if isinstance(v, (int, float)) and not isinstance(v, bool)}
        out = {"FE comparison": {
            "value": float(not checks["passed"]), "tolerance": 0.0, "passed": checks["passed"],
            "severity": "error", "description": "reduction vs full FE model (mass, CM, inertia, "
                                                "zero-energy modes, static deflection)"}}
        out.update({f"FE {k}": {"value": v, "tolerance": None, "passed": True, "severity": "info",
                                "description": "reported by the reduction"} for k, v in scalars.items()})
        return out
    out = {}
    for name, c in checks.items():
        if not isinstance(c, dict):
            continue
        passed = c.get("passed", c.get("pass", c.get("ok")))
        if passed is None and "value" in c and "tolerance" in c:
            passed = float(c["value"]) <= float(c["tolerance"])
        out[str(name)] = {"value": c.get("value"), "tolerance": c.get("tolerance"),
                          "passed": bool(passed), "severity": c.get("severity", "error"),
                          "description": c.get("description", "")}
    return out


def sid_checks(sid: SID) -> dict:
    """All checks of ``sid``: identities, modal data, free-body checks, and the FE comparisons."""
    meta = sid.metadata if isinstance(sid.metadata, dict) else {}
    return {**physical_checks(sid), **node_identities(sid), **inertia_identities(sid), **modal_checks(sid),
            **free_body_checks(sid), **normalise_external(meta.get("checks"))}


def failed_checks(checks: dict) -> list[str]:
    """Names of the failed checks of severity "error"."""
    return [name for name, c in checks.items() if not c["passed"] and c["severity"] == "error"]


def format_checks(checks: dict) -> str:
    """One line per check: status, name, value, tolerance."""
    def number(v):
        return f"{v:10.3e}" if isinstance(v, (int, float)) else f"{str(v):>10s}"

    lines = []
    for name, c in checks.items():
        flag = ("info" if c["severity"] == "info" else "ok  " if c["passed"]
                else "FAIL" if c["severity"] == "error" else "warn")
        lines.append(f"  {flag} {name:<42s} {number(c['value'])} (tol {number(c['tolerance'])})")
    return "\n".join(lines)
