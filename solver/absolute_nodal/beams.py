"""Interconnected planar flexible beams in absolute nodal coordinates (Kisu Lee, seed 002).

No floating frame and no joint constraints: the unknowns are the absolute positions x_i (m,
inertial X-Y plane) of the nodes of two-node elements; beams joined by a revolute share one node.

* Mass (eq. 1-2): linear C0 interpolation of the absolute positions, element mass matrix
  m_e/6 [[2, 1], [1, 2]] per direction -- constant.
* Elastic force (eq. 3-9): per beam J, a frame with origin at its first node and x axis through
  its last node (angle phi_J); nodal deformations w_i = A(phi)^T (x_i - x_1) - (s_i, 0); the slope
  theta_i from the quadratic through node i and its neighbours (eq. 5; one-sided at the ends);
  V_J = 1/2 u^T K u with u_i = (w_x, w_y, theta)_i and K the linear Euler-Bernoulli (Hermite) +
  bar stiffness of the beam.  The generalized force R_J K_J u_J of eq. 10 is the exact gradient
  dV_J/dx, the turning of the frame included (the paper's eq. 12-14 drop it), so the discrete
  system is conservative and RK4's energy error is the integration error alone.
* M x'' + sum_J dV_J/dx = f (eq. 10), f = gravity + constant nodal forces; pinned nodes are
  removed; prescribed-angle drivers Phi = phi_J + theta_end - psi(t) = 0 at a support add
  Lagrange multipliers (the paper's remark after eq. 14) with Baumgarte stabilisation.
* Classic RK4 (solver/integrators/runge_kutta.py) with a compiled right-hand side.

Outputs are a ``solver.results.Result`` (solver/results.py writes and plots it): a body per beam
(position / rotation / velocity / omega of its chord frame at the first node; q = [flexural
displacement -theta_n L, flexural slope theta_n - theta_1] as in the paper's Figs. 9-12), a
marker per point, a revolute "joint" per support (coordinate = the beam's chord angle phi) and
per shared point (coordinate = phi_2 - phi_1), energies kinetic / strain / gravity / external
(driver work) / total.
"""

from __future__ import annotations

import math
import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path

import numba
import numpy as np

from sidprep.errors import InputError
from sidprep.solver.integrators.runge_kutta import rk4_fixed

#: Baumgarte stabilisation of the driver constraints, Phi'' + 2 a Phi' + a^2 Phi = 0 (1/s)
BAUMGARTE_RATE = 20.0
#: two points given different positions by the initial angles (closed loop) beyond this (m)
CLOSURE_TOL = 1e-9
#: largest h * omega_max accepted for RK4 (its stability limit on the imaginary axis is 2 sqrt 2)
RK4_STABILITY = 2.6
#: relative coordinate perturbation of the finite-difference stiffness behind the step check
STIFFNESS_FD = 1e-7
#: smallest number of elements per beam (the end slopes need three nodes, eq. 3-4)
MIN_ELEMENTS = 2


# ---------------------------------------------------------------------------------------------
# the model description


@dataclass(frozen=True)
class Beam:
    """One straight, uniform beam.

    length (m), mass (kg), EI (N m^2), EA (N); elements >= 2; points = (start, end) point names
    (beams sharing a point are joined by a revolute); angle (rad) of start -> end from the X axis
    and rate (rad/s) of the initially straight beam.
    """

    name: str
    length: float
    mass: float
    EI: float
    EA: float
    elements: int
    points: tuple[str, str]
    angle: float = 0.0
    rate: float = 0.0


@dataclass(frozen=True)
class Support:
    """A pinned point at a fixed position (m)."""

    name: str
    point: str
    position: tuple[float, float] = (0.0, 0.0)


@dataclass(frozen=True)
class Driver:
    """Prescribed angle of beam ``beam``'s tangent at support ``support`` (a motor clamping the beam):

    psi(t) = psi0 + speed t + delta (tau - sin(2 pi tau) / (2 pi)), tau = min(t / duration, 1);
    psi0 = the beam's initial angle; speed (rad/s) must equal the beam's initial rate.
    """

    name: str
    support: str
    beam: str
    speed: float = 0.0
    delta: float = 0.0
    duration: float = 0.0


@dataclass(frozen=True)
class NodalForce:
    """A constant force (N, inertial X-Y) at a point."""

    name: str
    point: str
    force: tuple[float, float]


@dataclass(frozen=True)
class AbsoluteNodalModel:
    """Planar beams, supports, drivers and loads; gravity (m/s^2, X-Y).

    gravity_zero: "origin" (V_g = -sum m g . x) or "hanging" (zero for every beam hanging straight
    along gravity from the supports, the paper's choice).
    """

    beams: tuple[Beam, ...]
    supports: tuple[Support, ...] = ()
    drivers: tuple[Driver, ...] = ()
    forces: tuple[NodalForce, ...] = ()
    gravity: tuple[float, float] = (0.0, -9.81)
    gravity_zero: str = "origin"
    title: str = "absolute nodal beams"


@dataclass(frozen=True)
class AbsoluteNodalSettings:
    """Fixed-step RK4: t_end (s), step (s), output rate (samples/s; None = every step)."""

    t_end: float = 1.0
    step: float = 2.5e-4
    rate: float | None = None


# ---------------------------------------------------------------------------------------------
# assembly (Python, once)


