"""Numbered nodes and the constant matrices of an absolute-nodal model (Python, once per run):
masses, element stiffnesses, loads, initial positions and velocities, the compiled kernels' record."""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from sidprep.errors import InputError
from sidprep.solver.absolute_nodal.model import AbsoluteNodalModel, check_model
from sidprep.solver.core.absolute_nodal import BeamSystem

#: Baumgarte stabilisation of the driver constraints, Phi'' + 2 a Phi' + a^2 Phi = 0 (1/s)
BAUMGARTE_RATE = 20.0
#: two points given different positions by the initial angles (closed loop) beyond this (m)
CLOSURE_TOL = 1e-9


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
    check_model(model)
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


def beam_system(asm: Assembly, alpha: float = BAUMGARTE_RATE) -> BeamSystem:
    """The compiled kernels' record of ``asm`` (sidprep/solver/core/absolute_nodal.pyx), drivers
    stabilised at the Baumgarte rate ``alpha`` (1/s)."""
    return BeamSystem(asm, float(alpha))


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
