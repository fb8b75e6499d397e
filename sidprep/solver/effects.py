"""Which terms of the FFR equations (sid-spec 5.2) a simulation assembles, and what was left out.

A scene names the effects it wants, or ``"auto"``.  Each effect switches a group of SID terms
(docs/sid-spec.md 5.4); only the switched-on terms are assembled.  Every run ends with an
:class:`EffectsReport`: what was included, what was left out, and for each left-out effect an
estimate of the change it would make to the body's modal coordinates, computed from the run's
own result, with a WARNING above :data:`WARN_LEVEL`.

The effect names and their SID terms: sidprep/solver/model/effects.py.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg

from sidprep.solver.compile.layout import pack_terms
from sidprep.solver.core.effects import elastic_rows
from sidprep.solver.integrators.genalpha import genalpha_parameters
from sidprep.solver.model.bodies import Ground
from sidprep.solver.model.effects import DESCRIPTIONS, EFFECTS

#: a left-out effect whose estimated change of the modal coordinates (MEASURE) exceeds this gets
#: a WARNING in the report
WARN_LEVEL = 0.01


@dataclass(frozen=True)
class EffectEntry:
    """One line of the effects report for one body.

    included : bool
    available : bool   -- the SID holds the data for this effect
    reason : str       -- why it was included/left out (for ``auto``: the scene property)
    estimate : float   -- estimated change of the modal coordinates if the effect were included,
                          relative (NaN when not estimated: included or not in the SID)
    measure : str      -- what ``estimate`` is (MEASURE)
    """

    effect: str
    included: bool
    available: bool
    reason: str
    estimate: float = float("nan")
    measure: str = ""

    @property
    def warning(self) -> bool:
        return bool((not self.included) and self.estimate > WARN_LEVEL)  # NaN: False, inf: True


@dataclass(frozen=True)
class EffectsReport:
    """Effects included / left out per body, with size estimates of the left-out ones."""

    bodies: dict = field(default_factory=dict)  # body name -> tuple[EffectEntry, ...]
    notes: tuple[str, ...] = ()

    @property
    def warnings(self) -> list[str]:
        out = [
            f"WARNING: body '{b}': left out {e.effect} ({DESCRIPTIONS[e.effect]}) but it would "
            + (f"change the modal coordinates by an estimated {e.measure} = {e.estimate:.3g}, above {WARN_LEVEL:.0%}"
               if np.isfinite(e.estimate) else "deform the body, which the run leaves undeformed")
            for b, entries in self.bodies.items()
            for e in entries
            if e.warning
        ]
        return out + [n for n in self.notes if n.startswith("WARNING")]

    def text(self) -> str:
        """Human-readable report (one block per body, warnings last)."""
        lines = []
        for b, entries in self.bodies.items():
            lines.append(f"body '{b}':")
            for e in entries:
                state = "included" if e.included else ("left out" if e.available else "not in SID")
                est = f"  [estimated {e.measure} = {e.estimate:.3g}]" if not np.isnan(e.estimate) else ""
                lines.append(f"  {e.effect:24s} {state:9s} {e.reason}{est}")
        lines += [f"note: {n}" for n in self.notes if not n.startswith("WARNING")]
        lines += self.warnings
        return "\n".join(lines)

    def as_dict(self) -> dict:
        """JSON-serialisable form (for results files)."""
        return {
            "bodies": {
                b: [
                    {
                        "effect": e.effect,
                        "included": e.included,
                        "available": e.available,
                        "reason": e.reason,
                        "estimate": None if not np.isfinite(e.estimate) else float(e.estimate),
                        "measure": e.measure,
                        "warning": e.warning,
                    }
                    for e in entries
                ]
                for b, entries in self.bodies.items()
            },
            "notes": list(self.notes),
            "warnings": self.warnings,
        }

    def estimates(self) -> dict:
        """{body: {left-out effect: {"value": estimate, "measure": MEASURE}}}; value None: infinite
        (the run leaves the body undeformed, the effect would deform it)."""
        return {b: {e.effect: {"value": float(e.estimate) if np.isfinite(e.estimate) else None, "measure": e.measure}
                    for e in entries if not np.isnan(e.estimate)}
                for b, entries in self.bodies.items()}


# ---------------------------------------------------------------------------- choosing effects
def _scene_facts(system, body) -> dict:
    """Properties of the scene that decide ``auto`` for one body."""
    attached = [j for j in system.joints if body in (j.marker1.body, j.marker2.body)]
    fixed_to_ground = any(j.kind == "fixed" and isinstance(
        (j.marker2 if j.marker1.body is body else j.marker1).body, Ground) for j in attached)
    return {
        "gravity": bool(np.any(system.gravity)),
        "can_rotate": not fixed_to_ground,
        "loaded_nodes": any(m.k0f is not None or m.k0m is not None for m in body.markers),
    }


def assembled(effects: set, avail: dict) -> set:
    """The effects a run assembles for the named ``effects``: with gravity also the coupling
    (gravity's modal force Ct0 g uses the coupling matrix Ct0)."""
    return effects | ({"coupling"} if "gravity" in effects and avail["coupling"] else set())


def choose_effects(system, body, spec) -> tuple[set[str], dict[str, str]]:
    """Effects to assemble for one flexible body and the reason for each decision.

    spec : "auto" or a set of names (from ``parse_effects``).  Explicitly named effects that
    the SID cannot provide are reported as not available.
    """
    avail = body.available()
    kom_only = body.oe1_is_kom_only()
    if spec != "auto":
        reasons = {e: ("named by the scene" if e in spec else "not named by the scene") for e in EFFECTS}
        chosen = assembled({e for e in spec if avail[e]}, avail)
        if "coupling" in chosen and "coupling" not in spec:
            reasons["coupling"] = "not named, kept: gravity's modal force Ct0 g uses the coupling matrix Ct0"
        if "centrifugal_stiffening" in chosen and kom_only:
            reasons["centrifugal_stiffening"] = ("named by the scene; WARNING: Oe.M1 holds only Kom "
                                                 "(softening) without K0omega")
        return chosen, reasons
    f = _scene_facts(system, body)
    chosen, reasons = set(), {}

    def pick(effect: str, include: bool, why: str) -> None:
        if include and avail[effect]:
            chosen.add(effect)
        reasons[effect] = why if avail[effect] else "SID does not provide it"

    pick("gravity", f["gravity"], "gravity is set" if f["gravity"] else "no gravity in the scene")
    for e in ("coupling", "coriolis", "centrifugal"):
        pick(e, True, "always kept (cheap, zeroth order)")
    pick("damping", True, "the SID has De")
    pick("preload", True, "the SID has ksigma")
    stiff_ok = f["can_rotate"] and not kom_only
    pick("centrifugal_stiffening", stiff_ok,
         "Oe.M1 holds only Kom (softening) without K0omega: both left out (docs/sid-spec.md 5.4)" if kom_only
         else ("body can rotate: Kom + K0omega kept together" if f["can_rotate"]
               else "body is fixed to ground"))
    pick("inertia_change", f["can_rotate"],
         "body can rotate: J.M1 keeps Gr0 / Oe0 energy-consistent (first-order Lagrangian)"
         if f["can_rotate"] else "body is fixed to ground")
    pick("second_order_inertia", False, "second order, usually dropped (docs/sid-spec.md 5.4)")
    accel = f["gravity"] or f["can_rotate"]
    pick("acceleration_stiffening", accel, "gravity / body accelerations present" if accel
         else "no gravity and body fixed")
    pick("load_stiffening", f["loaded_nodes"], "node markers with K0F/K0M carry loads or joints"
         if f["loaded_nodes"] else "no node marker with K0F/K0M")
    return chosen, reasons


# ---------------------------------------------------------------------------- size estimates
#: what every estimate is: the largest change of the body's modal coordinates the left-out effect
#: would make, relative to their largest value, both in the mass norm |x| = sqrt(x^T Me x)
MEASURE = "max |dq| / max |q|"
#: output samples (evenly spread) at which the left-out terms are evaluated
ESTIMATE_SAMPLES = 200


#: the number of signals the left-out terms are weighted by (``signals``)
N_SIGNALS = 19


def signals(w, a, wdot, g) -> np.ndarray:
    """The N_SIGNALS signals the elastic rows of the body equations are linear in, (n, 19):
    1, the squares and products w_hat of omega (6), omega (3), a_O (3), omega_dot (3) and g (3),
    all in K (sid-spec 5.2: Oe w_hat, Ge(w) qd, Ct(q) a_O + Cr(q) w_dot, Ct g, ksigma, De qd).
    w, a, wdot, g : (n, 3)."""
    w_hat = np.stack([w[:, 0] ** 2, w[:, 1] ** 2, w[:, 2] ** 2, w[:, 0] * w[:, 1], w[:, 1] * w[:, 2],
                      w[:, 0] * w[:, 2]], axis=1)
    return np.concatenate([np.ones((len(w), 1)), w_hat, w, a, wdot, g], axis=1)


def probe_states() -> tuple[np.ndarray, ...]:
    """N_SIGNALS states (w, a, wdot, g), (19, 3) each, whose signals are independent: at rest;
    omega = +-e_i and e_i + e_j; a_O, omega_dot and g = e_i."""
    e = np.eye(3)
    zero = np.zeros((1, 3))
    w = np.vstack([zero, e, -e, e + np.roll(e, 1, axis=0), np.zeros((9, 3))])
    a, wdot, g = (np.zeros((N_SIGNALS, 3)) for _ in range(3))
    a[10:13], wdot[13:16], g[16:19] = e, e, e
    return w, a, wdot, g


def signal_coefficients(rows, probe_signals, modes) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The left-out modal force, stiffness and damping per signal, from the difference of
    ``elastic_rows`` with and without the effect at the probe states: force (19, nq) and, in
    modal coordinates (Phi^T dK Phi, Phi^T dC Phi), stiffness and damping (19, nq, nq)."""
    nq = modes.shape[0]
    coef = np.linalg.solve(probe_signals, rows.reshape(N_SIGNALS, -1)).reshape(rows.shape)
    return (coef[:, 0] @ modes, np.swapaxes(coef[:, 1:1 + nq] @ modes, 1, 2),
            np.swapaxes(coef[:, 1 + nq:] @ modes, 1, 2))


def free_modes(ke, me) -> tuple[np.ndarray, np.ndarray]:
    """omega (nq,) rad/s and the mass-normalised modes (nq, nq) of (Ke, Me) (nq, nq)."""
    lam, modes = scipy.linalg.eigh(ke, me)
    return np.sqrt(np.maximum(lam, 0.0)), modes


def frequency_shifts(stiffness, damping, omega) -> tuple[np.ndarray, np.ndarray]:
    """Per sample and mode: the change of omega_k^2 (1/s^2) and the added decay rate (1/s) that
    the left-out terms make, (nt, nq) each.

    stiffness, damping : (nt, nq, nq) modal dK, dC (Phi^T dK Phi).  The modal system
    eta'' + dC eta' + (Omega^2 + dK) eta = 0 at eta ~ exp(i w t), w ~ omega_k, couples mode k to
    mode j by Z_kj = dK_kj + i omega_k dC_kj.  Each mode moves first to the level
    L_k = omega_k^2 + Z_kk; each other mode j adds the two-level (2 x 2 eigenvalue) shift
    D/2 (sqrt(1 + 4 Z_kj Z_jk / D^2) - 1), D = L_k - L_j: the second-order perturbation
    Z_kj Z_jk / D when |Z| << |D|, sqrt(Z_kj Z_jk) when the levels coincide (how gyroscopic
    terms split a pair).  The imaginary part of d(omega_k^2) = 2 omega_k sigma_k is the decay.
    """
    row = omega[None, :, None]
    z, zt = stiffness, np.swapaxes(stiffness, 1, 2)
    if np.any(damping):
        z, zt = z + 1j * row * damping, zt + 1j * row * np.swapaxes(damping, 1, 2)
    diagonal = np.arange(omega.size)
    level = omega**2 + z[:, diagonal, diagonal]
    pair = z * zt
    half = 0.5 * (level[:, :, None] - level[:, None, :])
    apart = half != 0.0
    growth = np.where(apart, 1.0 + pair / np.where(apart, half, 1.0) ** 2, 1.0)
    degenerate = ~apart
    degenerate[:, diagonal, diagonal] = False
    if np.iscomplexobj(growth) or np.any(growth < 0.0) or np.any(degenerate):
        growth, pair = growth.astype(complex), pair.astype(complex)  # complex roots
    two_level = half * (np.sqrt(growth) - 1.0)
    two_level[degenerate] = np.sqrt(pair[degenerate])
    two_level[:, diagonal, diagonal] = z[:, diagonal, diagonal]
    shift = two_level.sum(axis=2)
    return shift.real, shift.imag / (2.0 * np.maximum(omega, 1e-300))


def cumulative(t, rate, forget=0.0) -> np.ndarray:
    """int_0^t rate(s) exp(-forget (t - s)) ds (nt, nq) by the trapezoidal rule over the samples
    t (nt,) s; forget (nq,) 1/s or 0: the plain integral.  The phase error of a damped mode's
    vibration: what vibrates at t was excited within its decay time 1 / forget, so it carries the
    frequency error of that time only (the sum of its parts, each decaying since it was
    excited)."""
    out = np.zeros(rate.shape)
    for j in range(1, len(t)):
        dt = t[j] - t[j - 1]
        fade = np.exp(-forget * dt)
        out[j] = fade * out[j - 1] + 0.5 * dt * (fade * rate[j - 1] + rate[j])
    return out


def genalpha_phase_response(omega, h: float, rho_inf: float) -> np.ndarray:
    """d(omega_num) / d(omega) of generalised-alpha at step h (s) for each modal frequency omega
    (nq,) rad/s: how much of a physical frequency shift the integrator's free vibration shows
    (1 when omega h << 1; 1 / (1 + (omega h / 2)^2) for the trapezoidal rule, rho_inf = 1).

    omega_num = |arg lambda| / h of the principal eigenvalue lambda of the one-step map of
    x'' + omega^2 x = 0 (Chung & Hulbert 1993; state x, v, a, ud; sidprep/solver/integrators/genalpha.py).
    """
    am, af, gamma, beta = genalpha_parameters(rho_inf)

    def frequency(w):
        c = (1 - af) / (1 - am)
        maps = np.zeros((w.size, 4, 4))
        for i, unit in enumerate(np.eye(4)):  # columns: the step applied to x, v, a, ud = e_i
            x, v, a, ud = unit
            lag = (af * ud - am * a) / (1 - am)
            ud1 = -w**2 * (x + h * v + h * h * ((0.5 - beta) * a + beta * lag)) / (1 + w**2 * h * h * beta * c)
            a1 = lag + c * ud1
            maps[:, :, i] = np.stack([x + h * v + h * h * ((0.5 - beta) * a + beta * a1),
                                      v + h * ((1 - gamma) * a + gamma * a1), a1, ud1], axis=1)
        lam = np.linalg.eigvals(maps)  # the principal pair has the largest imaginary parts
        principal = lam[np.arange(w.size), np.argmax(np.abs(lam.imag), axis=1)]  # (the spurious roots are real)
        return np.abs(np.angle(principal)) / h

    dw = 1e-4 * np.maximum(omega, 1e-300)
    return (frequency(omega + dw) - frequency(np.maximum(omega - dw, 0.0))) / (2 * dw)


def modal_change(t, amplitude, force, stiffness, damping, omega, response=1.0, decay0=0.0) -> np.ndarray:
    """Estimated |d eta(t)| (nt,) the left-out terms would make to the mass-normalised modal
    coordinates eta (q = Phi eta) of a run; t (nt,) s, force (nt, nq) = Phi^T df, amplitude
    (nt, nq) of the free vibration (``free_vibration``), response (nq,) or 1: the part of a
    frequency shift the integrator shows (``genalpha_phase_response``).

    Two parts per mode k of the modal oscillators eta_k'' + omega_k^2 eta_k = Phi_k^T f, whose
    stiffness the left-out terms change to omega_k^2 + d(omega_k^2) (``frequency_shifts``):
    the quasi-static response |Phi_k^T df| / (omega_k^2 + d(omega_k^2)) to the added force
    (infinite when the mode loses its stiffness: buckling), and the error of the free vibration:
    a mode vibrating with amplitude a_k at the shifted frequency
    sqrt(omega_k^2 + d(omega_k^2)) that decays faster by sigma_k drifts by the phasor difference
    a_k |1 - exp(i r_k int d(omega_k) dt - int sigma_k dt)| (at most 2 a_k; for a small shift the
    accumulated phase (dk_k / k_k) / 2 omega_k T), r_k = ``response``; a mode with the decay
    rate decay0_k (nq,; 1/s: 1/2 Phi_k^T De Phi_k of the kept damping) accumulates its phase over
    its decay time only (``cumulative``: the vibration present at t was excited since
    t - 1 / decay0_k; on examples/engine, whose rod's 329 Hz bending decays in ~25 ms, the
    whole-run phase overestimated a 1 s run's change 41x).
    """
    shift, decay = frequency_shifts(stiffness, damping, omega)
    stiff = omega**2 + shift
    phase = (cumulative(t, response * (np.sqrt(np.maximum(stiff, 0.0)) - omega), decay0)
             + 1j * cumulative(t, decay, decay0))
    vibration = amplitude * np.abs(1.0 - np.exp(1j * phase))
    with np.errstate(divide="ignore", invalid="ignore"):
        quasi_static = np.where(stiff > 0.0, np.abs(force) / stiff, np.where(np.abs(force) > 0.0, np.inf, 0.0))
    return np.linalg.norm(quasi_static + vibration, axis=1)


def free_vibration(eta_dot, eta_ddot, omega) -> np.ndarray:
    """Amplitude of each mode's free vibration, (nt, nq): a mode vibrating freely as
    a cos(omega_k t) has |eta_dot| / omega_k = a |sin| and |eta_ddot| / omega_k^2 = a |cos|, so
    their root sum of squares is a at every sample; a response forced at a lower frequency nu
    (by the rigid motion, the loads) counts only about nu / omega_k of its size (its phase does
    not drift: the quasi-static part sizes it).  eta_dot, eta_ddot (nt, nq) modal rates."""
    w = np.maximum(omega, 1e-300)
    return np.hypot(eta_dot / w, eta_ddot / w**2)


def load_stiffening(node_loads, modes, nt: int) -> np.ndarray:
    """Modal geometric stiffness of the node loads Phi^T dK Phi, (nt, nq, nq): the node force
    phi(q)^T F (sid-spec 5.2) with phi(q) = phi0 + K0F q gives dK = -sum_a (F_a K0F_a^T +
    T_a K0M_a^T) (sid-spec 6.2: a tension stiffens); F, T (nt, 3) in K at the node markers,
    joint reactions included (none: zero)."""
    dk = np.zeros((nt, *modes.shape))
    for marker, force, torque in node_loads:
        for k0, load in ((marker.k0f, force), (marker.k0m, torque)):
            if k0 is not None:
                dk -= np.einsum("ta,ajk->tkj", load, modes.T @ k0 @ modes)
    return dk


def packed(body, effects: set) -> tuple:
    """((F, off, flags, mass) for the compiled body equations, BodyTerms) of ``effects``."""
    terms = body.terms(effects, gravity="gravity" in effects)
    return pack_terms(terms) + (float(terms.mass),), terms


class LeftOutTerms:
    """The left-out terms of one body's elastic rows, per signal (``signal_coefficients``), from
    the body equations at the probe states with and without each effect."""

    def __init__(self, body, chosen: set, modes: np.ndarray):
        w, a, wdot, g = probe_states()
        nq = modes.shape[0]
        self.body, self.chosen, self.modes, self.avail = body, set(chosen), modes, body.available()
        self.probes = (w, g, np.concatenate([a, wdot, np.zeros((N_SIGNALS, nq))], axis=1), modes)
        generic = np.random.default_rng(0).uniform(0.5, 1.5, 12 + 2 * nq)  # no cancellation (e.g. a = g)
        self.generic = (generic[None, :3], generic[None, 3:6], generic[None, 6:12 + nq], generic[12 + nq:, None])
        self.probe_signals = signals(w, a, wdot, g)
        base = packed(body, self.chosen)[0]
        self.base, self.base_generic = elastic_rows(base, *self.probes), elastic_rows(base, *self.generic)

    def coefficients(self, effect: str) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """Modal force (19, nq), stiffness and damping (19, nq, nq) per signal that ``effect``
        adds to the elastic rows; None when it adds nothing there (rigid-body rows only)."""
        pack = packed(self.body, assembled(self.chosen | {effect}, self.avail))[0]
        if not np.any(elastic_rows(pack, *self.generic) - self.base_generic):
            return None
        return signal_coefficients(elastic_rows(pack, *self.probes) - self.base, self.probe_signals, self.modes)


def estimate_changes(body, chosen: set, samples: dict) -> dict[str, tuple[float, str]]:
    """Each effect the SID provides but the run left out: {effect: (estimated max |dq| /
    max |q|, MEASURE)}, computed from the run's own samples (no second simulation).

    samples: t (nt,) s, q, qd (nt, nq), omega (nt, 3) 1/s, rotation (nt, 3, 3), acceleration
    (nt, 6+nq) (inertial a_O, omega_dot, q_ddot), gravity (3,) m/s^2, node_loads
    [(marker, force (nt, 3), torque (nt, 3)) in K] and optionally the run's SolverSettings
    (``settings``: fixed-step generalised-alpha shows only part of a frequency shift,
    ``genalpha_phase_response``).  The left-out modal force, stiffness and
    damping per signal (``LeftOutTerms``; load stiffening from the node loads) weighted by the
    run's signals at up to ESTIMATE_SAMPLES samples; ``modal_change`` turns them into the
    change of the modes.  An effect acting on the rigid-body rows only is sized 0.
    """
    avail = body.available()
    left_out = [e for e in EFFECTS if avail[e] and e not in chosen]
    if not left_out or samples["q"].size == 0:  # no samples or no modes: nothing to change
        return {}
    idx = np.unique(np.linspace(0, len(samples["q"]) - 1, min(len(samples["q"]), ESTIMATE_SAMPLES)).astype(int))
    rot, acc = samples["rotation"][idx], samples["acceleration"][idx]  # A: K -> inertial
    x = signals(samples["omega"][idx], np.einsum("tji,tj->ti", rot, acc[:, :3]), acc[:, 3:6],
                np.einsum("tji,j->ti", rot, samples["gravity"]))
    terms = packed(body, set(chosen))[1]
    omega, modes = free_modes(terms.Ke, terms.Me)
    to_modal = terms.Me @ modes  # eta = Phi^T Me q
    eta, eta_dot = samples["q"][idx] @ to_modal, samples["qd"][idx] @ to_modal
    ref = float(np.max(np.linalg.norm(samples["q"] @ to_modal, axis=1)))
    amplitude = free_vibration(eta_dot, acc[:, 6:] @ to_modal, omega)
    decay0 = 0.5 * np.einsum("ik,ij,jk->k", modes, terms.De, modes) if terms.De is not None else 0.0
    settings = samples.get("settings")
    fixed_step_genalpha = settings is not None and settings.method == "genalpha" and settings.tolerance is None
    response = genalpha_phase_response(omega, settings.h, settings.rho_inf) if fixed_step_genalpha else 1.0
    terms_left_out = LeftOutTerms(body, set(chosen), modes)
    out = {}
    for effect in left_out:
        if effect == "load_stiffening":
            stiffness = load_stiffening([(m, f[idx], tq[idx]) for m, f, tq in samples.get("node_loads", [])], modes,
                                        len(idx))
            damping, force = np.zeros_like(stiffness), np.einsum("tkj,tj->tk", stiffness, eta)
        else:
            coefficients = terms_left_out.coefficients(effect)
            if coefficients is None:
                out[effect] = (0.0, MEASURE)
                continue
            f, k, c = coefficients
            stiffness, damping = ((x @ m.reshape(N_SIGNALS, -1)).reshape(-1, *m.shape[1:]) for m in (k, c))
            force = x @ f + (stiffness @ eta[:, :, None] + damping @ eta_dot[:, :, None])[:, :, 0]
        change = modal_change(samples["t"][idx], amplitude, force, stiffness, damping, omega, response, decay0)
        out[effect] = (_relative(float(np.max(change)), ref), MEASURE)
    return out


def _relative(change: float, ref: float) -> float:
    """change / ref; 0 when nothing changes, inf when an undeformed body would deform."""
    if change == 0.0:
        return 0.0
    return change / ref if ref > 0 else float("inf")


def build_report(choices: dict, estimates: dict, notes=()) -> EffectsReport:
    """EffectsReport from {body: (body, chosen, reasons)} and {body: estimate_changes(...)}."""
    bodies = {}
    for name, (body, chosen, reasons) in choices.items():
        avail = body.available()
        est = estimates.get(name, {})
        entries = []
        for e in EFFECTS:
            value, measure = est.get(e, (float("nan"), ""))
            shown = avail[e] and e not in chosen
            entries.append(EffectEntry(e, e in chosen, bool(avail[e]), reasons.get(e, ""),
                                       float(value) if shown else float("nan"), measure if shown else ""))
        bodies[name] = tuple(entries)
    return EffectsReport(bodies, tuple(notes))