@dataclass
class Assembly:
    """Numbered nodes and constant matrices of a model.

    points {name: node}; beam_nodes (B, nmax) node numbers (-1 padded); beam_n (B,); beam_e (B,)
    element lengths (m); beam_K (B, 6, 6) element stiffness; Ms (N, N) scalar mass matrix (kg);
    free (Nf,) / fixed (Np,) nodes; Minv (Nf, Nf) inverse of Ms[free, free]; f0 (N, 2) gravity +
    nodal forces (N); fg (N, 2) gravity alone (N); X0, V0 (N, 2) initial positions / velocities;
    gravity_offset (J) added to -sum fg . x; drv (nd, 6) drivers: beam, at_end, psi0, speed,
    delta, duration.
    """

    points: dict
    beam_nodes: np.ndarray
    beam_n: np.ndarray
    beam_e: np.ndarray
    beam_K: np.ndarray
    Ms: np.ndarray
    free: np.ndarray
    fixed: np.ndarray
    Minv: np.ndarray
    f0: np.ndarray
    fg: np.ndarray
    X0: np.ndarray
    V0: np.ndarray
    gravity_offset: float
    drv: np.ndarray = field(default_factory=lambda: np.zeros((0, 6)))


def element_stiffness(EA: float, EI: float, e: float) -> np.ndarray:
    """Linear bar + Euler-Bernoulli (Hermite) element stiffness, dofs (w_x, w_y, theta) x 2; (6, 6)."""
    a, b = EA / e, EI / e**3
    K = np.zeros((6, 6))
    K[np.ix_([0, 3], [0, 3])] = a * np.array([[1.0, -1.0], [-1.0, 1.0]])
    K[np.ix_([1, 2, 4, 5], [1, 2, 4, 5])] = b * np.array([[12, 6 * e, -12, 6 * e], [6 * e, 4 * e * e, -6 * e, 2 * e * e],
                                                          [-12, -6 * e, 12, -6 * e], [6 * e, 2 * e * e, -6 * e, 4 * e * e]])
    return K


def _check_model(model: AbsoluteNodalModel) -> None:
    if not model.beams:
        raise InputError("absolute-nodal model: no beams; add at least one beam")
    names = [b.name for b in model.beams]
    if len(set(names)) != len(names):
        raise InputError("absolute-nodal model: duplicate beam names; give every beam its own name")
    for b in model.beams:
        for what, v in (("length", b.length), ("mass", b.mass), ("EI", b.EI), ("EA", b.EA)):
            if not (np.isfinite(v) and v > 0):
                raise InputError(f"beam {b.name!r}: {what} must be > 0, got {v!r}; give a positive SI value")
        if b.elements < MIN_ELEMENTS:
            raise InputError(f"beam {b.name!r}: elements = {b.elements}; use at least {MIN_ELEMENTS} "
                             "(the end slopes come from a quadratic through three nodes)")
        if b.points[0] == b.points[1]:
            raise InputError(f"beam {b.name!r}: both ends at point {b.points[0]!r}; give two different points")
    points = {p for b in model.beams for p in b.points}
    for s in model.supports:
        if s.point not in points:
            raise InputError(f"support {s.name!r}: unknown point {s.point!r}; use a beam end point: {sorted(points)}")
    for f in model.forces:
        if f.point not in points:
            raise InputError(f"force {f.name!r}: unknown point {f.point!r}; use a beam end point: {sorted(points)}")
    if model.gravity_zero not in ("origin", "hanging"):
        raise InputError(f"gravity_zero {model.gravity_zero!r}; use \"origin\" or \"hanging\"")
    beams = {b.name: b for b in model.beams}
    sup = {s.name: s for s in model.supports}
    for d in model.drivers:
        if d.support not in sup or d.beam not in beams or sup[d.support].point not in beams[d.beam].points:
            raise InputError(f"driver {d.name!r}: needs a support and a beam that ends at it; "
                             f"supports: {sorted(sup)}, beams: {sorted(beams)}")
        if abs(d.speed - beams[d.beam].rate) > 1e-12:
            raise InputError(f"driver {d.name!r}: speed {d.speed} rad/s differs from beam {d.beam!r}'s initial rate "
                             f"{beams[d.beam].rate} rad/s; make them equal (consistent initial velocities)")


def _initial_state(model: AbsoluteNodalModel, hanging: np.ndarray | None = None):
    """Positions and velocities (m, m/s) of the beam end points: breadth-first from the supports
    (or from the first beam's start point at the origin), each beam straight at its angle and rate;
    with ``hanging`` (a unit vector) every beam at rest along it, away from the support side."""
    pos, vel = {}, {}
    for s in model.supports:
        pos[s.point], vel[s.point] = np.array(s.position, float), np.zeros(2)
    if not pos:
        p0 = model.beams[0].points[0]
        pos[p0], vel[p0] = np.zeros(2), np.zeros(2)
    queue = deque(pos)
    placed = set()
    while queue:
        p = queue.popleft()
        for b in model.beams:
            if b.name in placed or p not in b.points:
                continue
            placed.add(b.name)
            sign = 1.0 if p == b.points[0] else -1.0
            t = np.array([math.cos(b.angle), math.sin(b.angle)]) if hanging is None else sign * hanging
            rate = b.rate if hanging is None else 0.0
            other = b.points[1] if sign > 0 else b.points[0]
            x = pos[p] + sign * b.length * t
            v = vel[p] + sign * b.length * rate * np.array([-t[1], t[0]])
            if other not in pos:
                pos[other], vel[other] = x, v
                queue.append(other)
            elif hanging is None and np.linalg.norm(pos[other] - x) > CLOSURE_TOL:
                raise InputError(f"beam {b.name!r}: its angle puts point {other!r} {np.linalg.norm(pos[other] - x):.3g} m "
                                 "from where the other beams put it; closed loops need consistent angles")
    missing = [b.name for b in model.beams if b.name not in placed]
    if missing:
        raise InputError(f"beams {missing} are not connected to the supports or the first beam; "
                         "join them by shared points or add a support")
    return pos, vel


