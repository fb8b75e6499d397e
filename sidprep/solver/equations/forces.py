"""Force elements, compiled (model/forces.py describes them): marker loads, power and potential.

Each element adds forces / torques (inertial components) at markers into ``loads`` (nmk, 6)
and its power into ``flows`` = [power put in by applied loads, power dissipated, spring
potential energy, power put in by drives] (W, W, J, W).  Loads along a joint coordinate act
through the coordinate's velocity row c (constraints.joint_coordinate): F1 = Q cT1,
T1 = Q cR1, F2 = Q cT2, T2 = Q cR2.
"""

from __future__ import annotations

import numpy as np

from sidprep.solver.equations.curves import curve_value
from sidprep.solver.equations.rotations import add, dot, jit, matvec, put

#: force element kinds, column 0 of the layout's fe_int table (compile/layout.py writes them)
FE_FORCE, FE_TORQUE, FE_SPRING, FE_JOINT_FORCE, FE_FRICTION, FE_MOVING_MASS = range(6)


@jit
def curve_arrays(curve_x, curve_c, curve_meta, index):  # pragma: no cover - compiled
    """Breakpoints x (k+1,) and coefficients c (degree+1, k) of the layout's curve ``index``."""
    meta = curve_meta[index]
    n, rows = meta[1], meta[3]
    x = curve_x[meta[0]:meta[0] + n]
    c = curve_c[meta[2]:meta[2] + rows * (n - 1)].reshape((rows, n - 1))
    return x, c


@jit
def motion_curve(curve_x, curve_c, curve_meta, index):  # pragma: no cover - compiled
    """(x, c) of a motion profile's curve (TABULATED), placeholders when ``index`` < 0 (the
    closed-form profiles of curves.motion_state do not use them)."""
    if index >= 0:
        return curve_arrays(curve_x, curve_c, curve_meta, index)
    return np.zeros(2), np.zeros((1, 1))


@jit
def curve(curve_x, curve_c, curve_meta, curve_period, index, at):  # pragma: no cover - compiled
    """Value of the layout's curve ``index`` at ``at``."""
    x, c = curve_arrays(curve_x, curve_c, curve_meta, index)
    return curve_value(x, c, curve_period[index], at, 0)


@jit
def add_joint_load(loads, mk, crow, value):  # pragma: no cover - compiled
    """A generalised force ``value`` along a joint coordinate with velocity row crow (4, 3)."""
    for a in range(3):
        loads[mk[0], a] += value * crow[0, a]
        loads[mk[0], 3 + a] += value * crow[1, a]
        loads[mk[1], a] += value * crow[2, a]
        loads[mk[1], 3 + a] += value * crow[3, a]


@jit
def stop_penetration(par, x):  # pragma: no cover - compiled
    """Penetration of a spring-damper's bump stop, m: -(x + clearance) for the deflection x (m);
    the stop pushes while it is > 0 (par: spring_tension's)."""
    return -(x + par[4])


@jit
def spring_tension(par, x, rate):  # pragma: no cover - compiled
    """(tension, its dissipative part, its conservative linear part) of a spring-damper with
    deflection x (m) and rate (m/s); par = [k, c, length, has_stop, clearance, k_stop,
    exponent, c_stop]."""
    damp = par[1] * rate
    t = par[0] * x + damp
    if par[3] > 0.0:
        pen = stop_penetration(par, x)
        if pen > 0.0:
            stop_damp = par[7] * rate
            t += -par[5] * pen ** par[6] + stop_damp
            damp += stop_damp
    return t, damp, par[0] * x


@jit
def bump_potential(par, x):  # pragma: no cover - compiled
    """Elastic energy of an engaged bump stop, J: k_stop pen^(e+1) / (e+1)."""
    if par[3] <= 0.0:
        return 0.0
    pen = stop_penetration(par, x)
    return par[5] * pen ** (par[6] + 1.0) / (par[6] + 1.0) if pen > 0.0 else 0.0


@jit
def has_stops(L):  # pragma: no cover - compiled
    """Whether a force element has a bump stop (a kink the integrators locate)."""
    for i in range(L.fe_int.shape[0]):
        if L.fe_int[i, 0] == FE_SPRING and L.fe_par[i, 3] > 0.0:
            return True
    return False


