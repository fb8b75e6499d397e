"""The reduced body against the full FE model: mass, CM, inertia, zero-energy modes, static
deflection at the interface masters, eigenfrequencies (the checks run at export, sid-spec 7)."""

from __future__ import annotations

import numpy as np

#: relative tolerance of the mass / CM / inertia check (spec: equal to round-off)
MASS_CHECK_TOL = 1e-10
#: eigenfrequencies of the basis vs the full FE model (Craig-Bampton truncation)
FREQUENCY_CHECK_TOL = 0.01
#: FEMBS promise for static deflection of the reduced body vs the full FE model
STATIC_CHECK_TOL = 0.01


def master_compliance_full(red) -> tuple[np.ndarray, np.ndarray]:
    """Static deflection of the full model at the master DOFs under unit master loads.

    Returns (load DOFs (nl,) model indices, C (nl, nl) deflection of DOF i under load j).  Free
    bodies: inertia relief, then the rigid part removed (mean-axis deflection).
    """
    loads = np.setdiff1d(red.im.master_dofs.ravel(), [] if red.held is None else red.held)
    if not len(loads):
        return loads, np.zeros((0, 0))
    P = np.zeros((red.im.n_model, len(loads)))
    P[loads, np.arange(len(loads))] = 1.0
    R, M = red.rigid, red.M_model
    if red.held is None:
        P = P - M @ (R @ np.linalg.solve(R.T @ (M @ R), R.T @ P))
    u = red.static_solve(P)
    if red.held is None:
        u = u - R @ np.linalg.solve(R.T @ (M @ R), R.T @ (M @ u))
    return loads, u[loads]


def fe_checks(red, mesh, M_fe, sid, full_frequencies=True) -> dict:
    """Reduced body vs full FE model (module docstring step 6); JSON-ready dict."""
    from sidprep.interfaces import rigid_rows
    from sidprep.linalg import eigen_modes
    from sidprep.sid import inertia_matrix

    R = rigid_rows(mesh.points).reshape(-1, 6)
    A = R.T @ (M_fe @ R)                                  # sid-spec 4.3 Form A
    mass = A[0, 0]
    md = np.array([A[5, 1], A[3, 2], A[4, 0]])           # skew(md) = Sr^T M St
    checks = {
        "mass_fe_kg": float(mass),
        "mass_rel_error": abs(sid.mass - mass) / mass,
        "cm_rel_error": float(np.linalg.norm(sid.mdCM.M0.ravel() - md) / max(np.linalg.norm(md), mass * np.ptp(mesh.points))),
        "inertia_rel_error": float(np.abs(inertia_matrix(sid.J.M0) - A[3:, 3:]).max() / np.abs(A[3:, 3:]).max()),
    }
    checks["zero_energy_modes"] = red.basis.zero_energy_modes
    checks["zero_energy_modes_expected"] = 6 if red.held is None else 0
    loads, C_full = master_compliance_full(red)
    Pm = red.Phi_model[loads]
    C_red = Pm @ np.diag(1.0 / (2 * np.pi * red.basis.frequencies_hz) ** 2) @ Pm.T
    err = np.abs(np.diag(C_red) - np.diag(C_full)) / np.abs(np.diag(C_full))
    force = np.isin(loads, red.im.master_dofs[:, :3])
    checks["static_deflection_max_rel_error"] = float(err[force].max()) if force.any() else 0.0
    checks["static_rotation_max_rel_error"] = float(err[~force].max()) if (~force).any() else 0.0
    checks["static_deflection_rel_error_by_interface"] = {
        itf.name: float(err[np.isin(loads, m[:3])].max()) for itf, m in zip(red.im.interfaces, red.im.master_dofs)
        if np.isin(loads, m[:3]).any()}
    passed = (checks["mass_rel_error"] < MASS_CHECK_TOL and checks["cm_rel_error"] < MASS_CHECK_TOL
              and checks["inertia_rel_error"] < MASS_CHECK_TOL
              and checks["zero_energy_modes"] == checks["zero_energy_modes_expected"])
    if full_frequencies:
        # as many full-model modes as the basis has coordinates (all at or below the cut-off);
        # Rayleigh-Ritz: the k-th reduced frequency bounds the k-th full one from above
        f_red = np.sort(red.basis.frequencies_hz)
        keep = np.setdiff1d(np.arange(red.im.n_model), [] if red.held is None else red.held)
        ev = eigen_modes(red.K_model[keep][:, keep], red.M_model[keep][:, keep], count=len(f_red))
        f_full = ev.frequencies_hz[ev.n_rigid:][:len(f_red)]
        f_eig = red.basis.frequencies_hz[np.array(red.basis.kinds) == "eigen"]
        checks["frequencies_full_hz"] = f_full.tolist()
        checks["frequencies_reduced_hz"] = f_red.tolist()
        checks["eigen_frequency_max_rel_error"] = float(np.max(np.abs(f_eig - f_full[:len(f_eig)]) / f_full[:len(f_eig)]))
        checks["frequency_rel_error_up_to_cutoff"] = (np.abs(f_red - f_full) / f_full).tolist()
        passed = passed and checks["eigen_frequency_max_rel_error"] < FREQUENCY_CHECK_TOL
    checks["passed"] = bool(passed)
    checks["static_within_fembs_promise"] = bool(checks["static_deflection_max_rel_error"] < STATIC_CHECK_TOL)
    return checks


