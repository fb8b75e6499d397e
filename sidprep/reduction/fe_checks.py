"""The reduced body against the full FE model: mass, CM, inertia, zero-energy modes, static
deflection at the interface masters, eigenfrequencies (the checks run at export, sid-spec 7)."""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from sidprep.fe.linalg import eigen_modes
from sidprep.reduction.craig_bampton import interior_operator
from sidprep.reduction.interfaces import rigid_rows
from sidprep.reduction.modes import hz
from sidprep.sid.check import Check
from sidprep.sid.model import inertia_matrix

#: relative tolerance of the mass / CM / inertia check (spec: equal to round-off)
MASS_CHECK_TOL = 1e-10
#: eigenfrequencies of the basis vs the full FE model (Craig-Bampton truncation)
FREQUENCY_CHECK_TOL = 0.01
#: FEMBS promise for static deflection of the reduced body vs the full FE model
STATIC_CHECK_TOL = 0.01
#: columns per static solve of the checks
STATIC_BLOCK = 12
#: the eigenvalue count's conjugate gradients: relative residual (M norm) at convergence, iteration limit
COUNT_RTOL = 1e-10
COUNT_MAX_ITERATIONS = 200
#: boundary columns of the dynamic Schur complement per conjugate-gradient block (a reduction in
#: parts has thousands of coarse DOFs; the temporaries scale with the block)
COUNT_BLOCK = 48
#: the count's shift sits between the checked Ritz values and the next one; the checked set grows
#: over Ritz values within this factor (eigenvalues) of the last, so a degenerate pair is not split
COUNT_GAP = 1.1


def relieved_static_solve(red, P: np.ndarray) -> np.ndarray:
    """Exact full-model static deflection under loads P (n_model, nc), through the reduction's K_ii
    factor.  Free bodies: inertia relief, then the rigid part removed (mean-axis deflection), so
    that u = G P with G symmetric and G M R = 0 for the rigid motions R.  Solved STATIC_BLOCK
    columns at a time (the solve's temporaries scale with the columns: peak memory at 1M DOF)."""
    R, M = red.rigid, red.M_model
    u = np.empty(P.shape)
    for s in range(0, P.shape[1], STATIC_BLOCK):
        Pb = P[:, s:s + STATIC_BLOCK]
        if red.held is None:
            Pb = Pb - M @ (R @ np.linalg.solve(R.T @ (M @ R), R.T @ Pb))
        ub = red.static_solve(Pb)
        if red.held is None:
            ub -= R @ np.linalg.solve(R.T @ (M @ R), R.T @ (M @ ub))
        u[:, s:s + STATIC_BLOCK] = ub
    return u


def master_compliance_full(red) -> tuple[np.ndarray, np.ndarray]:
    """Static deflection of the full model at the master DOFs under unit master loads.

    Returns (load DOFs (nl,) model indices, C (nl, nl) deflection of DOF i under load j), from
    :func:`relieved_static_solve`.
    """
    loads = np.setdiff1d(red.im.master_dofs.ravel(), [] if red.held is None else red.held)
    if not len(loads):
        return loads, np.zeros((0, 0))
    P = np.zeros((red.im.n_model, len(loads)))
    P[loads, np.arange(len(loads))] = 1.0
    return loads, relieved_static_solve(red, P)[loads]


def eigenvalue_count(red, sigma: float) -> int | None:
    """Number of eigenvalues below ``sigma`` of the full model (held DOFs removed), rigid ones
    included, by Sylvester's law of inertia with the interior eliminated first (Wittrick-Williams):
    count = #{fixed-interface eigenvalues < sigma} + #{negative eigenvalues of S}, with S the exact
    dynamic Schur complement (:func:`dynamic_schur`).  None when it cannot be certified.  A reduction
    in parts counts over its parts (its factor's ``eigenvalue_count``, sidprep.reduction.substructured).
    """
    cb = red.cb
    by_parts = getattr(cb.interior_factor, "eigenvalue_count", None)
    if by_parts is not None:
        return by_parts(red, sigma)
    b = cb.boundary_dofs if red.held is None else cb.boundary_dofs[~np.isin(cb.boundary_dofs, red.held)]
    schur = dynamic_schur(red.K_model, red.M_model, cb.interior_factor, cb.basis[:, cb.n_boundary:],
                          (2 * np.pi * cb.fixed_interface_hz) ** 2, cb.boundary_dofs, b, sigma)
    if schur is None:
        return None
    below, S = schur
    return int(below + np.sum(np.linalg.eigvalsh(0.5 * (S + S.T)) < 0))