def _hanging_potential(model: AbsoluteNodalModel, points: dict, beam_nodes, beam_n, Ms, g) -> float:
    """-sum m g . x of every beam hanging straight along gravity from the supports (J)."""
    pos, _ = _initial_state(model, hanging=np.asarray(g) / max(np.linalg.norm(g), 1e-300))
    X = _node_positions(pos, points, model.beams, beam_nodes, beam_n, len(Ms))
    return float(-np.sum((Ms @ X) @ g))


def _node_positions(pos: dict, points: dict, beams, beam_nodes, beam_n, N) -> np.ndarray:
    X = np.zeros((N, 2))
    for j, b in enumerate(beams):
        a, z = pos[b.points[0]], pos[b.points[1]]
        n = beam_n[j]
        for k in range(n):
            X[beam_nodes[j, k]] = a + (z - a) * k / (n - 1)
    return X


def assemble(model: AbsoluteNodalModel) -> Assembly:
    """Number the nodes and build the constant matrices of ``model`` (see ``Assembly``)."""
    _check_model(model)
    points, N = {}, 0
    for b in model.beams:
        for p in b.points:
            if p not in points:
                points[p], N = N, N + 1
    B, nmax = len(model.beams), max(b.elements for b in model.beams) + 1
    beam_nodes = -np.ones((B, nmax), np.int64)
    beam_n = np.array([b.elements + 1 for b in model.beams], np.int64)
    for j, b in enumerate(model.beams):
        beam_nodes[j, 0], beam_nodes[j, b.elements] = points[b.points[0]], points[b.points[1]]
        for k in range(1, b.elements):
            beam_nodes[j, k], N = N, N + 1
    beam_e = np.array([b.length / b.elements for b in model.beams])
    beam_K = np.array([element_stiffness(b.EA, b.EI, b.length / b.elements) for b in model.beams])
    Ms = np.zeros((N, N))
    for j, b in enumerate(model.beams):
        me = b.mass / b.elements
        for k in range(b.elements):
            i0, i1 = beam_nodes[j, k], beam_nodes[j, k + 1]
            Ms[np.ix_([i0, i1], [i0, i1])] += me / 6.0 * np.array([[2.0, 1.0], [1.0, 2.0]])
    fixed = np.array(sorted({points[s.point] for s in model.supports}), np.int64)
    free = np.array([i for i in range(N) if i not in set(fixed.tolist())], np.int64)
    g = np.asarray(model.gravity, float)
    fg = np.outer(Ms.sum(axis=1), g)
    f0 = fg.copy()
    for f in model.forces:
        f0[points[f.point]] += np.asarray(f.force, float)
    pos, vel = _initial_state(model)
    X0 = _node_positions(pos, points, model.beams, beam_nodes, beam_n, N)
    V0 = _node_positions(vel, points, model.beams, beam_nodes, beam_n, N)
    offset = 0.0
    if model.gravity_zero == "hanging":
        offset = -_hanging_potential(model, points, beam_nodes, beam_n, Ms, g)
    beams = {b.name: j for j, b in enumerate(model.beams)}
    sup = {s.name: s for s in model.supports}
    drv = np.zeros((len(model.drivers), 6))
    for i, d in enumerate(model.drivers):
        j = beams[d.beam]
        at_end = float(sup[d.support].point == model.beams[j].points[1])
        drv[i] = (j, at_end, model.beams[j].angle, d.speed, d.delta, d.duration)
    return Assembly(points, beam_nodes, beam_n, beam_e, beam_K, Ms, free, fixed, np.linalg.inv(Ms[np.ix_(free, free)]),
                    f0, fg, X0, V0, offset, drv)


# ---------------------------------------------------------------------------------------------
# compiled kernels


@numba.njit(cache=True)
def slope_weight(k, i, n, e):  # pragma: no cover - compiled
    """d theta_k / d w_y,i of the quadratic through node k and its neighbours (eq. 4-5), nodes 0..n-1."""
    if k == 0:
        c = (-3.0, 4.0, -1.0)
        j = i
    elif k == n - 1:
        c = (1.0, -4.0, 3.0)
        j = i - (n - 3)
    else:
        c = (-1.0, 0.0, 1.0)
        j = i - (k - 1)
    if j < 0 or j > 2:
        return 0.0
    return c[j] / (2.0 * e)


@numba.njit(cache=True)
def _slope_stencil_start(k, n):  # pragma: no cover - compiled
    """First node of the three-node stencil of node k's slope."""
    if k == 0:
        return 0
    if k == n - 1:
        return n - 3
    return k - 1


