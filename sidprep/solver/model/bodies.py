"""Bodies of the FFR solver (descriptions): ground, rigid bodies, flexible bodies from SID, markers.

Coordinates of one body (sid-spec 5.1): position r_O (inertial), rotation matrix A (body K ->
inertial), modal coordinates q.  Velocities u = [v_O (inertial components), omega (K
components), qd].  The equations of motion of a body are written once, compiled, in
``sidprep/solver/core/body.pyx``; this module only describes a body: ``BodyTerms`` holds the SID
arrays of the switched-on effects (sid-spec 5.4, 5.5).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sidprep.errors import InputError
from sidprep.sid.checks import physical_problems
from sidprep.sid.io import read_sid
from sidprep.sid.model import ge_tensor, gr_tensor, inertia_matrix
from sidprep.solver.core.rotations import as_rotation
from sidprep.solver.model.effects import MASS_MATRIX_EFFECTS

#: relative size below which a split-off part of a SID member counts as round-off (zero)
ROUNDOFF = 1e-12
#: relative tolerance of the check "Oe.M1 holds only Kom" (trace identity, sid-spec 4.8 item 7)
KOM_ONLY_RTOL = 1e-6


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


@dataclass(frozen=True)
class BodyTerms:
    """SID arrays of one body for the switched-on effects (None = term not assembled).

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

    @property
    def nq(self) -> int:
        return self.Me.shape[0]


class Body:
    """Base class: a named body with ``ndof`` velocity coordinates and markers."""

    ndof: int = 0
    nq: int = 0

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


class MassBody(Body):
    """A body with 6 + nq coordinates; ``terms(effects, gravity)`` gives its BodyTerms."""

    @property
    def ndof(self) -> int:  # type: ignore[override]
        return 6 + self.nq


class RigidBody(MassBody):
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
        self.mass = float(mass)
        self.inertia_cm = i_cm

    def terms(self, effects: set[str], gravity: bool) -> BodyTerms:
        """The BodyTerms of a rigid body (only the gravity switch applies); inertia about O."""
        c, m = self.com, self.mass
        return BodyTerms(mass=m, md0=m * c, I0=self.inertia_cm + m * (c @ c * np.eye(3) - np.outer(c, c)),
                         Me=np.zeros((0, 0)), Ke=np.zeros((0, 0)), Ct0=np.zeros((0, 3)), Cr0=np.zeros((0, 3)),
                         gravity=gravity)


class FlexibleBody(MassBody):
    """A flexible body described by SID data (sid-spec 3, 5).

    Parameters
    ----------
    sid : sidprep.sid.model.SID or path of a SID file (.SID_FEM, .h5 ...; read with sidprep.sid.io.read_sid)
    name : body name
    position, rotation, velocity, omega : initial pose of the body frame K (see RigidBody)
    q0, qd0 : (nq,) initial modal coordinates and velocities (default 0)
    effects : None (use the system's choice), "auto", "all" or a list of effect names
    mode_pairs : optional (3, 3, nq, nq) mode-pair integrals P_ab for I2 / Gr1; derived from
        ``sid.stiffening['Kom'|'Kr']`` or from a pure-Kom Oe.M1 when not given
    source : what to call the SID in messages (default: its path, or "SID of body '<name>'")

    Raises InputError (one line naming the SID and the entry) when the SID is physically
    impossible (sidprep.sid.checks.physical_problems), before any step.
    """

    def __init__(self, sid, *, name="flex", position=None, rotation=None, velocity=None, omega=None,
                 q0=None, qd0=None, effects=None, mode_pairs=None, source=None):
        super().__init__(name, position, rotation, velocity, omega)
        if isinstance(sid, (str, Path)):
            source = source or str(sid)
            sid = read_sid(sid, physical="off")      # checked below, in memory too
        problems = physical_problems(sid)
        if problems:
            raise InputError(f"{source or f'SID of body {name!r}'}: {problems[0]}: a physically impossible body; "
                             "regenerate the SID (sidprep reduce) or correct that entry (sidprep check lists all)")
        self.sid = sid
        self.nq = sid.nq
        self.q0 = np.zeros(self.nq) if q0 is None else np.asarray(q0, float).copy()
        self.qd0 = np.zeros(self.nq) if qd0 is None else np.asarray(qd0, float).copy()
        self.effects = effects
        self.mode_pairs = mode_pairs if mode_pairs is not None else self._derive_mode_pairs()

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
    def terms(self, effects: set[str], gravity: bool) -> BodyTerms:
        """The BodyTerms with exactly the terms of ``effects`` (sid-spec 5.4)."""
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
        model = BodyTerms(
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

    def path_marker(self, path: str, motion=None, *, rotation=None, name: str | None = None) -> "PathMarker":
        """A marker moving along the SID path ``path`` (SID.paths, e.g. "axis" of a Beam) at arc
        length s(t) given by ``motion`` (ConstantSpeed, SmoothStart or TabulatedMotion, s in m),
        or, without a motion, at the projection of its OnPath joint partner onto the deformed
        path: position p(s) + Phi(s) q, orientation A T(s, q) R_m with T the smallest rotation
        from the undeformed to the deformed path tangent (``rotation`` R_m, default E; an OnPath
        joint needs the marker's z axis along the path). Off the path (s outside its range) it
        carries no load."""
        if path not in self.sid.paths:
            have = ", ".join(self.sid.paths) or "none (an analytical Beam has the path 'axis')"
            raise ValueError(f"body '{self.name}' has no path {path!r}; its SID has: {have}")
        p = self.sid.paths[path]
        m = PathMarker(self, name or f"{self.name}.{path}{len(self.markers)}", p.points[0].copy(),
                       as_rotation(rotation), path=p, motion=motion)
        self.markers.append(m)
        return m

    def initial_q(self) -> tuple[np.ndarray, np.ndarray]:
        return self.q0, self.qd0


def _gr(s) -> np.ndarray:
    return gr_tensor(s.Gr.M0, s.nq).copy()


def _ge(s) -> np.ndarray:
    ge = ge_tensor(s.Ge.M0, s.nq)
    return 0.5 * (ge - ge.transpose(0, 2, 1))  # physically antisymmetric (sid-spec 3.9)


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


@dataclass(eq=False)
class PathMarker(Marker):
    """A marker moving along a BodyPath of its flexible body (FlexibleBody.path_marker): at arc
    length s(t) of ``motion`` (m), with the path's interpolated point and mode shapes."""

    path: object = None
    motion: object = None