def dynamic_schur(K, M, factor, modes, mu, boundary, b, sigma: float):
    """(#{mu < sigma}, S) with S (len(b), len(b)) the exact dynamic Schur complement
    (K - sigma M)_bb - (K - sigma M)_bi (K - sigma M)_ii^-1 (K - sigma M)_ib, i = all DOFs but
    ``boundary`` (b a subset of it); or None when it cannot be certified.

    K, M : (n, n) sparse; factor : of K_ii; modes : (n, nm) fixed-interface modes, zero on the
    boundary, M_ii-orthonormal, eigenvalues mu (nm,) ascending.  (K - sigma M)_ii^-1 is applied
    exactly: on the modes spectrally, on their M_ii-orthogonal complement W by conjugate gradients on
    (I - sigma K_ii^-1 M_ii) y = K_ii^-1 g with the factor (condition number 1 / (1 - sigma /
    mu_(nm+1))).  None when that operator is not definite or the iteration does not converge (sigma
    above the computed fixed-interface spectrum).
    """

    n = K.shape[0]
    interior = np.ones(n, bool)
    interior[boundary] = False
    if len(mu) and sigma >= mu[-1]:
        return None

    def phi_t(v):                                         # Phi^T v without an interior copy of Phi
        full = np.zeros((n, v.shape[1]))
        full[interior] = v
        return modes.T @ full

    def phi(coef):
        return (modes @ coef)[interior]

    A_b = (K.tocsr()[b] - sigma * M.tocsr()[b]).tocsr()      # rows b of K - sigma M (sparse)
    F = A_b[:, np.flatnonzero(interior)].T.tocsc()          # (K - sigma M)_ib
    m_ii = interior_operator(M, interior).matmat

    def solve_w(v):                                       # (K_ii^-1 v, M_ii K_ii^-1 v), projected onto W
        w = np.asarray(factor.solve(v)).reshape(v.shape)
        w -= phi(phi_t(m_ii(w)))                          # the modes' round-off (M_ii-orthonormal to 1e-10)
        return w, m_ii(w)

    def shifted_solve(f):                                 # (K - sigma M)_ii^-1 f, exactly; None if not definite
        c = phi_t(f)
        g = f - m_ii(phi(c))
        # (I - sigma K_ii^-1 M_ii) y = K_ii^-1 g on W by conjugate gradients in the M_ii inner product
        # (the operator is self-adjoint there, eigenvalues 1 - sigma / mu >= 1 - sigma / mu_(ncb+1) > 0),
        # one column per boundary DOF, one solve and two M_ii products per step
        r, Mr = solve_w(g)
        y, p, Mp = np.zeros_like(r), r.copy(), Mr.copy()
        rr = rr0 = np.einsum("ij,ij->j", r, Mr)
        for _ in range(COUNT_MAX_ITERATIONS):
            active = rr > COUNT_RTOL ** 2 * rr0
            if not active.any():
                return phi(c / (mu - sigma)[:, None]) + y
            w, Mw = solve_w(Mp)
            pBp = np.einsum("ij,ij->j", p, Mp) - sigma * np.einsum("ij,ij->j", Mp, w)
            if np.any(pBp[active] <= 0):                  # not definite: sigma above mu_(ncb+1)
                return None
            alpha = np.where(active, rr / np.where(active, pBp, 1.0), 0.0)
            y += alpha * p
            r -= alpha * (p - sigma * w)
            Mr -= alpha * (Mp - sigma * Mw)
            rr, rr_old = np.einsum("ij,ij->j", r, Mr), rr
            beta = np.where(active, rr / np.where(active, rr_old, 1.0), 0.0)
            p = r + beta * p
            Mp = Mr + beta * Mp
        return None

    S = A_b[:, b].toarray()
    for s in range(0, len(b), COUNT_BLOCK):               # COUNT_BLOCK columns at a time (peak memory)
        X = shifted_solve(F[:, s:s + COUNT_BLOCK].toarray())
        if X is None:
            return None
        S[:, s:s + COUNT_BLOCK] -= F.T @ X
    return int(np.sum(mu < sigma)), S


