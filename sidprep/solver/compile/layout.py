"""The compiled layout of a System: every body, marker, joint, driver, curve and force element
as flat arrays (a namedtuple; the compiled core's Layout record views them), built once per run.

Coordinates: body i has positions (R[i] (3,), A[i] (3, 3), Q[qoff[i]:qoff[i+1]]) and
velocities u[uoff[i]:uoff[i+1]] = [v_O, omega, qd].  Constraint rows: the joints' rows in
order, then one row per driver.
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np

from sidprep.solver.core.body import (CR0, CR1, CT0, CT1, DE, F_CORIOLIS, F_CR1, F_CT1, F_DAMPING, F_GRAVITY, F_INERTIA,
                                     F_OE0, F_OE1, F_PRELOAD, F_SECOND, GE, GR0, I0, I1, KE, KS0, KS1, MD0, MD1, ME,
                                     N_FLAGS, N_TERMS, OE0, OE1, P2)
from sidprep.solver.core.body import body_matrices as packed_body_matrices
from sidprep.solver.core.constraints import ANGLE, NO_COORDINATE, SLIDE
from sidprep.solver.core.curves import CONSTANT_SPEED, SMOOTH_START, TABULATED
from sidprep.solver.core.forces import (FE_FORCE, FE_FRICTION, FE_INT_COLUMNS, FE_INT_JOINT, FE_INT_KIND,
                                        FE_INT_MARKER1, FE_INT_MARKER2, FE_INT_TABLE, FE_INT_TABLE_COLUMNS,
                                        FE_JOINT_FORCE, FE_MOVING_MASS, FE_PAR_CLEARANCE, FE_PAR_COLUMNS,
                                        FE_PAR_CONSTANT, FE_PAR_DAMPING, FE_PAR_DIRECTION, FE_PAR_HAS_DIRECTION,
                                        FE_PAR_HAS_STOP, FE_PAR_LENGTH, FE_PAR_LEVER, FE_PAR_MARKER_FRAME, FE_PAR_MASS,
                                        FE_PAR_MU, FE_PAR_PRELOAD, FE_PAR_REFERENCE, FE_PAR_REGULARISATION,
                                        FE_PAR_STIFFNESS, FE_PAR_STOP_DAMPING, FE_PAR_STOP_EXPONENT,
                                        FE_PAR_STOP_STIFFNESS, FE_PAR_VALUE, FE_SPRING, FE_TORQUE)
from sidprep.solver.core.records import layout_record
from sidprep.solver.model.forces import (JointForce, JointFriction, MarkerLoad, MovingMass, PointTorque, SpringDamper,
                                         Table)
from sidprep.solver.model.bodies import PathMarker
from sidprep.solver.model.joints import ConstantSpeed, SmoothStart

Layout = namedtuple("Layout", [
    "qoff", "uoff", "gravity",
    "body_F", "body_off", "body_flags", "body_mass",
    "mk_body", "mk_pos", "mk_rot", "mk_shape", "mk_k0", "mk_active", "mk_path", "mk_motion",
    "shapes",
    "jrows", "joint_off", "joint_mk", "joint_kind",
    "drv_joint", "drv_kind", "drv_par", "drv_curve",
    "curve_x", "curve_c", "curve_meta", "curve_period",
    "fe_int", "fe_par",
])


def _flat(x) -> np.ndarray:
    return np.ascontiguousarray(x, dtype=float).ravel()


def pack_terms(terms) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(F, off (N_TERMS,), flags (N_FLAGS,)) of one BodyTerms (body.py offsets and flags)."""
    nq = terms.nq
    parts: list[np.ndarray] = []
    off = np.full(N_TERMS, -1, dtype=np.int64)
    size = 0

    def put(index, array):
        nonlocal size
        if array is None:
            return
        a = _flat(array)
        off[index] = size
        parts.append(a)
        size += a.size

    def swap(t, c):  # X1[k, j, a] -> X1f[j, c*k + a]
        return None if t is None else t.transpose(1, 0, 2).reshape(nq, nq * c)

    put(MD0, terms.md0)
    put(I0, terms.I0)
    put(ME, terms.Me)
    put(KE, terms.Ke)
    put(MD1, terms.md1)
    put(I1, None if terms.I1 is None else terms.I1.reshape(nq, 9))
    put(CT0, terms.Ct0 if terms.Ct0 is not None else np.zeros((nq, 3)))
    put(CT1, swap(terms.Ct1, 3))
    put(CR0, terms.Cr0 if terms.Cr0 is not None else np.zeros((nq, 3)))
    put(CR1, swap(terms.Cr1, 3))
    put(GR0, None if terms.Gr0 is None else terms.Gr0.reshape(nq, 9))
    put(GE, None if terms.Ge is None else terms.Ge.reshape(3, nq * nq))
    put(OE0, terms.Oe0)
    put(OE1, swap(terms.Oe1, 6))
    put(KS0, terms.ks0)
    put(KS1, terms.ks1)
    put(DE, terms.De)
    put(P2, None if terms.P is None else terms.P.reshape(9, nq * nq))
    flags = np.zeros(N_FLAGS, dtype=np.int64)
    flags[F_INERTIA] = terms.md1 is not None
    flags[F_CT1] = terms.Ct1 is not None
    flags[F_CR1] = terms.Cr1 is not None
    flags[F_CORIOLIS] = terms.Gr0 is not None
    flags[F_OE0] = terms.Oe0 is not None
    flags[F_OE1] = terms.Oe1 is not None
    flags[F_PRELOAD] = terms.ks0 is not None
    flags[F_DAMPING] = terms.De is not None
    flags[F_GRAVITY] = terms.gravity
    flags[F_SECOND] = terms.P is not None
    return (np.concatenate(parts) if parts else np.zeros(0)), off, flags