@numba.njit(cache=True)
def beam_kinematics(X, V, A, nodes, n, e):  # pragma: no cover - compiled
    """Chord angle and slopes of one beam with their first and second time derivatives.

    X, V, A (N, 2) node positions, velocities, accelerations; nodes (n,) its node numbers; e
    element length.  Returns phi, phid, phidd (rad, rad/s, rad/s^2) of the chord x_n - x_1 and
    theta, thetad, thetadd (n,) the slopes of the elastic deflection w_y (eq. 4-5, 11), the
    frame's turning included.
    """
    d0 = X[nodes[n - 1], 0] - X[nodes[0], 0]
    d1 = X[nodes[n - 1], 1] - X[nodes[0], 1]
    dd0 = V[nodes[n - 1], 0] - V[nodes[0], 0]
    dd1 = V[nodes[n - 1], 1] - V[nodes[0], 1]
    da0 = A[nodes[n - 1], 0] - A[nodes[0], 0]
    da1 = A[nodes[n - 1], 1] - A[nodes[0], 1]
    L2 = d0 * d0 + d1 * d1
    L = math.sqrt(L2)
    c0, c1 = d0 / L, d1 / L
    n0, n1 = -c1, c0
    phi = math.atan2(d1, d0)
    cr = d0 * dd1 - d1 * dd0
    phid = cr / L2
    phidd = (d0 * da1 - d1 * da0) / L2 - 2.0 * (d0 * dd0 + d1 * dd1) * cr / (L2 * L2)
    w = np.empty(n)
    wd = np.empty(n)
    wdd = np.empty(n)
    for k in range(n):
        r0, r1 = X[nodes[k], 0] - X[nodes[0], 0], X[nodes[k], 1] - X[nodes[0], 1]
        v0, v1 = V[nodes[k], 0] - V[nodes[0], 0], V[nodes[k], 1] - V[nodes[0], 1]
        a0, a1 = A[nodes[k], 0] - A[nodes[0], 0], A[nodes[k], 1] - A[nodes[0], 1]
        cr_k, nr_k, cv_k = c0 * r0 + c1 * r1, n0 * r0 + n1 * r1, c0 * v0 + c1 * v1
        w[k] = nr_k
        wd[k] = n0 * v0 + n1 * v1 - phid * cr_k
        wdd[k] = n0 * a0 + n1 * a1 - phidd * cr_k - 2.0 * phid * cv_k - phid * phid * nr_k
    theta = np.zeros(n)
    thetad = np.zeros(n)
    thetadd = np.zeros(n)
    for k in range(n):
        s = _slope_stencil_start(k, n)
        for i in range(s, s + 3):
            a = slope_weight(k, i, n, e)
            theta[k] += a * w[i]
            thetad[k] += a * wd[i]
            thetadd[k] += a * wdd[i]
    return phi, phid, phidd, theta, thetad, thetadd


@numba.njit(cache=True)
def beam_elastic(X, nodes, n, e, Ke, Q):  # pragma: no cover - compiled
    """Add the elastic force -dV/dx of one beam to Q (N, 2) and return V = 1/2 u^T K u (J), eq. 6-10.

    u_k = (c . r_k - k e, n . r_k, theta_k), r_k = x_k - x_1, (c, n) the chord frame; K u is
    assembled element by element (Ke (6, 6)); dV/dx by the chain rule through w_x, w_y (slopes
    via the stencil weights) and the chord angle phi (d phi = n . d(x_n - x_1) / L).
    """
    d0 = X[nodes[n - 1], 0] - X[nodes[0], 0]
    d1 = X[nodes[n - 1], 1] - X[nodes[0], 1]
    L = math.sqrt(d0 * d0 + d1 * d1)
    c0, c1 = d0 / L, d1 / L
    n0, n1 = -c1, c0
    u = np.empty(3 * n)
    rc = np.empty(n)
    rn = np.empty(n)
    for k in range(n):
        r0, r1 = X[nodes[k], 0] - X[nodes[0], 0], X[nodes[k], 1] - X[nodes[0], 1]
        rc[k] = c0 * r0 + c1 * r1
        rn[k] = n0 * r0 + n1 * r1
        u[3 * k] = rc[k] - k * e
        u[3 * k + 1] = rn[k]
    for k in range(n):
        s = _slope_stencil_start(k, n)
        th = 0.0
        for i in range(s, s + 3):
            th += slope_weight(k, i, n, e) * rn[i]
        u[3 * k + 2] = th
    f = np.zeros(3 * n)
    for el in range(n - 1):
        o = 3 * el
        for a in range(6):
            acc = 0.0
            for b in range(6):
                acc += Ke[a, b] * u[o + b]
            f[o + a] += acc
    V = 0.0
    for a in range(3 * n):
        V += 0.5 * u[a] * f[a]
    gy = np.empty(n)
    for k in range(n):
        gy[k] = f[3 * k + 1]
    for k in range(n):                       # moments act on w_y through the slope stencils
        s = _slope_stencil_start(k, n)
        for i in range(s, s + 3):
            gy[i] += slope_weight(k, i, n, e) * f[3 * k + 2]
    P = 0.0                                  # dV/dphi at fixed r_k
    s0 = 0.0
    s1 = 0.0
    for k in range(1, n):
        F0 = f[3 * k] * c0 + gy[k] * n0
        F1 = f[3 * k] * c1 + gy[k] * n1
        Q[nodes[k], 0] -= F0
        Q[nodes[k], 1] -= F1
        s0 += F0
        s1 += F1
        P += f[3 * k] * rn[k] - gy[k] * rc[k]
    Q[nodes[0], 0] += s0
    Q[nodes[0], 1] += s1
    Q[nodes[n - 1], 0] -= P * n0 / L
    Q[nodes[n - 1], 1] -= P * n1 / L
    Q[nodes[0], 0] += P * n0 / L
    Q[nodes[0], 1] += P * n1 / L
    return V


