"""A multibody system: bodies, joints, drivers, force elements; simulate() -> Result.

Usage::

    from sidprep.solver.system import System, FlexibleBody, Revolute   # all public names re-exported
    sys = System(gravity=(0, 0, -9.81))
    bar = sys.add(FlexibleBody("bar.sid.h5", name="bar"))
    pivot = sys.add(Revolute(sys.ground.marker(rotation=...), bar.node_marker(node_id=1)))
    res = sys.simulate(1.0, h=1e-3, effects="auto")
    res.bodies["bar"].q, res.joints[pivot.name].force, res.energy["total"], res.effects.text()

Equations (docs/solver.md): for the generalised velocities u (per body [v_O inertial, omega
body, qd]) and the multipliers lambda of the kept constraint rows,

    M(x) u_dot - f(x, u, t) + B_F(x)^T lambda = 0,     g(x, t) = 0,

with g_dot = B(x) u + b_t(t).  B_F differs from B only by the load-stiffening parts K0F, K0M
of node markers (sid-spec 5.2).  Redundant constraint rows (e.g. a planar slider-crank built
from 3D revolute joints) are detected at the consistent initial state and dropped.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from sidprep.solver.bodies import (Body, FlexibleBody, Ground, Marker, RigidBody, _MassBody, _body_equations,
                           _marker_kinematics)
from sidprep.solver.effects import EFFECTS, EffectsReport
from sidprep.solver.forces import (JointForce, JointFriction, PointForce, PointTorque, SpringDamper, Table,
                           bump_stop)
from sidprep.solver.joints import (ConstantSpeed, Cylindrical, Driver, Fixed, Joint, JOINT_TYPES, Planar,
                           Prismatic, Revolute, SmoothStart, Spherical, TabulatedMotion, _joint_rows)
from sidprep.solver.kinematics import COMPILED, cross, exp_so3, jit, matmul

__all__ = [
    "System", "Result", "BodyHistory", "JointHistory", "Ground", "RigidBody", "FlexibleBody", "Marker",
    "Spherical", "Revolute", "Cylindrical", "Prismatic", "Planar", "Fixed", "JOINT_TYPES", "Driver",
    "ConstantSpeed", "SmoothStart", "TabulatedMotion", "PointForce", "PointTorque", "SpringDamper",
    "bump_stop", "JointForce", "JointFriction", "Table", "EFFECTS",
]

#: a constraint row is redundant when its component independent of the rows kept before it is
#: below this fraction of its norm (Gram-Schmidt at the initial state)
REDUNDANCY_TOL = 1e-8


@dataclass
class BodyHistory:
    """Time series of one body; arrays have leading dimension nt (output samples).

    position (nt, 3) r_O, m; rotation (nt, 3, 3) A (body -> inertial); velocity (nt, 3) v_O,
    m/s inertial; omega (nt, 3) rad/s body components; q, qd (nt, nq); acceleration
    (nt, 6 + nq) du/dt = [dv_O/dt, omega_dot, q_ddot].
    """

    name: str
    position: np.ndarray
    rotation: np.ndarray
    velocity: np.ndarray
    omega: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    acceleration: np.ndarray


@dataclass
class JointHistory:
    """Reaction of one joint / driver on body 2 at marker 2.

    force, torque (nt, 3), N / N m, inertial components; force_local, torque_local (nt, 3) in
    marker-1 components; coordinate, rate (nt,) joint angle (rad) or slide (m) and its rate
    (NaN for joints without a coordinate); effort (nt,) driver torque/force along z1 (drivers).
    """

    name: str
    kind: str
    force: np.ndarray
    torque: np.ndarray
    force_local: np.ndarray
    torque_local: np.ndarray
    coordinate: np.ndarray
    rate: np.ndarray
    effort: np.ndarray


@dataclass
class Result:
    """Everything a simulation produced (solver/results.py writes it to files).

    t (nt,) s; bodies {name: BodyHistory}; joints {name: JointHistory} (joints and drivers);
    markers {name: (nt, 3)} inertial marker positions; energy {kinetic, strain, gravity,
    spring, dissipated, external, total} (nt,) J (total = kinetic + strain + gravity + spring
    + dissipated - external: constant up to integration error); constraint_error (nt,) max |g|;
    effects: EffectsReport; stats: method, cpu_time (s), steps, rejected, newton_iterations,
    jacobians, dropped constraint rows, h_min/h_max used.
    """

    t: np.ndarray
    bodies: dict
    joints: dict
    markers: dict
    energy: dict
    constraint_error: np.ndarray
    effects: EffectsReport
    stats: dict = field(default_factory=dict)


@jit
def _kernel_marker(R, A, Q, qoff, b, position, rotation, phi, psi):  # pragma: no cover - compiled
    """(p, A_marker, JT, JR) of a marker on body b (-1: ground, position/rotation inertial)."""
    if b < 0:
        return position, rotation, np.zeros((3, 0)), np.zeros((3, 0))
    p, rot, jt, jr, _ = _marker_kinematics(R[b], A[b], Q[qoff[b]:qoff[b + 1]], position, rotation, phi, psi)
    return p, rot, jt, jr


@jit
def _add_rows(B, r0, col, ct, cr, jt, jr):  # pragma: no cover - compiled
    """B[r0:r0+m, col:col+ndof] += ct JT + cr JR (row coefficients times marker Jacobians)."""
    for r in range(ct.shape[0]):
        for a in range(3):
            for k in range(jt.shape[1]):
                B[r0 + r, col + k] += ct[r, a] * jt[a, k] + cr[r, a] * jr[a, k]


@jit
def _motion_value(motion, t):  # pragma: no cover - compiled
    """Value of a driver motion [kind, start, speed, ramp_time] at t: kind 0 ConstantSpeed, 1
    SmoothStart (joints.py)."""
    start, w, ramp = motion[1], motion[2], motion[3]
    if motion[0] == 0.0:
        return start + w * t
    if t <= 0.0:
        return start
    if t < ramp:
        return start + 0.5 * w * (t - ramp / np.pi * np.sin(np.pi * t / ramp))
    return start + w * (t - 0.5 * ramp)


@jit
def _system_kernel(R, A, Q, u, t, refs, data):  # pragma: no cover - compiled
    """M (n, n), f (n,), g (m_all,), B (m_all, n) of a system of bodies and joints, in one call.

    The same mathematics as System.mass_and_forces + constraint_rows (the Python path): body
    equations with the rotated translational row, marker kinematics, joint rows.  R (nb, 3),
    A (nb, 3, 3), Q (sum nq,) with offsets qoff (nb + 1,); u (n,) with body offsets uoff (nb,);
    bodies: packed BodyModel arrays; markers: body index (-1 = ground), c, AP0 R_m, Phi, Psi;
    rows[j] the row codes of joint j, joint_mk (nj, 2) its markers, roff (nj + nd + 1,) row
    offsets of the joints, then the drivers; drivers: drv_mk (nd, 2) markers, drv_kind (nd,) 0
    angle / 1 slide, drv_motion (nd, 4) (_motion_value); refs (nd,) the angle-unwrapping
    references at time t.  Also returns the driven joint coordinates (nd,).
    data = (qoff, uoff, gravity, bodies, mk_body, mk_pos, mk_rot, mk_phi, mk_psi, rows, joint_mk, roff,
    drv_mk, drv_kind, drv_motion).
    """
    (qoff, uoff, gravity, bodies, mk_body, mk_pos, mk_rot, mk_phi, mk_psi, rows, joint_mk, roff, drv_mk, drv_kind,
     drv_motion) = data
    n = u.shape[0]
    mass = np.zeros((n, n))
    f = np.zeros(n)
    for i in range(len(bodies)):
        p = bodies[i]
        s = uoff[i]
        nq = qoff[i + 1] - qoff[i]
        Ai = A[i]
        gk = np.zeros(3)
        for a in range(3):
            for b in range(3):
                gk[a] += Ai[b, a] * gravity[b]
        mk, h = _body_equations(Q[qoff[i]:qoff[i + 1]].copy(), u[s + 6:s + 6 + nq].copy(), u[s + 3:s + 6].copy(),
                                gk, p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], p[8], p[9], p[10],
                                p[11], p[12], p[13], p[14], p[15], p[16], p[17], p[18])
        top = matmul(Ai, mk[:3, 3:])
        mk[:3, 3:] = top
        mk[3:, :3] = top.T
        mass[s:s + 6 + nq, s:s + 6 + nq] = mk
        for a in range(3):
            for b in range(3):
                f[s + a] += Ai[a, b] * h[b]
        f[s + 3:s + 6 + nq] += h[3:]
    m_all = roff[-1]
    g = np.zeros(m_all)
    B = np.zeros((m_all, n))
    for j in range(joint_mk.shape[0]):
        r0, r1 = roff[j], roff[j + 1]
        k1, k2 = joint_mk[j, 0], joint_mk[j, 1]
        b1, b2 = mk_body[k1], mk_body[k2]
        p1, a1, jt1, jr1 = _kernel_marker(R, A, Q, qoff, b1, mk_pos[k1], mk_rot[k1], mk_phi[k1], mk_psi[k1])
        p2, a2, jt2, jr2 = _kernel_marker(R, A, Q, qoff, b2, mk_pos[k2], mk_rot[k2], mk_phi[k2], mk_psi[k2])
        gj, c = _joint_rows(rows[j], p1, a1, p2, a2)
        g[r0:r1] = gj
        if b1 >= 0:
            _add_rows(B, r0, uoff[b1], c[0], c[1], jt1, jr1)
        if b2 >= 0:
            _add_rows(B, r0, uoff[b2], c[2], c[3], jt2, jr2)
    nj = joint_mk.shape[0]
    coords = np.zeros(drv_mk.shape[0])
    for d in range(drv_mk.shape[0]):  # Driver rows: coordinate - motion(t) (joints.Joint.coordinate)
        r0 = roff[nj + d]
        k1, k2 = drv_mk[d, 0], drv_mk[d, 1]
        b1, b2 = mk_body[k1], mk_body[k2]
        p1, a1, jt1, jr1 = _kernel_marker(R, A, Q, qoff, b1, mk_pos[k1], mk_rot[k1], mk_phi[k1], mk_psi[k1])
        p2, a2, jt2, jr2 = _kernel_marker(R, A, Q, qoff, b2, mk_pos[k2], mk_rot[k2], mk_phi[k2], mk_psi[k2])
        z = a1[:, 2].copy()
        c = np.zeros((4, 1, 3))
        if drv_kind[d] == 0:
            sin_part = a1[0, 1] * a2[0, 0] + a1[1, 1] * a2[1, 0] + a1[2, 1] * a2[2, 0]
            cos_part = a1[0, 0] * a2[0, 0] + a1[1, 0] * a2[1, 0] + a1[2, 0] * a2[2, 0]
            raw = np.arctan2(sin_part, cos_part)
            value = refs[d] + (raw - refs[d] + np.pi) % (2 * np.pi) - np.pi
            c[1, 0], c[3, 0] = -z, z
        else:
            dist = p2 - p1
            value = z @ dist
            c[0, 0], c[1, 0], c[2, 0] = -z, cross(z, dist), z
        coords[d] = value
        g[r0] = value - _motion_value(drv_motion[d], t)
        if b1 >= 0:
            _add_rows(B, r0, uoff[b1], c[0], c[1], jt1, jr1)
        if b2 >= 0:
            _add_rows(B, r0, uoff[b2], c[2], c[3], jt2, jr2)
    return mass, f, g, B, coords


def _typed_list(items: list, dummy=None):
    """numba typed List of items; an empty one still typed like ``dummy``."""
    from numba.typed import List

    out = List(items or [dummy])
    if not items:
        out.pop()
    return out


def _motion_row(motion) -> list:
    """[kind, start, speed, ramp_time] of a ConstantSpeed (kind 0) or SmoothStart (1) motion."""
    if isinstance(motion, ConstantSpeed):
        return [0.0, motion.start, motion.speed, 0.0]
    return [1.0, motion.start, motion.speed, motion.ramp_time]


def _writable_float(x) -> np.ndarray:
    """A C-contiguous writable float64 copy (numba typed lists need one array type)."""
    return np.array(x, dtype=float, order="C")


class _Kernel:
    """Flat arrays of a system of bodies, joints and drivers (ConstantSpeed / SmoothStart) for
    ``_system_kernel`` (force elements, other motions, load stiffening and second-order inertia
    take the Python path)."""

    def __init__(self, system: "System", modes: list | None = None):
        """``modes``: per body the indices of the modal coordinates to keep (default all); the
        kernel then works on the reduced coordinates u[u_index], q[q_index]."""
        modes = modes or [np.arange(b.nq) for b in system.bodies]
        markers = list({id(mk): mk for c in system.joints + system.drivers
                        for mk in (c.marker1, c.marker2)}.values())
        index = {id(mk): k for k, mk in enumerate(markers)}
        self.qoff = np.concatenate([[0], np.cumsum([len(k) for k in modes])]).astype(np.int64)
        self.uoff = (np.arange(len(modes)) * 6 + self.qoff[:-1]).astype(np.int64)
        self.qoff_full = np.concatenate([[0], np.cumsum([b.nq for b in system.bodies])]).astype(int)
        self.q_index = np.concatenate([np.asarray(k, int) + self.qoff_full[i] for i, k in enumerate(modes)]
                                      + [np.zeros(0, int)])
        self.u_index = np.concatenate([np.concatenate([np.arange(sl.start, sl.start + 6), sl.start + 6 + np.asarray(k, int)])
                                       for sl, k in zip(system._slices, modes)] + [np.zeros(0, int)])
        self.bodies = _typed_list([tuple(np.array(v) if isinstance(v, np.ndarray) else v
                                         for v in b.model.restricted(k)._packed) for b, k in zip(system.bodies, modes)])
        self.mk_body = np.array([system._index.get(id(mk.body), -1) for mk in markers], dtype=np.int64)
        inertial = [mk.kinematics(np.zeros(3), np.eye(3), None) if mk.body.ndof == 0 else None for mk in markers]
        own = _writable_float
        vec, mat = np.zeros(3), np.zeros((3, 3))

        def shape(mk, values):
            b = system._index.get(id(mk.body), -1)
            nq = len(modes[b]) if b >= 0 else 0
            return own(np.zeros((3, nq)) if values is None else values[:, modes[b]])

        self.mk_pos = _typed_list([own(mk.position if k is None else k[0]) for mk, k in zip(markers, inertial)], vec)
        self.mk_rot = _typed_list([own(mk.rotation if k is None else k[1]) for mk, k in zip(markers, inertial)], mat)
        self.mk_phi = _typed_list([shape(mk, mk.phi) for mk in markers], mat)
        self.mk_psi = _typed_list([shape(mk, mk.psi) for mk in markers], mat)
        self.rows = _typed_list([np.array(j._rows, dtype=np.int64) for j in system.joints],
                                np.zeros((0, 3), dtype=np.int64))
        self.joint_mk = np.array([[index[id(j.marker1)], index[id(j.marker2)]] for j in system.joints],
                                 dtype=np.int64).reshape(-1, 2)
        self.roff = np.concatenate([[0], np.cumsum([c.nrows for c in system.joints + system.drivers])]).astype(np.int64)
        drivers = system.drivers
        drv_mk = np.array([[index[id(d.marker1)], index[id(d.marker2)]] for d in drivers], dtype=np.int64).reshape(-1, 2)
        drv_kind = np.array([d.joint.coordinate_kind == "slide" for d in drivers], dtype=np.int64)
        drv_motion = np.array([_motion_row(d.motion) for d in drivers], dtype=float).reshape(-1, 4)
        self.data = (self.qoff, self.uoff, np.asarray(system.gravity, float), self.bodies, self.mk_body,
                     self.mk_pos, self.mk_rot, self.mk_phi, self.mk_psi, self.rows, self.joint_mk, self.roff,
                     drv_mk, drv_kind, drv_motion)

    @staticmethod
    def usable(system: "System") -> bool:
        """True when every element of the system is covered by the compiled kernel."""
        return COMPILED and bool(system.bodies) and not system.forces and all(
            isinstance(d.motion, (ConstantSpeed, SmoothStart)) for d in system.drivers) and all(
            b.model.P is None and not (b.load_stiffening and any(
                mk.k0f is not None or mk.k0m is not None for mk in b.markers)) for b in system.bodies)

    def arrays(self, pose: "Pose"):
        """(R (nb, 3), A (nb, 3, 3), Q (kept modal coordinates,)) of a Pose."""
        return np.array(pose.r), np.array(pose.A), np.concatenate(pose.q + [np.zeros(0)])[self.q_index]

    def pose(self, R, A, Q) -> "Pose":
        """The Pose of the flat arrays (inverse of ``arrays``)."""
        q = np.zeros(self.qoff_full[-1])
        q[self.q_index] = Q
        return Pose(list(R.copy()), list(A.copy()), [q[a:b] for a, b in zip(self.qoff_full[:-1], self.qoff_full[1:])])


class Pose:
    """Positions of all bodies: lists r (3,), A (3, 3), q (nq,) indexed like System.bodies."""

    __slots__ = ("r", "A", "q")

    def __init__(self, r, A, q):
        self.r, self.A, self.q = r, A, q

    def copy(self) -> "Pose":
        return Pose([x.copy() for x in self.r], [x.copy() for x in self.A], [x.copy() for x in self.q])


class Context:
    """One evaluation of the system at (pose, u, t, lambda): marker kinematics (cached), the
    generalised forces of all elements and the constraint rows."""

    def __init__(self, system: "System", pose: Pose, u: np.ndarray, t: float, lam: np.ndarray | None):
        self.system, self.pose, self.u, self.t = system, pose, u, t
        self.lam = lam
        self.f = np.zeros(system.n)
        self._kin: dict = {}
        self.loads: dict = {}

    def body_index(self, body: Body) -> int:
        return self.system._index[id(body)]

    def kin(self, marker: Marker):
        """(p, A_marker, JT, JR, d) of a marker, inertial components (bodies.Marker.kinematics)."""
        k = self._kin.get(id(marker))
        if k is None:
            b = marker.body
            if isinstance(b, Ground):
                k = marker.kinematics(np.zeros(3), np.eye(3), None)
            else:
                i = self.body_index(b)
                k = marker.kinematics(self.pose.r[i], self.pose.A[i], self.pose.q[i])
            self._kin[id(marker)] = k
        return k

    def body_u(self, body: Body) -> np.ndarray:
        if isinstance(body, Ground):
            return np.zeros(0)
        sl = self.system._slices[self.body_index(body)]
        return self.u[sl]

    def marker_velocity(self, marker: Marker):
        """(v, omega) of the marker, inertial components."""
        k = self.kin(marker)
        ub = self.body_u(marker.body)
        return k[2] @ ub, k[3] @ ub

    def add_load(self, marker: Marker, force=None, torque=None) -> None:
        """Add a force (at the marker point) and/or torque, inertial components, N / N m."""
        b = marker.body
        f = np.zeros(3) if force is None else np.asarray(force, float)
        tq = np.zeros(3) if torque is None else np.asarray(torque, float)
        old = self.loads.get(id(marker))
        self.loads[id(marker)] = (marker, f + old[1], tq + old[2]) if old else (marker, f, tq)
        if isinstance(b, Ground):
            return
        i = self.body_index(b)
        k = self.kin(marker)
        jt, jr = marker.force_jacobians(self.pose.A[i], self.pose.q[i], k[2], k[3])
        self.f[self.system._slices[i]] += jt.T @ f + jr.T @ tq

    def joint_coordinate(self, joint: Joint):
        """(value, rate) of a joint coordinate (rad or m)."""
        k1, k2 = self.kin(joint.marker1), self.kin(joint.marker2)
        value, row = joint.coordinate(k1, k2)
        v1, w1 = self.marker_velocity(joint.marker1)
        v2, w2 = self.marker_velocity(joint.marker2)
        return value, float(row[0] @ v1 + row[1] @ w1 + row[2] @ v2 + row[3] @ w2)

    def add_joint_load(self, joint: Joint, value: float) -> None:
        """Generalised force along the joint coordinate (on body 2; reaction on body 1)."""
        c = joint.coordinate(self.kin(joint.marker1), self.kin(joint.marker2))[1]
        self.add_load(joint.marker1, force=value * c[0], torque=value * c[1])
        self.add_load(joint.marker2, force=value * c[2], torque=value * c[3])

    def joint_multipliers(self, joint: Joint) -> np.ndarray:
        """Multipliers of all rows of a joint (0 for dropped rows or when unknown)."""
        sl = self.system._row_slices[id(joint)]
        if self.lam is None:
            return np.zeros(sl.stop - sl.start)
        full = np.zeros(self.system.m_all)
        full[self.system.kept] = self.lam
        return full[sl]


class System:
    """A multibody system.  Build it with ``add``; integrate with ``simulate``.

    Parameters
    ----------
    gravity : (3,) m/s^2, inertial components (used when the gravity effect is on)
    effects : "auto" (default), "all", or a list of effect names (solver/effects.py), used by
        every flexible body that does not name its own
    planar : None (default: detect a planar scene and integrate its in-plane coordinates only),
        True (require it) or False (always the 3D coordinates); see integrate.planar_coordinates
    """

    def __init__(self, gravity=(0.0, 0.0, -9.81), effects="auto", planar=None):
        self.gravity = np.asarray(gravity, float)
        self.effects = effects
        self.planar = planar
        self.ground = Ground()
        self.bodies: list[_MassBody] = []
        self.joints: list[Joint] = []
        self.drivers: list[Driver] = []
        self.forces: list = []

    # ------------------------------------------------------------------ building
    def add(self, item):
        """Add a body, joint, driver or force element; returns it."""
        if isinstance(item, (RigidBody, FlexibleBody)):
            if any(b.name == item.name for b in self.bodies):
                raise ValueError(f"duplicate body name '{item.name}'")
            self.bodies.append(item)
        elif isinstance(item, Joint):
            self.joints.append(item)
        elif isinstance(item, Driver):
            self.drivers.append(item)
        elif hasattr(item, "apply"):
            self.forces.append(item)
        else:
            raise TypeError(f"cannot add {type(item).__name__} to a System")
        return item

    # ------------------------------------------------------------------ compiled layout
    def _compile(self) -> None:
        self._index = {id(b): i for i, b in enumerate(self.bodies)}
        self._slices, off = [], 0
        for b in self.bodies:
            self._slices.append(slice(off, off + b.ndof))
            off += b.ndof
        self.n = off
        self.constraints = list(self.joints) + list(self.drivers)
        self._row_slices, r = {}, 0
        for c in self.constraints:
            for mk in (c.marker1, c.marker2):
                if not isinstance(mk.body, Ground) and id(mk.body) not in self._index:
                    raise ValueError(f"'{c.name}': marker '{mk.name}' is on a body not added to the system")
            self._row_slices[id(c)] = slice(r, r + c.nrows)
            r += c.nrows
        self.m_all = r
        self.kept = np.ones(r, bool)
        self._accept_ctx = None
        for j in self.joints:  # per-run state: each run unwraps its angles from the start
            j._angle_ref = 0.0

    def initial_pose(self) -> tuple[Pose, np.ndarray]:
        """Pose and velocities from the bodies' initial values (not yet consistent)."""
        pose = Pose([b.position0.copy() for b in self.bodies], [b.rotation0.copy() for b in self.bodies],
                    [b.initial_q()[0].copy() for b in self.bodies])
        u = np.concatenate([np.concatenate([b.velocity0, b.omega0, b.initial_q()[1]]) for b in self.bodies]) \
            if self.bodies else np.zeros(0)
        return pose, u

    def advance(self, pose: Pose, delta: np.ndarray) -> Pose:
        """Pose moved by the increment delta (n,): r + dr, A exp(dtheta), q + dq (Lie group)."""
        r, A, q = [], [], []
        for i, sl in enumerate(self._slices):
            d = delta[sl]
            r.append(pose.r[i] + d[:3])
            A.append(pose.A[i] @ exp_so3(d[3:6]))
            q.append(pose.q[i] + d[6:])
        return Pose(r, A, q)

    # ------------------------------------------------------------------ evaluation
    def mass_and_forces(self, ctx: Context) -> np.ndarray:
        """Mass matrix M (n, n) and body forces added into ctx.f (sid-spec 5.2, rotated rows)."""
        n = self.n
        mass = np.zeros((n, n))
        g = self.gravity
        for i, b in enumerate(self.bodies):
            sl = self._slices[i]
            A = ctx.pose.A[i]
            q = ctx.pose.q[i]
            ub = ctx.u[sl]
            model = b.model
            mk, h = model.equations(q, ub[6:], ub[3:6], A.T @ g)
            h[:3] = A @ h[:3]
            ctx.f[sl] += h
            m = mk.copy()
            m[:3, 3:] = A @ mk[:3, 3:]
            m[3:, :3] = m[:3, 3:].T
            mass[sl, sl] = m
        return mass

    def constraint_rows(self, ctx: Context, force_rows: bool = True):
        """g (m_all,), B (m_all, n), B_F (m_all, n) and the per-row marker coefficients."""
        m, n = self.m_all, self.n
        g = np.zeros(m)
        B = np.zeros((m, n))
        BF = np.zeros((m, n)) if force_rows else None
        coeffs = {}
        for c in self.constraints:
            sl = self._row_slices[id(c)]
            k1, k2 = ctx.kin(c.marker1), ctx.kin(c.marker2)
            if isinstance(c, Driver):
                gc, ct1, cr1, ct2, cr2 = c.constraint(k1, k2, ctx.t)
            else:
                gc, ct1, cr1, ct2, cr2 = c.constraint(k1, k2)
            g[sl] = gc
            coeffs[id(c)] = (ct1, cr1, ct2, cr2)
            for mk, ct, cr in ((c.marker1, ct1, cr1), (c.marker2, ct2, cr2)):
                if isinstance(mk.body, Ground):
                    continue
                i = self._index[id(mk.body)]
                bs = self._slices[i]
                k = ctx.kin(mk)
                rows = ct @ k[2] + cr @ k[3]
                B[sl, bs] += rows
                if force_rows:
                    jt, jr = mk.force_jacobians(ctx.pose.A[i], ctx.pose.q[i], k[2], k[3])
                    BF[sl, bs] += rows if jt is k[2] and jr is k[3] else ct @ jt + cr @ jr
        return g, B, BF, coeffs

    def rate_terms(self, t: float) -> np.ndarray:
        """b_t (m_all,) in g_dot = B u + b_t (drivers only)."""
        b = np.zeros(self.m_all)
        for d in self.drivers:
            b[self._row_slices[id(d)]] = d.rate_term(t)
        return b

    def evaluate(self, pose: Pose, u: np.ndarray, t: float, lam: np.ndarray | None = None):
        """(M, f, g, B, B_F, ctx) at a state; g, B, B_F restricted to the kept rows."""
        ctx = Context(self, pose, u, t, lam)
        mass = self.mass_and_forces(ctx)
        for fe in self.forces:
            fe.apply(ctx)
        g, B, BF, coeffs = self.constraint_rows(ctx)
        ctx.coeffs = coeffs
        k = self.kept
        return mass, ctx.f, g[k], B[k], BF[k], ctx

    def velocity_constraint(self, pose: Pose, u: np.ndarray, t: float) -> np.ndarray:
        """g_dot = B u + b_t on the kept rows."""
        ctx = Context(self, pose, u, t, None)
        _, B, _, _ = self.constraint_rows(ctx, force_rows=False)
        return (B @ u + self.rate_terms(t))[self.kept]

    def gamma(self, pose: Pose, u: np.ndarray, t: float, eps: float = 1e-6) -> np.ndarray:
        """d/dt (B u + b_t) at constant u (central difference along the motion), kept rows."""
        plus = self.velocity_constraint(self.advance(pose, eps * u), u, t + eps)
        minus = self.velocity_constraint(self.advance(pose, -eps * u), u, t - eps)
        return (plus - minus) / (2 * eps)

    def accept(self, pose: Pose) -> None:
        """Called once per accepted step: update the joint-angle unwrapping references.

        The integrator leaves its last evaluation (within a Newton correction of ``pose``) in
        ``self._accept_ctx`` so that the marker kinematics are not recomputed.
        """
        ctx = getattr(self, "_accept_ctx", None) or Context(self, pose, np.zeros(self.n), 0.0, None)
        self._accept_ctx = None
        for j in self.joints:
            if j.coordinate_kind:
                j.accept(ctx.kin(j.marker1), ctx.kin(j.marker2))

    # ------------------------------------------------------------------ simulation
    def simulate(self, t_end: float, *, h: float = 1e-3, method: str = "genalpha", rho_inf: float = 0.9,
                 rtol: float | None = None, atol: float = 1e-9, effects=None, output_dt: float | None = None,
                 static_start: bool = False, newton_tol: float = 1e-8, max_steps: int = 10_000_000,
                 baumgarte: float = 20.0) -> Result:
        """Integrate from t = 0 to t_end and return the Result.

        Parameters
        ----------
        t_end : end time, s
        h : (initial) step size, s
        method : "genalpha" (implicit Lie-group generalised-alpha, index 3, Arnold-Bruls) or
            "rk45" / "dop853" (explicit scipy solve_ivp on the index-1 ODE with Baumgarte
            stabilisation; for non-stiff scenes)
        rho_inf : spectral radius at infinity of generalised-alpha (1 = no numerical damping)
        rtol, atol : step-size control (None = fixed step h for genalpha); for rk45/dop853 the
            solve_ivp tolerances (default rtol 1e-8)
        effects : overrides the system's effects choice
        output_dt : sampling interval of the results (default: every step / h)
        static_start : start with the elastic coordinates in quasi-static equilibrium with the
            initial rigid-body accelerations (no start-up vibration)
        newton_tol : Newton tolerance: position correction / system length L per step
        baumgarte : stabilisation rate (1/s) of the explicit methods
        """
        from sidprep.solver.integrate import integrate

        return integrate(self, t_end, h=h, method=method, rho_inf=rho_inf, rtol=rtol, atol=atol,
                         effects=self.effects if effects is None else effects, output_dt=output_dt,
                         static_start=static_start, newton_tol=newton_tol, max_steps=max_steps,
                         baumgarte=baumgarte)