class Curves:
    """Collects scalar piecewise polynomials (x, c (degree+1, k), period) into flat arrays."""

    def __init__(self):
        self.x: list[np.ndarray] = []
        self.c: list[np.ndarray] = []
        self.meta: list[list[int]] = []
        self.period: list[float] = []

    def add(self, x, c, period: float = 0.0) -> int:
        x_off = sum(a.size for a in self.x)
        c_off = sum(a.size for a in self.c)
        self.x.append(_flat(x))
        self.c.append(_flat(c))
        self.meta.append([x_off, len(x), c_off, c.shape[0]])
        self.period.append(float(period or 0.0))
        return len(self.meta) - 1

    def add_table(self, table: Table) -> int:
        """The columns of a Table as consecutive curves; returns the first index."""
        c = table.coefficients()
        first = len(self.meta)
        for k in range(table.columns):
            self.add(table.x, c[:, :, k], table.period or 0.0)
        return first

    def arrays(self):
        cat = (lambda parts: np.concatenate(parts) if parts else np.zeros(0))
        return (cat(self.x), cat(self.c), np.array(self.meta, dtype=np.int64).reshape(-1, 4),
                np.array(self.period, dtype=float))


def motion_row(motion, curves: Curves) -> tuple[int, np.ndarray, int]:
    """(kind, params [start, speed, ramp_time], curve index or -1) of a motion profile
    (ConstantSpeed, SmoothStart, TabulatedMotion; equations/curves.py motion_state)."""
    if isinstance(motion, ConstantSpeed):
        return CONSTANT_SPEED, np.array([motion.start, motion.speed, 0.0]), -1
    if isinstance(motion, SmoothStart):
        return SMOOTH_START, np.array([motion.start, motion.speed, motion.ramp_time]), -1
    return TABULATED, np.zeros(3), curves.add(motion.x, motion.c)


def add_path(path, curves: Curves) -> int:
    """A BodyPath as consecutive cubic-spline curves over s: points (3), phi (3 nq, row a,
    column k at 3 + a nq + k), psi (3 nq, after phi); returns the first curve's index."""
    from scipy.interpolate import CubicSpline  # deferred: 0.42 CPU-s of import (paths, tables)

    n = path.s.size
    values = np.concatenate([path.points.reshape(n, 3), path.phi.reshape(n, -1), path.psi.reshape(n, -1)], axis=1)
    spline = CubicSpline(path.s, values, axis=0)
    first = len(curves.meta)
    for k in range(values.shape[1]):
        curves.add(spline.x, spline.c[:, :, k])
    return first