def frequency_bounds(red, m: int) -> tuple[np.ndarray, np.ndarray, str]:
    """Certified bounds on the m lowest elastic eigenvalues of the full model from the reduction's
    own factor, without a full eigen solve: (lower (m,), upper (m,)) in (rad/s)^2 and "" - or NaN
    bounds and the reason when they cannot be certified.

    The operator A = G M (G: :func:`relieved_static_solve`) is self-adjoint in the M inner product
    with eigenvalues nu = 1/lambda of the elastic modes.  For the lowest Craig-Bampton Ritz vectors X
    (M-orthonormal; one multi-column static solve gives A X):

    * upper bounds lambda_k <= theta_k (Rayleigh-Ritz, Poincare);
    * the Ritz values nu_j of A in span X, grouped into clusters whose residual intervals
      nu_j +- ||R_c||_M overlap (R_c = A X_c - X_c diag(nu_c)); each cluster's interval holds as many
      eigenvalues of A as it has vectors (Kahan), and exactly that many when the intervals are disjoint
      and :func:`eigenvalue_count` finds exactly m elastic eigenvalues below sigma (between theta_m and
      the next Ritz value) - so no eigenvalue of the full model is missing from the basis;
    * then |nu_true - nu_j| <= ||R_c||^2 / delta_c (quadratic residual bound for clusters, Li & Li 2013),
      delta_c the distance of the cluster to the rest of the spectrum (other intervals, 1/sigma).
    """

    cb = red.cb
    held = np.zeros(cb.K.shape[0], bool)
    if red.held is not None:
        held[:cb.n_boundary] = np.isin(cb.boundary_dofs, red.held)
    lam, Z = sla.eigh(cb.K[np.ix_(~held, ~held)], cb.M[np.ix_(~held, ~held)])
    n_rigid = 6 if red.held is None else 0
    nan = np.full(m, np.nan)
    checked = m                                           # ... and the modes clustered with the m-th
    while n_rigid + checked < len(lam) and lam[n_rigid + checked] < COUNT_GAP * lam[n_rigid + checked - 1]:
        checked += 1
    if len(lam) <= n_rigid + checked:
        return nan, nan, "the Craig-Bampton space has no mode above the checked ones"
    sigma = float(np.sqrt(lam[n_rigid + checked - 1] * lam[n_rigid + checked]))
    count = eigenvalue_count(red, sigma)
    if count is None:
        return nan, nan, "the eigenvalue count did not converge (shift above the fixed-interface modes)"
    if count != n_rigid + checked:
        return nan, nan, (f"the full model has {count - n_rigid} elastic eigenvalues below "
                          f"{np.sqrt(sigma) / (2 * np.pi):.5g} Hz, the basis {checked}")
    theta = lam[n_rigid:n_rigid + checked]
    wanted, m = m, checked
    Z_all = np.zeros((cb.K.shape[0], m))
    Z_all[~held] = Z[:, n_rigid:n_rigid + m]
    X = cb.basis @ Z_all                                  # no column copy of the basis
    AX = relieved_static_solve(red, red.M_model @ X)
    H = X.T @ (red.M_model @ AX)
    nu, W = np.linalg.eigh(0.5 * (H + H.T))
    nu, W = nu[::-1], W[:, ::-1]                          # largest nu = lowest frequency first
    R = AX @ W                                            # the residuals, with few n x m temporaries
    del AX
    X = X @ W
    X *= nu
    R -= X
    del X
    clusters = [[j] for j in range(m)]

    def norm(c):
        Rc = R[:, c]
        return float(np.sqrt(max(np.linalg.eigvalsh(Rc.T @ (red.M_model @ Rc)).max(), 0.0)))

    while True:
        r = [norm(c) for c in clusters]
        merged = next((i for i in range(len(clusters) - 1)
                       if nu[clusters[i][-1]] - r[i] <= nu[clusters[i + 1][0]] + r[i + 1]), None)
        if merged is None:
            break
        clusters[merged:merged + 2] = [clusters[merged] + clusters[merged + 1]]
    low = [nu[c[-1]] - ri for c, ri in zip(clusters, r)]
    high = [nu[c[0]] + ri for c, ri in zip(clusters, r)]
    if low[-1] <= 1.0 / sigma:
        return nan, nan, "the residual bounds do not separate the checked modes from the higher ones"
    upper_nu = np.empty(m)
    for i, (c, ri) in enumerate(zip(clusters, r)):
        delta = nu[c[-1]] - 1.0 / sigma                     # to the eigenvalues below 1/sigma
        if i + 1 < len(clusters):
            delta = min(delta, nu[c[-1]] - high[i + 1])
        if i > 0:
            delta = min(delta, low[i - 1] - nu[c[0]])
        upper_nu[c] = nu[c] + min(ri, ri ** 2 / delta)
    return (1.0 / upper_nu)[:wanted], np.minimum(theta, 1.0 / nu)[:wanted], ""


