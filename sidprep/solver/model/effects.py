"""The effects a simulation may assemble: their names, the SID terms each switches, and the
parsing of a scene's or a body's choice (the report of what was left out: sidprep/solver/effects.py).

Effects (names used in scenes and in the API):

=========================  =====================================================================
name                        SID terms
=========================  =====================================================================
gravity                     uniform gravity on every body: M(q)[:, :3] g_K  (incl. Ct g_K)
coupling                    rigid-elastic inertia coupling Ct0, Cr0 in the mass matrix
coriolis                    Gr0 (rotation row), Ge (elastic row), 2 w~ Ct^T qd (translation row)
centrifugal                 Oe0 w_hat, the centrifugal load on the modes
inertia_change              first-order mass-matrix change: mdCM.M1, J.M1 (I1), Kr part of Cr.M1
second_order_inertia        I2 and Gr1 (needs the mode-pair integrals P_ab, sec. 4.5; exact model)
centrifugal_stiffening      Oe.M1 = Kom + K0omega, switched as ONE term (never one part alone)
acceleration_stiffening     Ct.M1 (K0t) and the symmetric K0r part of Cr.M1
load_stiffening             phi.M1 / psi.M1 (K0F, K0M) at nodes carrying loads or joints
preload                     ksigma (M0 force and M1 stiffness)
damping                     De qd (modal damping)
=========================  =====================================================================

The elastic stiffness Ke q and the rigid-body terms (w~ I w, w~ w~ md) are always assembled.
"""

from __future__ import annotations

EFFECTS = (
    "gravity",
    "coupling",
    "coriolis",
    "centrifugal",
    "inertia_change",
    "second_order_inertia",
    "centrifugal_stiffening",
    "acceleration_stiffening",
    "load_stiffening",
    "preload",
    "damping",
)

#: effects that make the mass matrix depend on q (then it is re-assembled every evaluation)
MASS_MATRIX_EFFECTS = frozenset({"inertia_change", "second_order_inertia", "acceleration_stiffening"})

DESCRIPTIONS = {
    "gravity": "uniform gravity (m g, md~ g, Ct g)",
    "coupling": "rigid-elastic inertia coupling Ct0, Cr0",
    "coriolis": "Coriolis terms Gr0, Ge, 2 w~ Ct^T qd",
    "centrifugal": "centrifugal modal load Oe0 w_hat",
    "inertia_change": "first-order inertia change mdCM.M1, J.M1, Kr",
    "second_order_inertia": "second-order inertia I2, Gr1",
    "centrifugal_stiffening": "centrifugal stiffening Oe.M1 (Kom + K0omega together)",
    "acceleration_stiffening": "stiffening by accelerations Ct.M1 (K0t), K0r",
    "load_stiffening": "stiffening by node loads phi.M1, psi.M1 (K0F, K0M)",
    "preload": "preload ksigma",
    "damping": "modal damping De",
}


def parse_effects(spec) -> set[str] | str:
    """Normalise an effects specification: ``"auto"``, ``"all"``, or an iterable of names.

    Raises ValueError naming the unknown effect and the valid names.
    """
    if spec is None or (isinstance(spec, str) and spec == "auto"):
        return "auto"
    if isinstance(spec, str) and spec == "all":
        return set(EFFECTS)
    names = [spec] if isinstance(spec, str) else list(spec)
    unknown = [n for n in names if n not in EFFECTS]
    if unknown:
        raise ValueError(f"unknown effect(s) {unknown}; valid names: {', '.join(EFFECTS)} or 'auto'")
    return set(names)