@numba.njit(cache=True)
def driver_angle(t, psi0, speed, delta, duration):  # pragma: no cover - compiled
    """psi(t), psi'(t), psi''(t) of a driver (rest-to-rest cycloid over ``duration`` plus a constant speed)."""
    psi, psid, psidd = psi0 + speed * t, speed, 0.0
    if duration > 0.0 and delta != 0.0:
        tau = min(t / duration, 1.0)
        psi += delta * (tau - math.sin(2.0 * math.pi * tau) / (2.0 * math.pi))
        if tau < 1.0:
            psid += delta * (1.0 - math.cos(2.0 * math.pi * tau)) / duration
            psidd += delta * 2.0 * math.pi * math.sin(2.0 * math.pi * tau) / duration**2
    return psi, psid, psidd


@numba.njit(cache=True)
def _wrap(a):  # pragma: no cover - compiled
    return a - 2.0 * math.pi * math.floor((a + math.pi) / (2.0 * math.pi))


@numba.njit(cache=True)
def _driver_value(X, V, A, nodes, n, e, at_end):  # pragma: no cover - compiled
    """Tangent angle phi + theta at the driven end and its derivatives (beam_kinematics)."""
    phi, phid, phidd, th, thd, thdd = beam_kinematics(X, V, A, nodes, n, e)
    k = n - 1 if at_end else 0
    return phi + th[k], phid + thd[k], phidd + thdd[k]


@numba.njit(cache=True)
def accelerations(t, y, params):  # pragma: no cover - compiled
    """Node accelerations A (N, 2), driver multipliers lam (nd,) (N m) and strain energy (J) at state y."""
    X0, free, Minv, f0, beam_nodes, beam_n, beam_e, beam_K, drv, alpha = params
    N, nf = X0.shape[0], free.shape[0]
    X = X0.copy()
    V = np.zeros((N, 2))
    for i in range(nf):
        X[free[i], 0], X[free[i], 1] = y[2 * i], y[2 * i + 1]
        V[free[i], 0], V[free[i], 1] = y[2 * nf + 2 * i], y[2 * nf + 2 * i + 1]
    Q = f0.copy()
    strain = 0.0
    for j in range(beam_n.shape[0]):
        strain += beam_elastic(X, beam_nodes[j], beam_n[j], beam_e[j], beam_K[j], Q)
    A = np.zeros((N, 2))
    for i in range(nf):
        a0, a1 = 0.0, 0.0
        for k in range(nf):
            a0 += Minv[i, k] * Q[free[k], 0]
            a1 += Minv[i, k] * Q[free[k], 1]
        A[free[i], 0], A[free[i], 1] = a0, a1
    nd = drv.shape[0]
    lam = np.zeros(nd)
    if nd > 0:
        # G a = rhs, G (nd, 2 nf) by differences of the driven tangent's acceleration (linear in A)
        G = np.zeros((nd, 2 * nf))
        rhs = np.zeros(nd)
        Z = np.zeros((N, 2))
        for r in range(nd):
            j, at_end = int(drv[r, 0]), drv[r, 1] > 0.5
            nodes, n, e = beam_nodes[j], beam_n[j], beam_e[j]
            val, vald, quad = _driver_value(X, V, Z, nodes, n, e, at_end)
            psi, psid, psidd = driver_angle(t, drv[r, 2], drv[r, 3], drv[r, 4], drv[r, 5])
            err, errd = _wrap(val - psi), vald - psid
            rhs[r] = psidd - quad - 2.0 * alpha * errd - alpha * alpha * err
            for i in range(nf):
                for c in range(2):
                    Z[free[i], c] = 1.0
                    _, _, unit = _driver_value(X, V, Z, nodes, n, e, at_end)
                    Z[free[i], c] = 0.0
                    G[r, 2 * i + c] = unit - quad
        MG = np.zeros((2 * nf, nd))            # M^-1 G^T
        for r in range(nd):
            for i in range(nf):
                for k in range(nf):
                    MG[2 * i, r] += Minv[i, k] * G[r, 2 * k]
                    MG[2 * i + 1, r] += Minv[i, k] * G[r, 2 * k + 1]
        S = G @ MG
        res = rhs.copy()
        for r in range(nd):
            for i in range(nf):
                res[r] -= G[r, 2 * i] * A[free[i], 0] + G[r, 2 * i + 1] * A[free[i], 1]
        lam = np.linalg.solve(S, res)
        for i in range(nf):
            for r in range(nd):
                A[free[i], 0] += MG[2 * i, r] * lam[r]
                A[free[i], 1] += MG[2 * i + 1, r] * lam[r]
    return A, lam, strain


@numba.njit(cache=True)
def rhs(t, y, params):  # pragma: no cover - compiled
    """y' of y = [free positions (2 nf), free velocities (2 nf)]: eq. 10 solved for x''."""
    free = params[1]
    nf = free.shape[0]
    A, _, _ = accelerations(t, y, params)
    yd = np.empty(4 * nf)
    yd[:2 * nf] = y[2 * nf:]
    for i in range(nf):
        yd[2 * nf + 2 * i], yd[2 * nf + 2 * i + 1] = A[free[i], 0], A[free[i], 1]
    return yd