def full_model_frequencies(red, count: int) -> np.ndarray:
    """The ``count`` lowest elastic frequencies (Hz) of the full model (held DOFs removed) by a full
    eigen solve: the independent reference, and the fallback of :func:`fe_checks` when the bounds of
    :func:`frequency_bounds` cannot be certified."""

    keep = np.setdiff1d(np.arange(red.im.n_model), [] if red.held is None else red.held)
    ev = eigen_modes(red.K_model[keep][:, keep], red.M_model[keep][:, keep], count=count)
    return ev.frequencies_hz[ev.n_rigid:][:count]


def frequency_checks(red) -> dict:
    """The eigen-kind frequencies of the basis against the full model's, JSON-ready:
    ``eigen_frequency_max_rel_error`` the largest relative error - a certified upper bound
    (:func:`frequency_bounds`), or, when the bounds cannot be certified, the error against a full
    eigen solve (``frequency_check`` says which); ``frequencies_full_hz_bounds`` [low, high] per mode."""

    f_eig = red.basis.frequencies_hz[np.array(red.basis.kinds) == "eigen"]
    lower, upper, reason = frequency_bounds(red, len(f_eig))
    if reason:
        f_low = f_high = full_model_frequencies(red, len(f_eig))
        method = f"full-model eigen solve ({reason})"
    else:
        f_low, f_high = hz(lower), hz(upper)
        method = "certified bounds from the reduction's factor"
    return {"frequency_check": method, "frequencies_full_hz_bounds": np.column_stack([f_low, f_high]).tolist(),
            "eigen_frequency_max_rel_error": float(np.max(np.maximum(f_eig / f_low - 1, 1 - f_eig / f_high)))}


def fe_checks(red, mesh, M_fe, sid, full_frequencies=True) -> dict:
    """Reduced body vs full FE model (module docstring step 6); JSON-ready dict (the frequency part:
    :func:`frequency_checks`)."""

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
    checks["frequency_response_modes"] = bool(np.isfinite(red.basis.frm_omega_hz))
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
        checks.update(frequency_checks(red))
        passed = passed and checks["eigen_frequency_max_rel_error"] < FREQUENCY_CHECK_TOL
    checks["passed"] = bool(passed)
    checks["static_within_fembs_promise"] = bool(checks["static_deflection_max_rel_error"] < STATIC_CHECK_TOL)
    return checks


