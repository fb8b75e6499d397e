"""Which terms of the FFR equations (sid-spec 5.2) a simulation assembles, and what was left out.

A scene names the effects it wants, or ``"auto"``.  Each effect switches a group of SID terms
(sid-spec 5.4); only the switched-on terms are assembled.  Every run ends with an
:class:`EffectsReport`: what was included, what was left out, and for each left-out effect an
estimate of its relative size measured along the simulated motion, with a WARNING above
:data:`WARN_LEVEL`.

The effect names and their SID terms: solver/model/effects.py.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from sidprep.solver.compile.layout import pack_terms
from sidprep.solver.equations.body import body_equations
from sidprep.solver.model.bodies import Ground
from sidprep.solver.model.effects import DESCRIPTIONS, EFFECTS

#: a left-out effect whose estimated relative size exceeds this gets a WARNING in the report
WARN_LEVEL = 0.01

@dataclass(frozen=True)
class EffectEntry:
    """One line of the effects report for one body.

    included : bool
    available : bool   -- the SID holds the data for this effect
    reason : str       -- why it was included/left out (for ``auto``: the scene property)
    estimate : float   -- relative size measured along the motion (NaN when not estimated)
    measure : str      -- what ``estimate`` is, e.g. "Omega_max^2 / omega_1^2"
    """

    effect: str
    included: bool
    available: bool
    reason: str
    estimate: float = float("nan")
    measure: str = ""

    @property
    def warning(self) -> bool:
        return bool((not self.included) and np.isfinite(self.estimate) and self.estimate > WARN_LEVEL)


@dataclass(frozen=True)
class EffectsReport:
    """Effects included / left out per body, with size estimates of the left-out ones."""

    bodies: dict = field(default_factory=dict)  # body name -> tuple[EffectEntry, ...]
    notes: tuple[str, ...] = ()

    @property
    def warnings(self) -> list[str]:
        out = [
            f"WARNING: body '{b}': left out {e.effect} ({DESCRIPTIONS[e.effect]}) but its size "
            f"{e.measure} = {e.estimate:.3g} exceeds {WARN_LEVEL:.0%}"
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
                est = f"  [{e.measure} = {e.estimate:.3g}]" if np.isfinite(e.estimate) else ""
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


def choose_effects(system, body, spec) -> tuple[set[str], dict[str, str]]:
    """Effects to assemble for one flexible body and the reason for each decision.

    spec : "auto" or a set of names (from ``parse_effects``).  Explicitly named effects that
    the SID cannot provide are reported as not available.
    """
    avail = body.available()
    kom_only = body.oe1_is_kom_only()
    if spec != "auto":
        reasons = {e: ("named by the scene" if e in spec else "not named by the scene") for e in EFFECTS}
        chosen = {e for e in spec if avail[e]}
        if "gravity" in chosen and "coupling" not in chosen and avail["coupling"]:
            chosen.add("coupling")
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
         "Oe.M1 holds only Kom (softening) without K0omega: both left out (sid-spec 5.4)" if kom_only
         else ("body can rotate: Kom + K0omega kept together" if f["can_rotate"]
               else "body is fixed to ground"))
    pick("inertia_change", f["can_rotate"],
         "body can rotate: J.M1 keeps Gr0 / Oe0 energy-consistent (first-order Lagrangian)"
         if f["can_rotate"] else "body is fixed to ground")
    pick("second_order_inertia", False, "second order, usually dropped (sid-spec 5.4)")
    accel = f["gravity"] or f["can_rotate"]
    pick("acceleration_stiffening", accel, "gravity / body accelerations present" if accel
         else "no gravity and body fixed")
    pick("load_stiffening", f["loaded_nodes"], "node markers with K0F/K0M carry loads or joints"
         if f["loaded_nodes"] else "no node marker with K0F/K0M")
    return chosen, reasons


# ---------------------------------------------------------------------------- size estimates
def _lowest_modal_stiffness(model) -> float:
    """omega_1^2 = smallest eigenvalue of (Ke, Me), 1/s^2."""
    import scipy.linalg  # deferred: 0.22 CPU-s of import, needed only for the effects estimates

    if model.nq == 0:
        return float("nan")
    lam = scipy.linalg.eigh(model.Ke, model.Me, eigvals_only=True)
    return float(max(lam[0], 1e-300))


def _ratio(num: float, den: float) -> float:
    if num == 0.0:
        return 0.0
    return num / den if den > 0 else float("inf")


def estimate_sizes(body, samples: dict, gravity: np.ndarray) -> dict[str, tuple[float, str]]:
    """Relative size of each effect along the simulated motion: {effect: (value, measure)}.

    samples: q, qd, omega, rotation, acceleration (nt, ...) of the body and ``node_loads``
    [(marker, force (nt, 3) K, torque (nt, 3) K)] at node markers (joint reactions included).
    """
    full = body.terms(set(EFFECTS), gravity=True)
    s = body.sid
    q, qd, w = samples["q"], samples["qd"], samples["omega"]
    rot, acc = samples["rotation"], samples["acceleration"]
    a_k = np.einsum("tji,tj->ti", rot, acc[:, :3])
    g_k = np.einsum("tji,j->ti", rot, gravity)
    wdot = acc[:, 3:6]
    w1sq = _lowest_modal_stiffness(full)
    ref = float(np.max(np.linalg.norm(q @ full.Ke.T, axis=1))) if len(q) else 0.0
    w_hat = np.stack([w[:, 0] ** 2, w[:, 1] ** 2, w[:, 2] ** 2, w[:, 0] * w[:, 1], w[:, 1] * w[:, 2],
                      w[:, 0] * w[:, 2]], axis=1)
    out = {}
    spin = float(np.max(np.linalg.norm(w, axis=1))) if len(w) else 0.0
    out["centrifugal_stiffening"] = (spin**2 / w1sq, "Omega_max^2 / omega_1^2")
    i0 = np.linalg.norm(full.I0)
    if full.I1 is not None:
        out["inertia_change"] = (float(np.max(np.linalg.norm(np.tensordot(q, full.I1, 1), axis=(1, 2)))) / i0,
                                 "max |J.M1 q| / |J0|")
    if full.P is not None:
        pq = np.einsum("abjk,tj,tk->tab", full.P, q, q)
        i2 = np.einsum("taa->t", pq)[:, None, None] * np.eye(3) - pq
        out["second_order_inertia"] = (float(np.max(np.linalg.norm(i2, axis=(1, 2)))) / i0, "max |I2(q)| / |J0|")
    if full.Ct1 is not None or full.Cr1 is not None:
        k0 = np.zeros((len(q), full.nq, full.nq))
        if full.Ct1 is not None:
            k0 += np.einsum("kja,ta->tkj", full.Ct1, a_k - g_k)
        k0r = body._k0r()
        if k0r is not None:
            k0 += np.einsum("akj,ta->tkj", k0r, wdot)
        out["acceleration_stiffening"] = (float(np.max(np.linalg.norm(k0, ord=2, axis=(1, 2)))) / w1sq,
                                          "|K0t (a - g) + K0r w_dot| / omega_1^2")
    loads = [0.0]
    for marker, force, torque in samples.get("node_loads", []):
        k = np.zeros((len(q), full.nq, full.nq))
        if marker.k0f is not None:
            k += np.einsum("ajk,ta->tkj", marker.k0f, force)
        if marker.k0m is not None:
            k += np.einsum("ajk,ta->tkj", marker.k0m, torque)
        loads.append(float(np.max(np.linalg.norm(k, ord=2, axis=(1, 2)))))
    out["load_stiffening"] = (max(loads) / w1sq, "max |K0F F + K0M T| / omega_1^2")
    if full.Oe0 is not None:
        out["centrifugal"] = (_ratio(float(np.max(np.linalg.norm(w_hat @ full.Oe0.T, axis=1))), ref),
                              "max |Oe0 w_hat| / max |Ke q|")
    if full.Ge is not None:
        ge = np.einsum("akj,ta,tj->tk", full.Ge, w, qd)
        out["coriolis"] = (_ratio(float(np.max(np.linalg.norm(ge, axis=1))), ref), "max |Ge(w) qd| / max |Ke q|")
    if np.any(s.Ct.M0) or np.any(s.Cr.M0):
        c = a_k @ s.Ct.M0.T + wdot @ s.Cr.M0.T
        out["coupling"] = (_ratio(float(np.max(np.linalg.norm(c, axis=1))), ref),
                           "max |Ct a + Cr w_dot| / max |Ke q|")
    if np.any(s.De.M0):
        zeta = np.diag(s.De.M0) / (2 * np.sqrt(np.abs(np.diag(s.Ke.M0) * np.diag(s.Me.M0))) + 1e-300)
        out["damping"] = (float(np.max(zeta)), "max modal damping ratio")
    if np.any(s.ksigma.M0):
        out["preload"] = (_ratio(float(np.linalg.norm(s.ksigma.M0)), ref), "|ksigma| / max |Ke q|")
    amax = float(np.max(np.linalg.norm(acc[:, :3], axis=1))) if len(acc) else 0.0
    out["gravity"] = (_ratio(float(np.linalg.norm(gravity)), amax), "|g| / max |a_O|")
    return out


#: effects whose terms are part of the body equations (load stiffening acts through the node
#: Jacobians and keeps its load-based estimate)
BODY_EFFECTS = tuple(e for e in EFFECTS if e != "load_stiffening")
#: output samples (evenly spread) at which the left-out generalised forces are evaluated
RUN_ESTIMATE_SAMPLES = 200


def run_estimates(body, chosen: set, samples: dict) -> dict[str, tuple[float, str]]:
    """Each left-out effect measured on the run itself: the modal generalised force it would
    have added, Delta(h) - Delta(M) u_dot of the body equations with and without it, at up to
    RUN_ESTIMATE_SAMPLES output samples, max over them, relative to the largest kept modal
    elastic force |Ke q| of the run (the deflection the left-out force would add, relative to
    the run's; the inertial modal force |(M u_dot)_e| when nothing deforms).

    samples: q, qd, omega, rotation, acceleration (nt, ...) of the body and gravity (3,).
    """
    avail = body.available()
    left_out = [e for e in BODY_EFFECTS if avail[e] and e not in chosen]
    q, qd, w, rot, acc = (samples[k] for k in ("q", "qd", "omega", "rotation", "acceleration"))
    if not left_out or len(q) == 0:
        return {}
    idx = np.unique(np.linspace(0, len(q) - 1, min(len(q), RUN_ESTIMATE_SAMPLES)).astype(int))

    def packed(effects):
        terms = body.terms(effects, gravity="gravity" in effects)
        return pack_terms(terms) + (float(terms.mass),)

    def evaluated(pack, k):
        F, off, flags, mass = pack
        gk = rot[k].T @ samples["gravity"]
        mk, h = body_equations(F, off, flags, mass, q[k].copy(), qd[k].copy(), w[k].copy(), gk)
        ud = np.concatenate([rot[k].T @ acc[k, :3], acc[k, 3:]])
        return mk @ ud - h, mk, h, ud

    base = packed(set(chosen))
    kept = [evaluated(base, k) for k in idx]
    ke = body.terms(set(), gravity=False).Ke
    ref = max(np.linalg.norm(ke @ q[k]) for k in idx)
    if ref == 0.0:  # no deformation: against the inertial modal force
        ref = max(np.linalg.norm((mk @ ud)[6:]) for _, mk, _, ud in kept)
    out = {}
    for effect in left_out:
        pack = packed(set(chosen) | {effect})
        size = max(np.linalg.norm((evaluated(pack, k)[0] - r[0])[6:]) for k, r in zip(idx, kept))
        out[effect] = (_ratio(float(size), float(ref)), "max |modal force left out| / max |Ke q| (sampled on the run)")
    return out


def build_report(choices: dict, estimates: dict, notes=()) -> EffectsReport:
    """EffectsReport from {body: (body, chosen, reasons)} and {body: estimate_sizes(...)}."""
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
