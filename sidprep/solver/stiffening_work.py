"""The work of the geometric-stiffening terms: the energy kind "stiffening" of a run.

Geometric stiffening (sid-spec 5.2: centrifugal K0omega with Kom, acceleration K0t / K0r, load
K0F / K0M) adds forces proportional to the current loads, accelerations or spin times q.  For a
load that changes they are not the gradient of a potential, so their work is booked as an
integral of their power along the run, not as a function of the state.  Their power is the
difference of the model power

    P(x, u, lambda) = u . (f - B_F^T lambda) + 1/2 u . (dM/dt) u + dV/dt      (W)

(dE/dt of the equations at a state: zero for a model whose forces derive from the booked
kinetic and potential energies) between the run's layout and the same layout without the
stiffening effects and without second_order_inertia (I2 and Gr1 pair with the Kom part of the
centrifugal stiffening: the exact model is conservative with all three, the first-order one
with none); dM/dt u and dV/dt are central differences along the motion (step
RATE_STEP s, core/outputs.pyx).  The other terms (loads, drives, damping, friction, springs, moving masses) are
the same in both layouts and cancel; a term outside the stiffening effects that did not
conserve energy would still show in the balance error.  P_s is computed at every output sample
by the compiled post-processing (core/outputs.pyx: ``sample_outputs`` from ``model_power``,
with the central differences at step RATE_STEP).

The work W_s(t) = int_0^t P_s dt is integrated by the trapezoidal rule over the output samples;
the energy kind "stiffening" is -W_s, so that the total stays constant.
"""

from __future__ import annotations

from sidprep.solver.compile.layout import build_layout

#: effects whose work is booked here (preload is a potential, booked in the strain energy)
STIFFENING_EFFECTS = ("centrifugal_stiffening", "acceleration_stiffening", "load_stiffening")
#: left out of the reference layout with them: I2, Gr1 balance the Kom part of Oe.M1
PAIRED_EFFECTS = ("second_order_inertia",)
def base_layout(run):
    """The run's layout without the stiffening effects (None when none is switched on)."""
    if not any(e in chosen for _, chosen, _ in run.choices.values() for e in STIFFENING_EFFECTS):
        return None
    terms = []
    for b, t in zip(run.system.bodies, run.terms):
        choice = run.choices.get(b.name)
        terms.append(t if choice is None else b.terms(set(choice[1]) - set(STIFFENING_EFFECTS + PAIRED_EFFECTS),
                                                        t.gravity))
    return build_layout(run.system, terms, [False] * len(terms))._replace(fe_par=run.L.fe_par)