def structured_checks(checks: dict) -> dict:
    """The FE comparison as named checks {value, tolerance, passed, severity, description} for the
    SID metadata (sidprep.checks reads this form)."""
    def entry(value, tol, severity, description):
        return {"value": float(value), "tolerance": tol, "severity": severity, "description": description,
                "passed": bool(tol is None or value <= tol)}

    out = {
        "FE mass": entry(checks["mass_rel_error"], MASS_CHECK_TOL, "error",
                         f"SID mass vs full consistent mass matrix ({checks['mass_fe_kg']:.6g} kg), relative"),
        "FE centre of mass": entry(checks["cm_rel_error"], MASS_CHECK_TOL, "error", "mdCM vs full FE, relative"),
        "FE inertia": entry(checks["inertia_rel_error"], MASS_CHECK_TOL, "error", "J vs full FE, relative"),
        "FE zero-energy modes": entry(abs(checks["zero_energy_modes"] - checks["zero_energy_modes_expected"]), 0.0,
                                      "error", f"reduced model: {checks['zero_energy_modes']} zero-energy modes, "
                                               f"expected {checks['zero_energy_modes_expected']}"),
        "FE static deflection": entry(checks["static_deflection_max_rel_error"], STATIC_CHECK_TOL, "warning",
                                      "largest relative error of a master's deflection under a unit force "
                                      "(FEMBS promise < 1 %)"),
        "FE static rotation": entry(checks["static_rotation_max_rel_error"], None, "info",
                                    "largest relative error of a master's rotation under a unit moment"),
    }
    if "eigen_frequency_max_rel_error" in checks:
        out["FE eigenfrequencies"] = entry(checks["eigen_frequency_max_rel_error"], FREQUENCY_CHECK_TOL, "error",
                                           "eigen-kind coordinates vs a full-model eigen solve, relative")
    return out


def format_checks(checks: dict) -> str:
    """The check table printed at export."""
    lines = ["FE comparison (reduced body vs full FE model):",
             f"  mass {checks['mass_fe_kg']:.6g} kg, rel. error mass {checks['mass_rel_error']:.1e}, "
             f"CM {checks['cm_rel_error']:.1e}, inertia {checks['inertia_rel_error']:.1e} (tol {MASS_CHECK_TOL:g})",
             f"  zero-energy modes {checks['zero_energy_modes']} (expected {checks['zero_energy_modes_expected']})",
             f"  static deflection at the masters under unit forces: max rel. error "
             f"{100 * checks['static_deflection_max_rel_error']:.3f} % (FEMBS promise < {100 * STATIC_CHECK_TOL:g} %); "
             f"rotation under unit moments {100 * checks['static_rotation_max_rel_error']:.2f} %"]
    if "eigen_frequency_max_rel_error" in checks:
        lines.append(f"  eigenfrequencies: max rel. error {checks['eigen_frequency_max_rel_error']:.1e} "
                     f"(tol {FREQUENCY_CHECK_TOL:g}); full model "
                     + ", ".join(f"{f:.1f}" for f in checks["frequencies_full_hz"]) + " Hz")
    if not checks["static_within_fembs_promise"]:
        lines.append("  WARNING: static deflection error above 1 %: frequency-response modes above the cut-off were "
                     "dropped; raise --cutoff-factor or --modes")
    lines.append("  checks (mass, CM, inertia, zero-energy modes, eigenfrequencies) "
                 + ("passed" if checks["passed"] else "FAILED"))
    return "\n".join(lines)