# ---------------------------------------------------------------------------------------------
# running


def kernel_params(asm: Assembly, alpha: float = BAUMGARTE_RATE) -> tuple:
    """The tuple the compiled rhs reads (see ``accelerations``)."""
    return (asm.X0.copy(), asm.free, asm.Minv, asm.f0, asm.beam_nodes, asm.beam_n, asm.beam_e, asm.beam_K,
            asm.drv, float(alpha))


def initial_vector(asm: Assembly) -> np.ndarray:
    """y0 = [free positions, free velocities] (m, m/s)."""
    return np.concatenate([asm.X0[asm.free].ravel(), asm.V0[asm.free].ravel()])


def unpack(asm: Assembly, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """All node positions and velocities (nt, N, 2) from states Y (nt, 4 nf)."""
    nf = len(asm.free)
    X = np.broadcast_to(asm.X0, (len(Y), *asm.X0.shape)).copy()
    V = np.zeros_like(X)
    X[:, asm.free] = Y[:, :2 * nf].reshape(len(Y), nf, 2)
    V[:, asm.free] = Y[:, 2 * nf:].reshape(len(Y), nf, 2)
    return X, V


def highest_frequency(asm: Assembly) -> float:
    """omega_max (rad/s) of the system linearised about its initial shape: the largest
    generalized eigenvalue of (K, M) on the free coordinates, K by central differences of the
    elastic forces (beam_elastic)."""
    import scipy.linalg

    free = [2 * i + c for i in asm.free for c in (0, 1)]
    scale = STIFFNESS_FD * max(float(np.max(asm.beam_e)), 1e-300)

    def force(X):
        Q = np.zeros_like(X)
        for j in range(len(asm.beam_n)):
            beam_elastic(X, asm.beam_nodes[j], asm.beam_n[j], asm.beam_e[j], asm.beam_K[j], Q)
        return Q.ravel()[free]

    K = np.zeros((len(free), len(free)))
    for col, k in enumerate(free):
        X = asm.X0.copy().ravel()
        X[k] += scale
        fp = force(X.reshape(-1, 2))
        X[k] -= 2 * scale
        K[:, col] = -(fp - force(X.reshape(-1, 2))) / (2 * scale)
    M = np.kron(asm.Ms[np.ix_(asm.free, asm.free)], np.eye(2))
    lam = scipy.linalg.eigh(0.5 * (K + K.T), M, eigvals_only=True)
    return float(np.sqrt(max(lam[-1], 0.0)))


def integrate(asm: Assembly, settings: AbsoluteNodalSettings) -> tuple[np.ndarray, np.ndarray, float]:
    """RK4 of eq. 10: sample times (s), states (nt, 4 nf) and CPU time (s)."""
    n_steps = int(round(settings.t_end / settings.step))
    if n_steps < 1 or abs(n_steps * settings.step - settings.t_end) > 1e-9 * settings.t_end:
        raise InputError(f"t_end = {settings.t_end} s is not a whole number of steps of {settings.step} s; "
                         "choose t_end as a multiple of the step")
    omega = highest_frequency(asm)
    if settings.step * omega > RK4_STABILITY:
        raise InputError(f"step {settings.step:g} s is beyond RK4's stability limit for the highest frequency of the "
                         f"beams ({omega:.4g} rad/s); use step <= {RK4_STABILITY / omega:.3g} s or fewer elements / "
                         "a smaller EA")
    every = 1 if settings.rate is None else max(1, int(round(1.0 / (settings.rate * settings.step))))
    params = kernel_params(asm)
    y0 = initial_vector(asm)
    rk4_fixed(rhs, 0.0, y0, settings.step, 1, 1, params)      # compile / load outside the timing
    cpu = time.process_time()
    t, Y = rk4_fixed(rhs, 0.0, y0, settings.step, n_steps, every, params)
    cpu = time.process_time() - cpu
    if not np.all(np.isfinite(Y)):
        bad = t[np.argmax(~np.all(np.isfinite(Y), axis=1))]
        raise InputError(f"the motion became non-finite at t = {bad:g} s (deformations too large for the small-strain "
                         "beams, or an unstable driver); use a smaller step or check the model")
    return t, Y, cpu


def _samples(asm: Assembly, t: np.ndarray, Y: np.ndarray):
    """Per sample: positions X, velocities V, accelerations A (nt, N, 2), multipliers (nt, nd), strain (nt,)."""
    params = kernel_params(asm)
    X, V = unpack(asm, Y)
    A = np.zeros_like(X)
    lam = np.zeros((len(t), asm.drv.shape[0]))
    strain = np.zeros(len(t))
    for s in range(len(t)):
        A[s], lam[s], strain[s] = accelerations(t[s], Y[s], params)
    return X, V, A, lam, strain


def simulate_absolute_nodal(model: AbsoluteNodalModel, settings: AbsoluteNodalSettings = AbsoluteNodalSettings()):
    """Simulate ``model`` -> ``solver.results.Result`` (write it with solver.results.write_results)."""
    asm = assemble(model)
    t, Y, cpu = integrate(asm, settings)
    stats = {"method": "rk4", "cpu_time": cpu, "steps": int(round(settings.t_end / settings.step)), "rejected": 0,
             "h_min": settings.step, "h_max": settings.step, "formulation": "absolute nodal (Kisu Lee)",
             "nodes": int(len(asm.X0)), "dof": int(2 * len(asm.free))}
    return _result(model, asm, t, Y, stats)


def initial_result(model: AbsoluteNodalModel):
    """The ``Result`` of the initial state alone (one sample, no integration): its signal names
    are those of every run of ``model`` (``sidprep simulate --list-signals``)."""
    asm = assemble(model)
    return _result(model, asm, np.zeros(1), initial_vector(asm)[None, :], {"method": "rk4", "steps": 0})


def _result(model: AbsoluteNodalModel, asm: Assembly, t: np.ndarray, Y: np.ndarray, stats: dict):
    """Signals, energies and reactions of the sampled states Y (nt, 4 nf) at times t."""
    from sidprep.solver.effects import EffectsReport
    from sidprep.solver.results import BodyHistory, JointHistory, Result

    X, V, A, lam, strain = _samples(asm, t, Y)
    nt = len(t)
    kinetic = 0.5 * np.einsum("sic,ij,sjc->s", V, asm.Ms, V)
    gravity = -np.einsum("sic,ic->s", X, asm.fg) + asm.gravity_offset
    power = np.zeros(nt)
    for r in range(asm.drv.shape[0]):
        psid = np.array([driver_angle(ti, *asm.drv[r, 2:])[1] for ti in t])
        power += lam[:, r] * psid
    external = np.concatenate([[0.0], np.cumsum(0.5 * (power[1:] + power[:-1]) * np.diff(t))])
    external += -np.einsum("sic,ic->s", X - asm.X0, asm.f0 - asm.fg)          # work of the constant nodal forces
    energy = {"kinetic": kinetic, "strain": strain, "gravity": gravity, "external": external,
              "total": kinetic + strain + gravity - external}
    bodies, phis, phids = {}, {}, {}
    for j, b in enumerate(model.beams):
        nodes, n, e = asm.beam_nodes[j, :asm.beam_n[j]], asm.beam_n[j], asm.beam_e[j]
        kin = [beam_kinematics(X[s], V[s], A[s], nodes, n, e) for s in range(nt)]
        phi = np.unwrap([k[0] for k in kin])
        phid = np.array([k[1] for k in kin])
        phidd = np.array([k[2] for k in kin])
        th = np.array([k[3] for k in kin])
        thd = np.array([k[4] for k in kin])
        thdd = np.array([k[5] for k in kin])
        phis[b.name], phids[b.name] = phi, phid
        zero = np.zeros(nt)
        c, s_ = np.cos(phi), np.sin(phi)
        rot = np.zeros((nt, 3, 3))
        rot[:, 0, 0], rot[:, 0, 1], rot[:, 1, 0], rot[:, 1, 1], rot[:, 2, 2] = c, -s_, s_, c, 1.0
        flex = lambda a: np.column_stack([-a[:, -1] * b.length, a[:, -1] - a[:, 0]])  # noqa: E731 (paper Figs. 9-12)
        x0 = X[:, nodes[0]]
        bodies[b.name] = BodyHistory(
            b.name, position=np.column_stack([x0, zero]), rotation=rot,
            velocity=np.column_stack([V[:, nodes[0]], zero]), omega=np.column_stack([zero, zero, phid]),
            q=flex(th), qd=flex(thd),
            acceleration=np.column_stack([A[:, nodes[0]], zero, zero, zero, phidd, flex(thdd)]))
    markers = {p: np.column_stack([X[:, i], np.zeros(nt)]) for p, i in asm.points.items()}
    joints = {}
    nan3 = np.full((nt, 3), np.nan)
    reaction = np.einsum("ij,sjc->sic", asm.Ms, A) - asm.f0[None]
    for j, b in enumerate(model.beams):                 # elastic forces on the supports
        for s in range(nt):
            Q = np.zeros_like(asm.X0)
            beam_elastic(X[s], asm.beam_nodes[j, :asm.beam_n[j]], asm.beam_n[j], asm.beam_e[j], asm.beam_K[j], Q)
            reaction[s] -= Q
    effort = {d.support: lam[:, r] for r, d in enumerate(model.drivers)}
    for sup in model.supports:
        beam = next(b for b in model.beams if sup.point in b.points)
        F = np.column_stack([reaction[:, asm.points[sup.point]], np.zeros(nt)])
        joints[sup.name] = JointHistory(sup.name, "revolute", force=F, torque=np.zeros((nt, 3)), force_local=F,
                                        torque_local=np.zeros((nt, 3)), coordinate=phis[beam.name],
                                        rate=phids[beam.name], effort=effort.get(sup.name, np.full(nt, np.nan)))
    pinned = {s.point for s in model.supports}
    for p in asm.points:
        on = [b.name for b in model.beams if p in b.points]
        if len(on) >= 2 and p not in pinned:
            joints[p] = JointHistory(p, "revolute", force=nan3, torque=nan3, force_local=nan3, torque_local=nan3,
                                     coordinate=phis[on[1]] - phis[on[0]], rate=phids[on[1]] - phids[on[0]],
                                     effort=np.full(nt, np.nan))
    derr = np.zeros(nt)
    for r, d in enumerate(model.drivers):
        j = int(asm.drv[r, 0])
        k = -1 if asm.drv[r, 1] > 0.5 else 0
        nodes, n, e = asm.beam_nodes[j, :asm.beam_n[j]], asm.beam_n[j], asm.beam_e[j]
        for s in range(nt):
            val = _driver_value(X[s], V[s], A[s], nodes, n, e, k == -1)[0]
            derr[s] = max(derr[s], abs(_wrap(val - driver_angle(t[s], *asm.drv[r, 2:])[0])))
    notes = ("absolute nodal beams: every effect of the formulation is included (no effect selection); "
             "force of beam-beam revolutes not computed (NaN)",)
    return Result(t=t, bodies=bodies, joints=joints, markers=markers, energy=energy, constraint_error=derr,
                  effects=EffectsReport(bodies={}, notes=notes), stats=stats)


# ---------------------------------------------------------------------------------------------
# scene files


#: the top-level tables of an absolute-nodal scene file
SCENE_TABLES = ("scene", "solver", "output", "beams", "supports", "drivers", "forces")


@dataclass(frozen=True)
class AbsoluteNodalScene:
    """A parsed absolute-nodal scene: the model, the RK4 settings and the output settings."""

    model: AbsoluteNodalModel
    settings: AbsoluteNodalSettings
    output: object


def is_absolute_nodal_scene(root: dict) -> bool:
    """True when a parsed scene TOML describes absolute-nodal beams (it has [beams.<name>] tables)."""
    return "beams" in root


def _angle(t, key: str, default: float = 0.0) -> float:
    """``key`` in rad or ``key_deg`` in degrees (not both); rad."""
    if t.has(key) and t.has(key + "_deg"):
        t.fail(key, f"given both as {key} (rad) and {key}_deg", "keep one of them")
    if t.has(key + "_deg"):
        return math.radians(t.number(key + "_deg"))
    return t.number(key, default)


def load_absolute_nodal_scene(root: dict, source, t_end: float | None = None) -> AbsoluteNodalScene:
    """Parse a scene TOML (already read: ``root``) of absolute-nodal beams.

    Tables: [scene] title, gravity = [gx, gy] (m/s^2, X-Y plane), gravity_zero = "origin" |
    "hanging"; [solver] method = "rk4", t_end (s), step (s); [output] as every scene;
    [beams.<name>] length (m), mass (kg), EI (N m^2), EA (N), elements, points = [start, end],
    angle (rad) | angle_deg, rate (rad/s) | rate_deg; [supports.<name>] point, position = [x, y];
    [drivers.<name>] support, beam, speed (rad/s) | speed_deg, delta | delta_deg, duration (s);
    [forces.<name>] point, force = [fx, fy] (N).  ``t_end`` overrides [solver] t_end.
    """
    from sidprep.solver.scene import _output_settings, _subtables, _Table

    source = Path(source)
    for key in root:
        if key not in SCENE_TABLES:
            raise InputError(f"{source}: unknown top-level table `{key}` in an absolute-nodal scene; "
                             f"use: {', '.join(SCENE_TABLES)}")
    head = _Table(source, "scene", root.get("scene", {}))
    title = head.string("title", source.stem)
    gravity = tuple(head.array("gravity", [0.0, -9.81], shape=(2,)))
    zero = head.string("gravity_zero", "origin", ("origin", "hanging"))
    head.finish()
    sol = _Table(source, "solver", root.get("solver", {}))
    sol.string("method", "rk4", ("rk4",))
    settings_t_end = sol.number("t_end", positive=True)
    if t_end is not None:
        if not t_end > 0:
            sol.fail("t_end", f"--t-end must be > 0, got {t_end}", "give a positive end time in s")
        settings_t_end = t_end
    step = sol.number("step", 2.5e-4, positive=True)
    sol.finish()
    output = _output_settings(source, root)
    beams = []
    for name, t in _subtables(source, root, "beams"):
        points = t.strings("points")
        if len(points) != 2:
            t.fail("points", f"needs two point names, got {len(points)}", 'write e.g. points = ["pin", "elbow"]')
        beams.append(Beam(name, t.number("length", positive=True), t.number("mass", positive=True),
                          t.number("EI", positive=True), t.number("EA", positive=True), t.integer("elements", 4),
                          tuple(points), _angle(t, "angle"), _angle(t, "rate")))
        t.finish()
    if not beams:
        raise InputError(f"{source}: no [beams.<name>] tables; add at least one beam")
    supports = []
    for name, t in _subtables(source, root, "supports"):
        supports.append(Support(name, t.string("point"), tuple(t.array("position", [0.0, 0.0], shape=(2,)))))
        t.finish()
    drivers = []
    for name, t in _subtables(source, root, "drivers"):
        drivers.append(Driver(name, t.string("support"), t.string("beam"), _angle(t, "speed"), _angle(t, "delta"),
                              t.number("duration", 0.0, nonnegative=True)))
        t.finish()
    forces = []
    for name, t in _subtables(source, root, "forces"):
        forces.append(NodalForce(name, t.string("point"), tuple(t.array("force", shape=(2,)))))
        t.finish()
    model = AbsoluteNodalModel(tuple(beams), tuple(supports), tuple(drivers), tuple(forces), gravity, zero, title)
    from sidprep.solver.results import signal

    try:                                                 # validate before the long work
        first = initial_result(model)
        for name in output.signals:
            signal(first, name)
    except InputError as exc:
        where = "[output] signals: " if "signal" in str(exc) else ""
        raise InputError(f"{source}: {where}{exc}") from None
    return AbsoluteNodalScene(model, AbsoluteNodalSettings(settings_t_end, step, output.rate), output)