@jit
def stop_states(L, kin, pen, rate):  # pragma: no cover - compiled
    """Every force element's bump-stop penetration pen (nfe,; m, > 0 engaged, -inf for elements
    without a stop) and its rate (nfe,; m/s), written in place, from the markers' kinematics kin
    (assemble.MarkerKinematics).  The stops are the force laws with a kink at pen = 0 that the
    integrators locate (docs/solver.md, "Contacts")."""
    for i in range(L.fe_int.shape[0]):
        row, par = L.fe_int[i], L.fe_par[i]
        pen[i], rate[i] = -np.inf, 0.0
        if row[0] == FE_SPRING and par[3] > 0.0:
            d = kin.P[row[2]] - kin.P[row[1]]
            length = np.sqrt(dot(d, d))
            e = d / length if length > 0.0 else np.zeros(3)
            pen[i] = stop_penetration(par, length - par[2])
            rate[i] = -dot(e, kin.VEL[row[2]] + kin.VC[row[2]] - kin.VEL[row[1]] - kin.VC[row[1]])


@jit
def force_elements(L, t, kin, coords, crows, convective, lam, loads, flows):  # pragma: no cover - compiled
    """Add every force element's marker loads into loads (nmk, 6) and flows (4,).

    kin: the markers' kinematics (assemble.MarkerKinematics): positions P, orientations AM,
    material velocities VEL, angular velocities OMG (inertial) and the convective velocities VC
    (nmk, 3) of markers moved along a path (a marker moves at VEL + VC); coords (nj, 2) joint
    coordinate and rate, crows (nj, 4, 3) their velocity rows, convective (nj,) the part of the
    rates due to path motions; lam (m_all,) multipliers (friction reads the transverse
    reactions).  Springs and joint loads see the markers' whole motion; the power their loads
    take from a path's motion (-load . VC) is the drive's, flows[3].
    """
    P, AM, VEL, OMG, VC = kin.P, kin.AM, kin.VEL, kin.OMG, kin.VC
    for i in range(L.fe_int.shape[0]):
        row = L.fe_int[i]
        kind, mk1, mk2, joint, first, columns = row[0], row[1], row[2], row[3], row[4], row[5]
        par = L.fe_par[i]
        if kind == FE_FORCE or kind == FE_TORQUE:
            x = t if joint < 0 else coords[joint, 0]
            v = np.zeros(3)
            if columns == 0:
                put(v, 0, par[:3])
            else:
                for a in range(columns):
                    v[a] = curve(L.curve_x, L.curve_c, L.curve_meta, L.curve_period, first + a, x)
            if par[6] > 0.0:
                v = v[0] * par[3:6]
            if par[7] > 0.0:
                v = matvec(AM[mk1], v)
            if kind == FE_FORCE:
                add(loads[mk1], 0, v)
                flows[0] += dot(v, VEL[mk1])
            else:
                add(loads[mk1], 3, v)
                flows[0] += dot(v, OMG[mk1])
        elif kind == FE_SPRING:
            d = P[mk2] - P[mk1]
            length = np.sqrt(dot(d, d))
            e = d / length if length > 0.0 else np.zeros(3)  # coincident markers: no direction
            rate = dot(e, VEL[mk2] + VC[mk2] - VEL[mk1] - VC[mk1])
            x = length - par[2]
            tension, damp, linear = spring_tension(par, x, rate)
            add(loads[mk2], 0, e, -tension)
            add(loads[mk1], 0, e, tension)
            flows[1] += damp * rate
            flows[3] += tension * dot(e, VC[mk2] - VC[mk1])
            flows[2] += 0.5 * par[0] * x * x + bump_potential(par, x)
        elif kind == FE_JOINT_FORCE:
            x, xd = coords[joint, 0], coords[joint, 1]
            q = par[3] - par[0] * (x - par[2]) - par[1] * xd
            if first >= 0:
                q += curve(L.curve_x, L.curve_c, L.curve_meta, L.curve_period, first, x)
            add_joint_load(loads, L.joint_mk[joint], crows[joint], q)
            flows[3] -= q * convective[joint]
            flows[1] += par[1] * xd * xd
            flows[2] += 0.5 * par[0] * (x - par[2]) ** 2
            flows[0] += (q + par[1] * xd + par[0] * (x - par[2])) * xd
        elif kind == FE_FRICTION:
            r0 = L.joint_off[joint]
            normal = np.sqrt(lam[r0] ** 2 + lam[r0 + 1] ** 2) + par[2]
            xd = coords[joint, 1]
            q = -par[0] * normal * par[1] * np.tanh(xd / par[3])
            add_joint_load(loads, L.joint_mk[joint], crows[joint], q)
            flows[3] -= q * convective[joint]
            flows[1] -= q * xd
