"""Eigenmodes of a mechanism linearised at its assembled start (sidprep/solver/linear.py) against
closed forms: a compound pendulum and an Euler-Bernoulli cantilever."""

from __future__ import annotations

import math

import numpy as np

from sidprep.reduction.beam import beam_options_from_table, beam_sid
from sidprep.solver import Fixed, FlexibleBody, Revolute, RigidBody, System
from sidprep.solver.linear import mechanism_modes

#: finite-difference tangent stiffness (central, step 1e-6 L): relative frequency error
LINEAR_RTOL = 1e-6
#: beta_n L of a clamped-free Euler-Bernoulli beam (roots of cos x cosh x = -1)
CANTILEVER_BETA_L = (1.8751040687, 4.6940911330, 7.8547574382)


def test_compound_pendulum_frequency():
    """f = sqrt(m g d / (I_c + m d^2)) / (2 pi), hanging at rest about a revolute."""
    m, d, i_c, g = 2.0, 0.4, 0.03, 9.81
    s = System(gravity=(0.0, 0.0, -g))
    axis_y = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]).T      # marker z = y
    body = s.add(RigidBody(m, (0.0, 0.0, -d), [i_c, i_c, i_c], name="pendulum"))
    s.add(Revolute(s.ground.marker(rotation=axis_y), body.marker(rotation=axis_y)))
    modes = mechanism_modes(s)
    expected = math.sqrt(m * g * d / (i_c + m * d * d)) / (2 * math.pi)
    assert modes.n_rigid == 0 and modes.frequencies_hz.size == 1
    assert abs(modes.frequencies_hz[0] / expected - 1) < LINEAR_RTOL


def test_clamped_beam_frequencies():
    """A clamped-free Beam held by a fixed joint at its root: the Euler-Bernoulli frequencies
    (beta_n L)^2 / (2 pi L^2) sqrt(EI / (rho A)), no gravity."""
    length, b, h, E, rho = 2.0, 0.05, 0.02, 2.1e11, 7850.0
    sid = beam_sid(beam_options_from_table({"length": length, "section": f"rectangle:{b},{h}", "E": E, "nu": 0.3,
                                            "rho": rho, "bc": "clamped-free", "modes": "xz:1-3"}, "test"))
    s = System(gravity=(0.0, 0.0, 0.0))
    beam = s.add(FlexibleBody(sid, name="beam"))
    s.add(Fixed(s.ground.marker(), beam.marker()))
    modes = mechanism_modes(s)
    ei = E * b * h**3 / 12
    expected = [bl**2 / (2 * math.pi * length**2) * math.sqrt(ei / (rho * b * h)) for bl in CANTILEVER_BETA_L]
    np.testing.assert_allclose(modes.frequencies_hz, expected, rtol=LINEAR_RTOL)