def build_layout(system, terms: list, load_stiffening: list[bool]) -> Layout:
    """The Layout of ``system`` with the BodyTerms ``terms`` (one per body) and, per body,
    whether its node markers use the load-stiffening parts K0F / K0M."""
    bodies = system.bodies
    index = {id(b): i for i, b in enumerate(bodies)}
    nqs = [t.nq for t in terms]
    qoff = np.concatenate([[0], np.cumsum(nqs)]).astype(np.int64)
    uoff = np.concatenate([[0], np.cumsum([6 + k for k in nqs])]).astype(np.int64)
    packed = [pack_terms(t) for t in terms]
    starts = np.concatenate([[0], np.cumsum([p[0].size for p in packed])]).astype(np.int64)
    body_F = np.concatenate([p[0] for p in packed] + [np.zeros(0)])
    body_off = np.array([np.where(p[1] >= 0, p[1] + s, -1) for p, s in zip(packed, starts)],
                        dtype=np.int64).reshape(-1, N_TERMS)
    body_flags = np.array([p[2] for p in packed], dtype=np.int64).reshape(-1, N_FLAGS)
    body_mass = np.array([t.mass for t in terms], dtype=float)

    markers = system.markers()
    mindex = {id(m): k for k, m in enumerate(markers)}
    shapes: list[np.ndarray] = []
    size = 0

    def store(a) -> int:
        nonlocal size
        shapes.append(_flat(a))
        size += shapes[-1].size
        return size - shapes[-1].size

    mk_body = np.array([index.get(id(m.body), -1) for m in markers], dtype=np.int64)
    mk_shape = np.zeros(len(markers), dtype=np.int64)
    mk_k0 = np.full((len(markers), 2), -1, dtype=np.int64)
    for k, m in enumerate(markers):
        b = mk_body[k]
        nq = nqs[b] if b >= 0 else 0
        phi = np.zeros((3, nq)) if m.phi is None else m.phi
        psi = np.zeros((3, nq)) if m.psi is None else m.psi
        mk_shape[k] = store(np.concatenate([_flat(phi), _flat(psi)]))
        if b >= 0 and load_stiffening[b]:
            if m.k0f is not None:
                mk_k0[k, 0] = store(m.k0f)
            if m.k0m is not None:
                mk_k0[k, 1] = store(m.k0m)
    used = {id(m) for c in system.joints for m in (c.marker1, c.marker2)}
    used |= {id(getattr(fe, name)) for fe in system.forces for name in ("marker", "marker1", "marker2")
             if hasattr(fe, name)}
    mk_active = np.array([id(m) in used for m in markers], dtype=np.int64)
    mk_pos = np.array([m.position for m in markers], dtype=float).reshape(-1, 3)
    mk_rot = np.array([m.rotation for m in markers], dtype=float).reshape(-1, 3, 3)
    curves = Curves()
    mk_path = np.full((len(markers), 3), -1, dtype=np.int64)     # [first path curve, motion curve, partner]
    mk_motion = np.zeros((len(markers), 4))                       # [kind, start, speed, ramp_time]
    partners = {id(j.marker1): mindex[id(j.marker2)] for j in system.joints if j.kind == "on_path"}
    for k, m in enumerate(markers):
        if isinstance(m, PathMarker):
            if m.motion is None:  # follows its OnPath partner (System.check)
                mk_path[k, 2] = partners[id(m)]
            else:
                kind, par, mk_path[k, 1] = motion_row(m.motion, curves)
                mk_motion[k, 0], mk_motion[k, 1:] = kind, par
            mk_path[k, 0] = add_path(m.path, curves)

    joints = system.joints
    jindex = {id(j): i for i, j in enumerate(joints)}
    kinds = {None: NO_COORDINATE, "angle": ANGLE, "slide": SLIDE}
    jrows = np.concatenate([j._rows for j in joints] + [np.zeros((0, 3), dtype=np.int64)]).astype(np.int64)
    joint_off = np.concatenate([[0], np.cumsum([len(j.rows) for j in joints])]).astype(np.int64)
    joint_mk = np.array([[mindex[id(j.marker1)], mindex[id(j.marker2)]] for j in joints],
                        dtype=np.int64).reshape(-1, 2)
    joint_kind = np.array([kinds[j.coordinate_kind] for j in joints], dtype=np.int64)

    drivers = system.drivers
    drv_joint = np.array([jindex[id(d.joint)] for d in drivers], dtype=np.int64)
    drv_kind = np.zeros(len(drivers), dtype=np.int64)
    drv_par = np.zeros((len(drivers), 3))
    drv_curve = np.full(len(drivers), -1, dtype=np.int64)
    for i, d in enumerate(drivers):
        drv_kind[i], drv_par[i], drv_curve[i] = motion_row(d.motion, curves)

    fe_int = np.full((len(system.forces), FE_INT_COLUMNS), -1, dtype=np.int64)
    fe_par = np.zeros((len(system.forces), FE_PAR_COLUMNS))
    for i, fe in enumerate(system.forces):
        row, par = fe_int[i], fe_par[i]
        if isinstance(fe, MarkerLoad):
            row[FE_INT_KIND] = FE_TORQUE if isinstance(fe, PointTorque) else FE_FORCE
            row[FE_INT_MARKER1] = mindex[id(fe.marker)]
            row[FE_INT_JOINT] = -1 if fe.argument is None else jindex[id(fe.argument)]
            if isinstance(fe.value, Table):
                row[FE_INT_TABLE], row[FE_INT_TABLE_COLUMNS] = curves.add_table(fe.value), fe.value.columns
            else:
                row[FE_INT_TABLE_COLUMNS] = 0
                par[FE_PAR_VALUE:FE_PAR_VALUE + fe.value.size] = fe.value.ravel()
            if fe.direction is not None:
                par[FE_PAR_DIRECTION:FE_PAR_DIRECTION + 3], par[FE_PAR_HAS_DIRECTION] = fe.direction, 1.0
            par[FE_PAR_MARKER_FRAME] = fe.frame == "marker"
        elif isinstance(fe, SpringDamper):
            row[FE_INT_KIND], row[FE_INT_MARKER1], row[FE_INT_MARKER2] = \
                FE_SPRING, mindex[id(fe.marker1)], mindex[id(fe.marker2)]
            par[FE_PAR_STIFFNESS], par[FE_PAR_DAMPING] = fe.stiffness, fe.damping
            par[FE_PAR_LENGTH] = np.nan if fe.length is None else fe.length
            if fe.law is not None:
                par[FE_PAR_HAS_STOP], par[FE_PAR_CLEARANCE], par[FE_PAR_STOP_STIFFNESS] = \
                    1.0, fe.law.clearance, fe.law.stiffness
                par[FE_PAR_STOP_EXPONENT], par[FE_PAR_STOP_DAMPING] = fe.law.exponent, fe.law.damping
        elif isinstance(fe, JointForce):
            row[FE_INT_KIND], row[FE_INT_JOINT] = FE_JOINT_FORCE, jindex[id(fe.joint)]
            if fe.table is not None:
                row[FE_INT_TABLE] = curves.add_table(fe.table)
            par[FE_PAR_STIFFNESS], par[FE_PAR_DAMPING] = fe.stiffness, fe.damping
            par[FE_PAR_REFERENCE], par[FE_PAR_CONSTANT] = fe.reference, fe.constant
        elif isinstance(fe, MovingMass):
            row[FE_INT_KIND], row[FE_INT_MARKER1], par[FE_PAR_MASS] = FE_MOVING_MASS, mindex[id(fe.marker)], fe.mass
        elif isinstance(fe, JointFriction):
            row[FE_INT_KIND], row[FE_INT_JOINT] = FE_FRICTION, jindex[id(fe.joint)]
            par[FE_PAR_MU], par[FE_PAR_PRELOAD], par[FE_PAR_REGULARISATION] = fe.mu, fe.preload, fe.regularisation
            par[FE_PAR_LEVER] = 1.0 if fe.joint.kind in ("prismatic", "on_path") else fe.radius
    cx, cc, cmeta, cper = curves.arrays()
    return Layout(qoff, uoff, np.asarray(system.gravity, float), body_F, body_off, body_flags, body_mass,
                  mk_body, mk_pos, mk_rot, mk_shape, mk_k0, mk_active, mk_path, mk_motion,
                  np.concatenate(shapes + [np.zeros(0)]),
                  jrows, joint_off, joint_mk, joint_kind, drv_joint, drv_kind, drv_par, drv_curve,
                  cx, cc, cmeta, cper, fe_int, fe_par)


def compiled_layout(system, terms: list, load_stiffening: list[bool]):
    """The compiled core's Layout record (sidprep/solver/core/records.pxd) of ``build_layout``."""
    return layout_record(build_layout(system, terms, load_stiffening))


def constraint_count(system) -> int:
    """Number of constraint rows (joints, then drivers)."""
    return sum(len(j.rows) for j in system.joints) + len(system.drivers)


def body_matrices(terms, q, qd, w, g_k):
    """(M_K (6+nq, 6+nq), h_K (6+nq,)) of one body's BodyTerms at a state (core body.body_equations)."""
    F, off, flags = pack_terms(terms)
    c = np.ascontiguousarray
    return packed_body_matrices(F, off, flags, float(terms.mass), c(q, float), c(qd, float), c(w, float), c(g_k, float))
