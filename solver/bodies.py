"""Bodies of the FFR solver: ground, rigid bodies, flexible bodies from SID, and markers.

Coordinates of one body (sid-spec 5.1): position r_O (inertial), rotation matrix A (body K ->
inertial), modal coordinates q.  Velocities u = [v_O (inertial components), omega (K
components), qd]; the accelerations are their time derivatives.  The equations of one body are
sid-spec 5.2 written in K, with the translational row rotated to inertial components
(T = blockdiag(A^T, E, E)):

    T^T [ M_K(q) T du  -  h_K(q, u) ]  =  T^T h_ext,K

``BodyModel`` holds the SID arrays of the switched-on effects (sid-spec 5.5: contractions stored
as (nq, nq, 3|6) arrays) and evaluates M_K and h_K = -(k_omega + k_e) + gravity.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from sidprep.sid import ge_tensor, gr_tensor, inertia_matrix
from sidprep.solver.effects import EFFECTS, MASS_MATRIX_EFFECTS
from sidprep.solver.kinematics import COMPILED, as_rotation, cross, exp_so3, jit, matmul, skew

_E3 = np.eye(3)

#: relative size below which a split-off part of a SID member counts as round-off (zero)
ROUNDOFF = 1e-12
#: relative tolerance of the check "Oe.M1 holds only Kom" (trace identity, sid-spec 4.8 item 7)
KOM_ONLY_RTOL = 1e-6


def _omega_hat(w: np.ndarray) -> np.ndarray:
    """[wx^2, wy^2, wz^2, wx wy, wy wz, wx wz] (sid-spec 1)."""
    return np.array([w[0] * w[0], w[1] * w[1], w[2] * w[2], w[0] * w[1], w[1] * w[2], w[0] * w[2]])


def _i1_tensor(j_m1: np.ndarray) -> np.ndarray:
    """J.M1 (6, nq, 1) -> I1 (nq, 3, 3)."""
    return np.stack([inertia_matrix(j_m1[:, k, 0]) for k in range(j_m1.shape[1])])


def mode_pairs_from_kom_kr(kom: np.ndarray, kr: np.ndarray) -> np.ndarray:
    """Mode-pair integrals P[a, b] = int Phi_a^T Phi_b dm, (3, 3, nq, nq), from Kom and Kr.

    kom : (6, nq, nq) in omega-hat order; kr : (3, nq, nq).  Inverts sid-spec 3.6 / 3.10.
    """
    xx, yy, zz, xy, yz, xz = kom
    p = np.empty((3, 3) + kom.shape[1:])
    p[0, 0] = 0.5 * (xx - yy - zz)
    p[1, 1] = 0.5 * (yy - xx - zz)
    p[2, 2] = 0.5 * (zz - xx - yy)
    p[0, 1], p[1, 0] = 0.5 * (xy - kr[2]), 0.5 * (xy + kr[2])
    p[1, 2], p[2, 1] = 0.5 * (yz - kr[0]), 0.5 * (yz + kr[0])
    p[0, 2], p[2, 0] = 0.5 * (xz + kr[1]), 0.5 * (xz - kr[1])
    return p


@jit
def _body_equations(q, qd, w, gk, mass, md0, I0, Me, Ke, md1, I1f, Ct0, Ct1f, Cr0, Cr1f, Gr0f, Gef, Oe0,
                    Oe1f, ks0, ks1, De, flags):  # pragma: no cover - compiled
    """M_K (6+nq, 6+nq) and h_K (6+nq,) of sid-spec 5.2, loops compiled by numba.

    flags: [inertia_change, Ct.M1, Cr.M1, coriolis, Oe0, Oe.M1, preload, damping, gravity].
    Same mathematics as BodyModel.mass_matrix / internal_forces (the reference implementation).
    """
    nq = q.shape[0]
    n = 6 + nq
    md = md0.copy()
    inertia = I0.copy()
    ct = Ct0.copy()
    cr = Cr0.copy()
    for j in range(nq):
        qj = q[j]
        if flags[0]:
            for a in range(3):
                md[a] += qj * md1[j, a]
                for b in range(3):
                    inertia[a, b] += qj * I1f[j, 3 * a + b]
        if flags[1]:
            for k in range(nq):
                for a in range(3):
                    ct[k, a] += qj * Ct1f[j, 3 * k + a]
        if flags[2]:
            for k in range(nq):
                for a in range(3):
                    cr[k, a] += qj * Cr1f[j, 3 * k + a]
    m = np.zeros((n, n))
    for a in range(3):
        m[a, a] = mass
        for b in range(3):
            m[3 + a, 3 + b] = inertia[a, b]
    m[3, 1], m[3, 2], m[4, 0], m[4, 2], m[5, 0], m[5, 1] = -md[2], md[1], md[2], -md[0], -md[1], md[0]
    for a in range(3):
        for b in range(3):
            m[a, 3 + b] = m[3 + b, a]
    for k in range(nq):
        for a in range(3):
            m[6 + k, a] = ct[k, a]
            m[a, 6 + k] = ct[k, a]
            m[6 + k, 3 + a] = cr[k, a]
            m[3 + a, 6 + k] = cr[k, a]
        for j in range(nq):
            m[6 + k, 6 + j] = Me[k, j]
    h = np.zeros(n)
    wmd = np.cross(w, md)
    h[0:3] = -np.cross(w, wmd)
    iw = inertia @ w
    h[3:6] = -np.cross(w, iw)
    wh = np.array([w[0] * w[0], w[1] * w[1], w[2] * w[2], w[0] * w[1], w[1] * w[2], w[0] * w[2]])
    if flags[3]:
        ctq = np.zeros(3)
        g = np.zeros((3, 3))
        for k in range(nq):
            for a in range(3):
                ctq[a] += ct[k, a] * qd[k]
                for b in range(3):
                    g[a, b] += qd[k] * Gr0f[k, 3 * a + b]
        h[0:3] -= 2.0 * np.cross(w, ctq)
        h[3:6] -= g @ w
    for k in range(nq):
        he = 0.0
        for j in range(nq):
            he -= Ke[k, j] * q[j]
            if flags[3]:
                for a in range(3):
                    he -= w[a] * Gef[a, k * nq + j] * qd[j]
            if flags[5]:
                for i in range(6):
                    he -= q[j] * Oe1f[j, 6 * k + i] * wh[i]
            if flags[6]:
                he -= ks1[k, j] * q[j]
            if flags[7]:
                he -= De[k, j] * qd[j]
        if flags[4]:
            for i in range(6):
                he -= Oe0[k, i] * wh[i]
        if flags[6]:
            he -= ks0[k]
        h[6 + k] = he
    if flags[8]:
        for i in range(n):
            for a in range(3):
                h[i] += m[i, a] * gk[a]
    return m, h


@dataclass(frozen=True)
class BodyModel:
    """Arrays of one body for the switched-on effects (None = term not assembled).

    Shapes: md0 (3,), md1 (nq, 3), I0 (3, 3), I1 (nq, 3, 3), P (3, 3, nq, nq) for I2/Gr1,
    Ct0 (nq, 3), Ct1 (nq, nq, 3) [k, j, a], Cr0 (nq, 3), Cr1 (nq, nq, 3), Me (nq, nq),
    Gr0 (nq, 3, 3) [k, i, a], Ge (3, nq, nq) [a, k, j], Oe0 (nq, 6), Oe1 (nq, nq, 6),
    ks0 (nq,), ks1 (nq, nq), Ke (nq, nq), De (nq, nq).  SI units.
    """

    mass: float
    md0: np.ndarray
    I0: np.ndarray
    Me: np.ndarray
    Ke: np.ndarray
    md1: np.ndarray | None = None
    I1: np.ndarray | None = None
    P: np.ndarray | None = None
    Ct0: np.ndarray | None = None
    Ct1: np.ndarray | None = None
    Cr0: np.ndarray | None = None
    Cr1: np.ndarray | None = None
    Gr0: np.ndarray | None = None
    Ge: np.ndarray | None = None
    Oe0: np.ndarray | None = None
    Oe1: np.ndarray | None = None
    ks0: np.ndarray | None = None
    ks1: np.ndarray | None = None
    De: np.ndarray | None = None
    gravity: bool = True
    constant_mass: bool = True

    def __post_init__(self):
        """Flattened copies for BLAS mat-vecs (sid-spec 5.5): X1f[j, k*c + a] = X1[k, j, a]."""
        nq = self.nq

        def flat(t, c):
            return None if t is None else np.ascontiguousarray(t.transpose(1, 0, 2).reshape(nq, nq * c))

        extra = {
            "I1f": None if self.I1 is None else self.I1.reshape(nq, 9),
            "Ct1f": flat(self.Ct1, 3),
            "Cr1f": flat(self.Cr1, 3),
            "Oe1f": flat(self.Oe1, 6),
            "Gr0f": None if self.Gr0 is None else self.Gr0.reshape(nq, 9),
            "Gef": None if self.Ge is None else self.Ge.reshape(3, nq * nq),
        }
        for k, v in extra.items():
            object.__setattr__(self, k, v)
        none2 = np.zeros((0, 0))
        flags = np.array([self.md1 is not None, self.Ct1 is not None, self.Cr1 is not None, self.Gr0 is not None,
                          self.Oe0 is not None, self.Oe1 is not None, self.ks0 is not None,
                          self.De is not None, self.gravity], dtype=np.int64)

        def arr(x, empty=none2):
            return empty if x is None else np.ascontiguousarray(x, dtype=float)

        packed = (float(self.mass), arr(self.md0), arr(self.I0), arr(self.Me), arr(self.Ke), arr(self.md1),
                  arr(extra["I1f"]), arr(self.Ct0), arr(extra["Ct1f"]), arr(self.Cr0), arr(extra["Cr1f"]),
                  arr(extra["Gr0f"]), arr(extra["Gef"]), arr(self.Oe0), arr(extra["Oe1f"]),
                  arr(self.ks0, np.zeros(0)), arr(self.ks1), arr(self.De), flags)
        object.__setattr__(self, "_packed", packed)

    def equations(self, q, qd, w, g_k):
        """(M_K, h_K) at the state: the compiled kernel, or the numpy reference methods when the
        second-order terms (P) are on or numba is not available."""
        if self.P is not None or not COMPILED:
            terms = self.inertia_terms(q)
            mk = self.mass_matrix(q, terms)
            return mk, self.internal_forces(q, qd, w, g_k, mk, terms)
        c = np.ascontiguousarray
        return _body_equations(c(q), c(qd), c(w), c(g_k), *self._packed)

    @property
    def nq(self) -> int:
        return self.Me.shape[0]

    def restricted(self, modes: np.ndarray) -> "BodyModel":
        """The model of the modal subset ``modes`` (indices), the other modal coordinates held
        at zero (planar scenes)."""
        ix = np.ix_(modes, modes)

        def sub(x, *axes):
            if x is None:
                return None
            for axis in axes:
                x = np.take(x, modes, axis=axis)
            return x

        return replace(self, Me=self.Me[ix], Ke=self.Ke[ix], md1=sub(self.md1, 0), I1=sub(self.I1, 0),
                       P=sub(self.P, 2, 3), Ct0=sub(self.Ct0, 0), Ct1=sub(self.Ct1, 0, 1), Cr0=sub(self.Cr0, 0),
                       Cr1=sub(self.Cr1, 0, 1), Gr0=sub(self.Gr0, 0), Ge=sub(self.Ge, 1, 2), Oe0=sub(self.Oe0, 0),
                       Oe1=sub(self.Oe1, 0, 1), ks0=sub(self.ks0, 0), ks1=sub(self.ks1, 0, 1),
                       De=sub(self.De, 0, 1))

    def inertia_terms(self, q: np.ndarray):
        """md (3,), I (3, 3), Ct (nq, 3), Cr (nq, 3) at q (sid-spec 5.2)."""
        md, inertia, ct, cr = self.md0, self.I0, self.Ct0, self.Cr0
        nq = self.nq
        if self.md1 is not None:
            md = md + q @ self.md1
            inertia = inertia + (q @ self.I1f).reshape(3, 3)
        if self.P is not None:
            pq = np.einsum("abjk,j,k->ab", self.P, q, q)
            inertia = inertia + np.trace(pq) * _E3 - pq
        if self.Ct1f is not None:
            ct = ct + (q @ self.Ct1f).reshape(nq, 3)
        if self.Cr1f is not None:
            cr = cr + (q @ self.Cr1f).reshape(nq, 3)
        return md, inertia, ct, cr

    def mass_matrix(self, q: np.ndarray, terms=None) -> np.ndarray:
        """M_K(q), (6 + nq, 6 + nq), for accelerations [a_O (K), omega_dot, q_ddot]."""
        md, inertia, ct, cr = terms or self.inertia_terms(q)
        nq = self.nq
        m = np.empty((6 + nq, 6 + nq))
        m[:3, :3] = self.mass * _E3
        m[3:6, :3] = skew(md)
        m[:3, 3:6] = m[3:6, :3].T
        m[3:6, 3:6] = inertia
        m[6:, :3], m[6:, 3:6] = ct, cr
        m[:3, 6:], m[3:6, 6:] = ct.T, cr.T
        m[6:, 6:] = self.Me
        return m

    def internal_forces(self, q, qd, w, g_k, mass_matrix, terms=None) -> np.ndarray:
        """h_K = -k_omega - k_e + M_K[:, :3] g_K in K components, (6 + nq,) (sid-spec 5.2)."""
        md, inertia, ct, _ = terms or self.inertia_terms(q)
        nq = self.nq
        h = np.empty(6 + nq)
        h[:3] = -cross(w, cross(w, md))
        h[3:6] = -cross(w, inertia @ w)
        he = -(self.Ke @ q)
        if self.Gr0f is not None:
            h[:3] -= 2.0 * cross(w, ct.T @ qd)
            h[3:6] -= (qd @ self.Gr0f).reshape(3, 3) @ w
            he -= (w @ self.Gef).reshape(nq, nq) @ qd
        if self.P is not None:  # Gr1 part of Gr(q, qd), sid-spec 3.8
            r = np.einsum("iakj,k,j->ia", self.P, qd, q)
            h[3:6] -= 2.0 * (np.trace(r) * w - r @ w)
        if self.Oe0 is not None or self.Oe1f is not None:
            wh = _omega_hat(w)
            if self.Oe0 is not None:
                he -= self.Oe0 @ wh
            if self.Oe1f is not None:
                he -= (q @ self.Oe1f).reshape(nq, 6) @ wh
        if self.ks0 is not None:
            he -= self.ks0 + self.ks1 @ q
        if self.De is not None:
            he -= self.De @ qd
        h[6:] = he
        if self.gravity:
            h += mass_matrix[:, :3] @ g_k
        return h


class Body:
    """Base class: a named body with ``ndof`` velocity coordinates and markers."""

    ndof: int = 0
    nq: int = 0
    load_stiffening: bool = False

    def __init__(self, name: str, position=None, rotation=None, velocity=None, omega=None):
        self.name = name
        self.position0 = np.zeros(3) if position is None else np.asarray(position, float).copy()
        self.rotation0 = as_rotation(rotation)
        self.velocity0 = np.zeros(3) if velocity is None else np.asarray(velocity, float).copy()
        self.omega0 = np.zeros(3) if omega is None else np.asarray(omega, float).copy()
        self.markers: list[Marker] = []

    def marker(self, position=(0.0, 0.0, 0.0), rotation=None, name: str | None = None) -> Marker:
        """A marker fixed in the body frame K at ``position`` (m, K components) with the
        orientation ``rotation`` (3x3 marker -> K, or a rotation vector)."""
        m = Marker(self, name or f"{self.name}.m{len(self.markers)}",
                   np.asarray(position, float), as_rotation(rotation))
        self.markers.append(m)
        return m

    def initial_q(self) -> tuple[np.ndarray, np.ndarray]:
        return np.zeros(0), np.zeros(0)


class Ground(Body):
    """The inertial frame (no coordinates)."""

    def __init__(self, name: str = "ground"):
        super().__init__(name)


class _MassBody(Body):
    """A body with 6 + nq coordinates described by a BodyModel."""

    model: BodyModel

    @property
    def ndof(self) -> int:  # type: ignore[override]
        return 6 + self.nq


class RigidBody(_MassBody):
    """A rigid body.

    Parameters
    ----------
    mass : float, kg
    com : (3,) centre of mass in the body frame K, m
    inertia : (3, 3) or 6-vector [Ixx, Iyy, Izz, Ixy, Ixz, Iyz] about the CENTRE OF MASS, in K
        axes, kg m^2 (products as negative integrals, SID convention)
    obj : optional path of an OBJ surface for animation (passed through to results)
    position, rotation, velocity, omega : initial pose of K: r_O (m), A (3x3 or rotation
        vector), v_O (m/s, inertial), omega (rad/s, K components)
    """

    def __init__(self, mass, com=(0.0, 0.0, 0.0), inertia=np.zeros(3), *, name="rigid", obj=None,
                 position=None, rotation=None, velocity=None, omega=None):
        super().__init__(name, position, rotation, velocity, omega)
        c = np.asarray(com, float)
        i = np.asarray(inertia, float)
        i_cm = np.diag(i) if i.shape == (3,) else (inertia_matrix(i) if i.shape == (6,) else i)
        if mass <= 0 or i_cm.shape != (3, 3):
            raise ValueError(f"rigid body '{name}': need mass > 0 and a 3x3 / 6-vector inertia")
        self.obj = obj
        self.com = c
        self.model = BodyModel(
            mass=float(mass), md0=mass * c, I0=i_cm + mass * (c @ c * np.eye(3) - np.outer(c, c)),
            Me=np.zeros((0, 0)), Ke=np.zeros((0, 0)), Ct0=np.zeros((0, 3)), Cr0=np.zeros((0, 3)),
        )

    def configure(self, effects: set[str], gravity: bool) -> None:
        """Rigid bodies have only the gravity switch."""
        self.model = replace(self.model, gravity=gravity)


class FlexibleBody(_MassBody):
    """A flexible body described by SID data (sid-spec 3, 5).

    Parameters
    ----------
    sid : sidprep.sid.SID or path of a SID file (.SID_FEM, .h5 ...; read with sidprep.io.read_sid)
    name : body name
    position, rotation, velocity, omega : initial pose of the body frame K (see RigidBody)
    q0, qd0 : (nq,) initial modal coordinates and velocities (default 0)
    effects : None (use the system's choice), "auto", "all" or a list of effect names
    mode_pairs : optional (3, 3, nq, nq) mode-pair integrals P_ab for I2 / Gr1; derived from
        ``sid.stiffening['Kom'|'Kr']`` or from a pure-Kom Oe.M1 when not given
    """

    def __init__(self, sid, *, name="flex", position=None, rotation=None, velocity=None, omega=None,
                 q0=None, qd0=None, effects=None, mode_pairs=None):
        super().__init__(name, position, rotation, velocity, omega)
        if isinstance(sid, (str, Path)):
            from sidprep.io import read_sid

            sid = read_sid(sid)
        self.sid = sid
        self.nq = sid.nq
        self.q0 = np.zeros(self.nq) if q0 is None else np.asarray(q0, float).copy()
        self.qd0 = np.zeros(self.nq) if qd0 is None else np.asarray(qd0, float).copy()
        self.effects = effects
        self.mode_pairs = mode_pairs if mode_pairs is not None else self._derive_mode_pairs()
        self.model = self.build_model(set(EFFECTS), gravity=True)

    # ----------------------------------------------------------------- SID queries
    def _m1(self, taylor) -> np.ndarray | None:
        m1 = taylor.M1
        return None if m1 is None or not np.any(m1) else m1

    def oe1_is_kom_only(self) -> bool:
        """True if Oe.M1 holds only the centrifugal softening Kom (no K0omega stiffening)."""
        st = self.sid.stiffening
        if "Kom" in st or "K0omega" in st:
            return "K0omega" not in st or not np.any(st["K0omega"])
        oe1 = self._m1(self.sid.Oe)
        if oe1 is None:
            return False
        trace = oe1[:, :, 0] + oe1[:, :, 1] + oe1[:, :, 2]
        me = self.sid.Me.M0
        return np.linalg.norm(trace + 2 * me) <= KOM_ONLY_RTOL * np.linalg.norm(me)

    def _kr(self) -> np.ndarray | None:
        """Kr (3, nq, nq): from the stiffening parts, else the antisymmetric part of Cr.M1."""
        if "Kr" in self.sid.stiffening:
            return np.asarray(self.sid.stiffening["Kr"])
        cr1 = self._m1(self.sid.Cr)
        if cr1 is None:
            return None
        kr = cr1.transpose(2, 0, 1)
        return 0.5 * (kr - kr.transpose(0, 2, 1))

    def _k0r(self) -> np.ndarray | None:
        """K0r (3, nq, nq): symmetric part of Cr.M1 (sid-spec 3.6)."""
        if "K0r" in self.sid.stiffening:
            return np.asarray(self.sid.stiffening["K0r"])
        cr1 = self._m1(self.sid.Cr)
        if cr1 is None:
            return None
        kr = cr1.transpose(2, 0, 1)
        sym = 0.5 * (kr + kr.transpose(0, 2, 1))
        return sym if np.max(np.abs(sym)) > ROUNDOFF * np.max(np.abs(kr)) else None

    def _derive_mode_pairs(self) -> np.ndarray | None:
        st = self.sid.stiffening
        kr = self._kr()
        if "Kom" in st and kr is not None:
            return mode_pairs_from_kom_kr(np.asarray(st["Kom"]), kr)
        oe1 = self._m1(self.sid.Oe)
        if oe1 is not None and kr is not None and self.oe1_is_kom_only():
            return mode_pairs_from_kom_kr(oe1.transpose(2, 0, 1), kr)
        return None

    def available(self) -> dict[str, bool]:
        """Which effects this SID can provide."""
        s = self.sid
        node_stiff = any(self._m1(n.phi) is not None or self._m1(n.psi) is not None for n in s.nodes)
        return {
            "gravity": True,
            "coupling": bool(np.any(s.Ct.M0) or np.any(s.Cr.M0)),
            "coriolis": bool(np.any(s.Gr.M0) or np.any(s.Ge.M0)),
            "centrifugal": bool(np.any(s.Oe.M0)),
            "inertia_change": self._m1(s.mdCM) is not None or self._m1(s.J) is not None
            or self._kr() is not None,
            "second_order_inertia": self.mode_pairs is not None,
            "centrifugal_stiffening": self._m1(s.Oe) is not None,
            "acceleration_stiffening": self._m1(s.Ct) is not None or self._k0r() is not None,
            "load_stiffening": node_stiff,
            "preload": bool(np.any(s.ksigma.M0)) or self._m1(s.ksigma) is not None,
            "damping": bool(np.any(s.De.M0)),
        }

    # ----------------------------------------------------------------- model assembly
    def build_model(self, effects: set[str], gravity: bool) -> BodyModel:
        """The BodyModel with exactly the terms of ``effects`` (sid-spec 5.4)."""
        s, nq = self.sid, self.nq
        z3 = np.zeros((nq, 3))
        on = effects.__contains__
        md1 = self._m1(s.mdCM)
        j1 = self._m1(s.J)
        kr, k0r = self._kr(), self._k0r()
        cr1 = None
        if on("inertia_change") and kr is not None:
            cr1 = kr.transpose(1, 2, 0)
        if on("acceleration_stiffening") and k0r is not None:
            cr1 = (cr1 if cr1 is not None else 0.0) + k0r.transpose(1, 2, 0)
        ct1 = self._m1(s.Ct) if on("acceleration_stiffening") else None
        oe1 = self._m1(s.Oe) if on("centrifugal_stiffening") else None
        ks1 = self._m1(s.ksigma)
        inertia_change = on("inertia_change") and (md1 is not None or j1 is not None)
        p = self.mode_pairs if on("second_order_inertia") else None
        model = BodyModel(
            mass=float(s.mass),
            md0=s.mdCM.M0[:, 0].copy(),
            I0=inertia_matrix(s.J.M0[:, 0]) if s.J.M0.shape[0] == 6 else s.J.M0.copy(),
            Me=s.Me.M0.copy(),
            Ke=s.Ke.M0.copy(),
            md1=(md1[:, :, 0].T.copy() if md1 is not None else np.zeros((nq, 3))) if inertia_change else None,
            I1=(_i1_tensor(j1) if j1 is not None else np.zeros((nq, 3, 3))) if inertia_change else None,
            P=p,
            Ct0=s.Ct.M0.copy() if on("coupling") else z3,
            Ct1=ct1.copy() if ct1 is not None else None,
            Cr0=s.Cr.M0.copy() if on("coupling") else z3,
            Cr1=cr1,
            Gr0=_gr(s) if on("coriolis") else None,
            Ge=_ge(s) if on("coriolis") else None,
            Oe0=s.Oe.M0.copy() if on("centrifugal") else None,
            Oe1=oe1.copy() if oe1 is not None else None,
            ks0=s.ksigma.M0[:, 0].copy() if on("preload") else None,
            ks1=(ks1[:, :, 0] if ks1 is not None else np.zeros((nq, nq))) if on("preload") else None,
            De=s.De.M0.copy() if on("damping") and np.any(s.De.M0) else None,
            gravity=gravity,
            constant_mass=not (effects & MASS_MATRIX_EFFECTS and (inertia_change or p is not None
                                                                   or cr1 is not None or ct1 is not None)),
        )
        return model

    def configure(self, effects: set[str], gravity: bool) -> None:
        """Switch the body to the given effects (called by System before integration)."""
        self.active_effects = set(effects)
        self.load_stiffening = "load_stiffening" in effects
        self.model = self.build_model(self.active_effects, gravity)

    def node_index(self, node_id: int) -> int:
        """0-based index of the SID node with FE node number ``node_id``."""
        for i, n in enumerate(self.sid.nodes):
            if n.node_id == node_id:
                return i
        raise KeyError(f"body '{self.name}': no SID node with id {node_id}")

    def node_marker(self, index: int | None = None, *, node_id: int | None = None, rotation=None,
                    name: str | None = None) -> Marker:
        """A marker on SID node ``index`` (0-based) or ``node_id`` (FE node number).

        Position d_n = c_n + Phi_n q, orientation A R(Psi_n q) AP0 R_m (sid-spec 3.2, 5.2), with
        ``rotation`` R_m (3x3 or rotation vector, default E) orienting the marker in the node
        frame, e.g. to put a joint axis (marker z) along the node's y axis.
        """
        if (index is None) == (node_id is None):
            raise ValueError("give exactly one of index / node_id")
        i = self.node_index(node_id) if node_id is not None else int(index)
        node = self.sid.nodes[i]
        m = Marker(self, name or f"{self.name}.n{node.node_id}", node.origin.M0[:, 0].copy(),
                   node.AP.M0 @ as_rotation(rotation), node=i, phi=node.phi.M0.copy(), psi=node.psi.M0.copy(),
                   k0f=self._m1(node.phi), k0m=self._m1(node.psi))
        self.markers.append(m)
        return m

    def initial_q(self) -> tuple[np.ndarray, np.ndarray]:
        return self.q0, self.qd0


def _gr(s) -> np.ndarray:
    return gr_tensor(s.Gr.M0, s.nq).copy()


def _ge(s) -> np.ndarray:
    ge = ge_tensor(s.Ge.M0, s.nq)
    return 0.5 * (ge - ge.transpose(0, 2, 1))  # physically antisymmetric (sid-spec 3.9)


@jit
def _marker_kinematics(r, A, q, position, rotation, phi, psi):  # pragma: no cover - compiled
    """p, A R(Psi q) AP0, JT = [E, -A d~, A Phi], JR = [0, A, A Psi], d = c + Phi q (sid-spec 5.2)."""
    nq = q.shape[0]
    d = position.copy()
    rv = np.zeros(3)
    for a in range(3):
        for k in range(nq):
            d[a] += phi[a, k] * q[k]
            rv[a] += psi[a, k] * q[k]
    rot = matmul(matmul(A, exp_so3(rv)), rotation)
    jt = np.zeros((3, 6 + nq))
    jr = np.zeros((3, 6 + nq))
    ad = -matmul(A, skew(d))
    for a in range(3):
        jt[a, a] = 1.0
        for b in range(3):
            jt[a, 3 + b] = ad[a, b]
            jr[a, 3 + b] = A[a, b]
        for k in range(nq):
            for b in range(3):
                jt[a, 6 + k] += A[a, b] * phi[b, k]
                jr[a, 6 + k] += A[a, b] * psi[b, k]
    p = r.copy()
    for a in range(3):
        for b in range(3):
            p[a] += A[a, b] * d[b]
    return p, rot, jt, jr, d


@dataclass(eq=False)
class Marker:
    """A frame on a body: fixed in K, or on a SID node (moves with Phi_n q, rotates by Psi_n q).

    position (3,) c_n or the fixed position in K; rotation (3, 3) AP0 (marker -> K);
    node: SID node index or None; phi, psi (3, nq) node mode shapes; k0f, k0m (3, nq, nq) the
    phi.M1 / psi.M1 load-stiffening parts or None.
    """

    body: Body
    name: str
    position: np.ndarray
    rotation: np.ndarray
    node: int | None = None
    phi: np.ndarray | None = None
    psi: np.ndarray | None = None
    k0f: np.ndarray | None = None
    k0m: np.ndarray | None = None
    _fixed: tuple | None = None
    _shapes: tuple | None = None

    def kinematics(self, r, A, q):
        """Marker pose and velocity Jacobians for body pose (r, A, q).

        Returns p (3,) inertial position, Am (3, 3) marker -> inertial, JT (3, ndof), JR (3, ndof)
        with v_marker = JT u_body and omega_marker = JR u_body (inertial components),
        and d (3,) the marker position in K (sid-spec 5.2 node kinematics).
        """
        if self.body.ndof == 0:
            if self._fixed is None:
                empty = np.zeros((3, 0))
                self._fixed = (r + A @ self.position, A @ self.rotation, empty, empty, self.position)
            return self._fixed
        if self._shapes is None:
            nq = self.body.nq
            self._shapes = (np.zeros((3, nq)), np.zeros((3, nq))) if self.phi is None else (
                np.ascontiguousarray(self.phi), np.ascontiguousarray(self.psi))
        return _marker_kinematics(r, A, q, self.position, self.rotation, *self._shapes)

    def force_jacobians(self, A, q, jt, jr):
        """Jacobians transposed onto the body for a force / torque at the marker (sid-spec 5.2).

        With load stiffening the modal columns use phi(q) = phi0 + K0F q, psi(q) likewise.
        """
        if not self.body.load_stiffening or (self.k0f is None and self.k0m is None):
            return jt, jr
        jt, jr = jt.copy(), jr.copy()
        if self.k0f is not None:
            jt[:, 6:] += A @ np.einsum("ajk,j->ak", self.k0f, q)
        if self.k0m is not None:
            jr[:, 6:] += A @ np.einsum("ajk,j->ak", self.k0m, q)
        return jt, jr