def structured_checks(checks: dict) -> dict:
    """The FE comparison as named checks {name: Check} (sidprep.sid.check) for the SID metadata."""
    out = {
        "FE mass": Check.measured(checks["mass_rel_error"], MASS_CHECK_TOL,
                                  f"SID mass vs full consistent mass matrix ({checks['mass_fe_kg']:.6g} kg), relative"),
        "FE centre of mass": Check.measured(checks["cm_rel_error"], MASS_CHECK_TOL, "mdCM vs full FE, relative"),
        "FE inertia": Check.measured(checks["inertia_rel_error"], MASS_CHECK_TOL, "J vs full FE, relative"),
        "FE zero-energy modes": Check.measured(
            abs(checks["zero_energy_modes"] - checks["zero_energy_modes_expected"]), 0.0,
            f"reduced model: {checks['zero_energy_modes']} zero-energy modes, "
            f"expected {checks['zero_energy_modes_expected']}"),
        "FE static deflection": Check.measured(checks["static_deflection_max_rel_error"], STATIC_CHECK_TOL,
                                               "largest relative error of a master's deflection under a unit "
                                               "force (FEMBS promise < 1 %)", "warning"),
        "FE static rotation": Check.measured(checks["static_rotation_max_rel_error"], None,
                                             "largest relative error of a master's rotation under a unit moment",
                                             "info"),
    }
    if "rigid_energy_ratio" in checks:
        out["FE rigid-body energy"] = Check.measured(checks["rigid_energy_ratio"], checks["rigid_energy_tol"],
                                                     "imported K: strain energy of the six rigid motions / the "
                                                     "same without cancellation (zero for a free model)")
    if "eigen_frequency_max_rel_error" in checks:
        out["FE eigenfrequencies"] = Check.measured(checks["eigen_frequency_max_rel_error"], FREQUENCY_CHECK_TOL,
                                                    "eigen-kind coordinates vs the full model, relative (certified "
                                                    "bound or full eigen solve)")
    return out


def static_advice(checks: dict) -> str:
    """What to change when the static deflection misses the 1 % promise, for the options used."""
    if checks.get("frequency_response_modes", True):
        return "frequency-response modes above the cut-off were dropped; raise --cutoff-factor or --modes"
    return ("the basis has eigenmodes only (--no-frm): leave out --no-frm to add the frequency-response "
            "modes, or raise --modes (expected when only the dynamics of the kept modes matter)")


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
                     f"(tol {FREQUENCY_CHECK_TOL:g}; {checks['frequency_check']}); full model "
                     + ", ".join(f"{lo:.1f}" if hi - lo < 0.05 else f"{lo:.1f}-{hi:.1f}"
                                 for lo, hi in checks["frequencies_full_hz_bounds"]) + " Hz")
    if "stress_static_max_rel_error" in checks:
        lines.append(f"  modal stresses under unit master forces vs the full model: max rel. error "
                     f"{100 * checks['stress_static_max_rel_error']:.3f} %")
    if "rigid_energy_ratio" in checks:
        lines.append(f"  imported matrices ({checks['matrices_format']}): rigid-body strain energy ratio "
                     f"{checks['rigid_energy_ratio']:.1e} (tol {checks['rigid_energy_tol']:g})")
    if "fe_code_frequencies_hz" in checks:
        lines.append("  the FE code's own eigenfrequencies " + ", ".join(f"{f:.1f}" for f in checks["fe_code_frequencies_hz"])
                     + f" Hz: SID max rel. difference {checks['fe_code_frequency_max_rel_error']:.1e}")
    if not checks["static_within_fembs_promise"]:
        lines.append("  WARNING: static deflection error above 1 %: " + static_advice(checks))
    lines.append("  checks (mass, CM, inertia, zero-energy modes, eigenfrequencies) "
                 + ("passed" if checks["passed"] else "FAILED"))
    return "\n".join(lines)
