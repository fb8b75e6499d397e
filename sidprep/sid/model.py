"""The SID data model (Standard Input Data, Wallrapp 1994): Taylor objects, nodes, the body.

Conventions (docs/sid-spec.md sections 1-3, 8):

* everything resolved in the body frame K, SI units unless ``SID.units`` says otherwise;
* a Taylor object is M(q) = M0 + sum_k M1[:, k, :] q_k, with M1 stored (nrow, nq, ncol)
  exactly as the ASCII ``m1(row, q, col)`` entries (the modal index is the MIDDLE one);
* J is the 6-vector [Ixx, Iyy, Izz, Ixy, Ixz, Iyz] (products are negative integrals);
* Oe columns follow omega_hat = [wx^2, wy^2, wz^2, wx wy, wy wz, wx wz];
* Gr (3 x 3nq) and Ge (nq x 3nq) are held in the a-block layout: column a*nq + k (0-based)
  is omega component a, mode k.  Readers convert other layouts on input;
  ``gr_tensor`` / ``ge_tensor`` give the canonical 3-index tensors.

This module depends on numpy only; the solver imports it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from sidprep.sid.stress import StressModes

#: ASCII structure codes of M0 (sid-spec.md section 2)
ZERO, DIAGONAL, SYMMETRIC, GENERAL, IDENTITY = 0, 1, 2, 3, 4

J_ORDER = ("xx", "yy", "zz", "xy", "xz", "yz")
OMEGA_HAT_ORDER = ("xx", "yy", "zz", "xy", "yz", "xz")


@dataclass(frozen=True)
class Taylor:
    """A matrix-valued function of the modal coordinates, to first order.

    Attributes
    ----------
    M0 : (nrow, ncol) float64
    M1 : (nrow, nq, ncol) float64 or None
        None means order 0.
    structure : int
        Storage pattern of M0 for the ASCII file (ZERO, DIAGONAL, SYMMETRIC, GENERAL, IDENTITY).
    """

    M0: np.ndarray
    M1: np.ndarray | None = None
    structure: int = GENERAL

    @property
    def order(self) -> int:
        return 0 if self.M1 is None else 1

    @property
    def nrow(self) -> int:
        return self.M0.shape[0]

    @property
    def ncol(self) -> int:
        return self.M0.shape[1]

    def __call__(self, q: np.ndarray | None = None) -> np.ndarray:
        """Evaluate M(q) = M0 + sum_k M1[:, k, :] q_k; (nrow, ncol)."""
        if self.M1 is None or q is None:
            return self.M0
        return self.M0 + np.einsum("ikj,k->ij", self.M1, q)


@dataclass(frozen=True)
class SIDNode:
    """One node frame of a SID (sid-spec.md section 3.2).

    origin 3x1 (M1 = phi.M0), phi 3 x nq, psi 3 x nq, AP 3x3 (M1[:, k, :] = skew(psi_k) AP0),
    sigma 6x1 or None.
    """

    node_id: int
    origin: Taylor
    phi: Taylor
    psi: Taylor
    AP: Taylor
    sigma: Taylor | None = None
    name: str = ""


@dataclass(frozen=True)
class BodyPath:
    """A curve on or in a flexible body along which loads and bodies can move (moving loads, Hartweg and Heckmann 2012): the undeformed points and the mode shapes sampled along its arc length.

    s : (n,) arc length, m, increasing; points : (n, 3) undeformed positions in K, m;
    phi : (n, 3, nq) displacement per unit q_k; psi : (n, 3, nq) small rotation per unit q_k.
    Sampled densely enough for cubic interpolation in s (the solver's).
    """

    s: np.ndarray
    points: np.ndarray
    phi: np.ndarray
    psi: np.ndarray


@dataclass(frozen=True)
class SurfaceModes:
    """Mode shapes on the outer surface, for animation.

    points : (ns, 3) undeformed surface node positions in K; triangles : (nf, 3) int64 rows of
    ``points`` (outward normals); shapes : (ns, 3, nq) displacement of each surface node per
    unit modal coordinate; node_ids : (ns,) FE node numbers.
    """

    points: np.ndarray
    triangles: np.ndarray
    shapes: np.ndarray
    node_ids: np.ndarray


@dataclass(frozen=True)
class SID:
    """A reduced flexible body.

    Attributes
    ----------
    mass : float
        Total mass, kg.
    labels : tuple of str, length nq
        ``ielastq`` labels, e.g. ``"Eigen Mode    7 :       51.626 Hz"``.
    nodes : tuple of SIDNode
    mdCM (3x1), J (6x1), Ct (nq x 3), Cr (nq x 3), Me (nq x nq), Gr (3 x 3nq, a-block),
    Ge (nq x 3nq, a-block), Oe (nq x 6), ksigma (nq x 1), Ke (nq x nq), De (nq x nq) : Taylor
    frequencies_hz : (nq,) float64
        Frequency of each coordinate (NaN where the coordinate is not an eigen-type mode).
    mode_kinds : tuple of str
        "eigen", "frm", "static", "constraint", ... per coordinate.
    units : str
        "SI" (kg, m, s, N, rad) or another system named by the file that was read.
    stiffening : mapping name -> ndarray
        Raw geometric-stiffness parts kept apart so that the solver can switch each:
        "K0t" (3,nq,nq), "K0r" (3,nq,nq), "K0omega" (6,nq,nq), "Kom" (6,nq,nq), "Kr" (3,nq,nq),
        "K0F/<node index>" (3,nq,nq), "K0M/<node index>" (3,nq,nq).  Empty when unknown
        (e.g. read from an ASCII file, which stores only the sums).
    metadata : mapping
        Provenance, options, checks, library versions (JSON-serialisable values).
    surface : SurfaceModes or None
        Mode shapes on the outer surface (HDF5 files only), for animation.
    paths : mapping name -> BodyPath
        Curves along which loads move (HDF5 files only), e.g. "axis" of an analytical Beam.
    stress : StressModes or None
        Stress per unit modal coordinate at nodes (HDF5 files only; ``sidprep reduce --stress``).
    """

    mass: float
    labels: tuple[str, ...]
    nodes: tuple[SIDNode, ...]
    mdCM: Taylor
    J: Taylor
    Ct: Taylor
    Cr: Taylor
    Me: Taylor
    Gr: Taylor
    Ge: Taylor
    Oe: Taylor
    ksigma: Taylor
    Ke: Taylor
    De: Taylor
    frequencies_hz: np.ndarray = field(default_factory=lambda: np.zeros(0))
    mode_kinds: tuple[str, ...] = ()
    units: str = "SI"
    stiffening: Mapping[str, np.ndarray] = field(default_factory=dict)
    metadata: Mapping[str, object] = field(default_factory=dict)
    surface: SurfaceModes | None = None
    paths: Mapping[str, BodyPath] = field(default_factory=dict)
    stress: StressModes | None = None

    @property
    def nq(self) -> int:
        return len(self.labels)


def skew(a: np.ndarray) -> np.ndarray:
    """The tilde operator: skew(a) @ b == cross(a, b); (3,) -> (3, 3)."""
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def inertia_matrix(j6: np.ndarray) -> np.ndarray:
    """3x3 inertia tensor from the SID 6-vector [Ixx, Iyy, Izz, Ixy, Ixz, Iyz]."""
    xx, yy, zz, xy, xz, yz = np.ravel(j6)
    return np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])


def gr_tensor(gr: np.ndarray, nq: int) -> np.ndarray:
    """Canonical (nq, 3, 3) tensor G[k, i, a] from an a-block Gr matrix (3, 3nq)."""
    return gr.reshape(3, 3, nq).transpose(2, 0, 1)


def ge_tensor(ge: np.ndarray, nq: int) -> np.ndarray:
    """Canonical (3, nq, nq) tensor Ge[a, k, j] from an a-block Ge matrix (nq, 3nq)."""
    return ge.reshape(nq, 3, nq).transpose(1, 0, 2)


# ------------------------------------------------------------------------------------------------
# Invariants from FE data (sid-spec.md section 4)
# ------------------------------------------------------------------------------------------------

#: relative tolerance below which Me counts as the identity and Ke/De as diagonal (structure codes
#: 4 / 1; the ASCII writer then drops the rest, close to the file's 12-digit precision, and readers
#: that hard-code Me = E stay right)
STRUCTURE_TOL = 1e-10
#: relative off-diagonal size of Me and Ke below which coordinates count as eigen-type (frequencies)
DIAGONAL_BASIS_TOL = 1e-8


def j6(i3: np.ndarray) -> np.ndarray:
    """SID 6-vector [Ixx, Iyy, Izz, Ixy, Ixz, Iyz] of a (..., 3, 3) tensor; (..., 6)."""
    i3 = np.asarray(i3)
    return np.stack([i3[..., 0, 0], i3[..., 1, 1], i3[..., 2, 2],
                     i3[..., 0, 1], i3[..., 0, 2], i3[..., 1, 2]], axis=-1)


def omega_hat_combination(T: np.ndarray) -> np.ndarray:
    """Omega-hat coefficients [-(Tyy+Tzz), -(Txx+Tzz), -(Txx+Tyy), Txy+Tyx, Tyz+Tzy, Txz+Tzx]; (..., 6).

    For T = S_k this is Oe0[k, :]; for T = P (mode pairs) it is Kom (sid-spec.md 3.10).
    """
    d = np.diagonal(T, axis1=-2, axis2=-1)
    return np.stack([-(d[..., 1] + d[..., 2]), -(d[..., 0] + d[..., 2]), -(d[..., 0] + d[..., 1]),
                     T[..., 0, 1] + T[..., 1, 0], T[..., 1, 2] + T[..., 2, 1],
                     T[..., 0, 2] + T[..., 2, 0]], axis=-1)


def axial(T: np.ndarray) -> np.ndarray:
    """Axial vector of the antisymmetric part times 2: (T23-T32, T31-T13, T12-T21); (..., 3)."""
    return np.stack([T[..., 1, 2] - T[..., 2, 1], T[..., 2, 0] - T[..., 0, 2],
                     T[..., 0, 1] - T[..., 1, 0]], axis=-1)


def mode_pair_integrals(Ms, Phi3: np.ndarray) -> np.ndarray:
    """P[a, b] = Phi_a^T Ms Phi_b, the mode-pair mass integrals (sid-spec.md 4.4); (3, 3, nq, nq).

    Phi3 : (n, 3, nq) node-wise mode shapes; Ms : (n, n) scalar mass matrix (sparse or dense).
    """
    n, _, nq = Phi3.shape
    flat = Phi3.reshape(n, 3 * nq)
    MsPhi = np.asarray(Ms @ flat).reshape(n, 3 * nq)
    return (flat.T @ MsPhi).reshape(3, nq, 3, nq).transpose(0, 2, 1, 3)


def first_moments(Ms, points: np.ndarray, Phi3: np.ndarray) -> np.ndarray:
    """S_k[a, b] = x_a^T Ms Phi_b[:, k] = integral of c_a phi_{k,b} dm (sid-spec.md 3, 4.3); (nq, 3, 3)."""
    MsX = np.asarray(Ms @ points).reshape(points.shape)
    return np.einsum("na,nbk->kab", MsX, Phi3)


def inertia_first_order(S: np.ndarray) -> np.ndarray:
    """I1_k = 2 tr(S_k) E - S_k - S_k^T (sid-spec.md 3.4); (nq, 3, 3)."""
    tr = np.trace(S, axis1=1, axis2=2)
    return 2 * tr[:, None, None] * np.eye(3) - S - S.transpose(0, 2, 1)


def gyroscopic_tensor(S: np.ndarray) -> np.ndarray:
    """Canonical Gr0 tensor G[k, i, a] = 2 (tr(S_k) E - S_k^T)[i, a] (sid-spec.md 3.8); (nq, 3, 3)."""
    tr = np.trace(S, axis1=1, axis2=2)
    return 2 * (tr[:, None, None] * np.eye(3) - S.transpose(0, 2, 1))


def rotational_coupling(P: np.ndarray) -> np.ndarray:
    """Kr[a, k, j] = integral of (phi_j x phi_k)_a dm (sid-spec.md 3.6); (3, nq, nq), antisymmetric."""
    return np.stack([P[2, 1] - P[1, 2], P[0, 2] - P[2, 0], P[1, 0] - P[0, 1]])


def centrifugal_softening(P: np.ndarray) -> np.ndarray:
    """Kom[i, k, j], omega-hat component i of the centrifugal mode coupling (sid-spec.md 3.10); (6, nq, nq)."""
    return np.moveaxis(omega_hat_combination(np.moveaxis(P, (0, 1), (2, 3))), -1, 0)


def gr_matrix(G: np.ndarray) -> np.ndarray:
    """a-block Gr matrix (3, 3nq) from the canonical tensor G[k, i, a] (inverse of ``gr_tensor``)."""
    return G.transpose(1, 2, 0).reshape(3, 3 * G.shape[0])


def ge_matrix(Ge: np.ndarray) -> np.ndarray:
    """a-block Ge matrix (nq, 3nq) from the canonical tensor Ge[a, k, j] (inverse of ``ge_tensor``)."""
    return Ge.transpose(1, 0, 2).reshape(Ge.shape[1], 3 * Ge.shape[1])


def structure_code(M0: np.ndarray, kind: str = "general") -> int:
    """ASCII structure code of M0 by the writer rules of sid-spec.md 7.4.

    kind : "general" (0 or 3), "mass" (Me: 4 if the identity, else 2), "stiffness" (Ke, De: 1 if
    diagonal, else 2).  Identity/diagonal are judged to STRUCTURE_TOL relative to max |M0|.
    """
    scale = np.max(np.abs(M0)) if M0.size else 0.0
    if scale == 0.0:
        return ZERO
    if kind == "general":
        return GENERAL
    off = M0 - np.diag(np.diag(M0))
    if kind == "mass" and np.max(np.abs(M0 - np.eye(len(M0)))) <= STRUCTURE_TOL:
        return IDENTITY
    if kind == "stiffness" and np.max(np.abs(off)) <= STRUCTURE_TOL * scale:
        return DIAGONAL
    return SYMMETRIC


def taylor(M0: np.ndarray, M1: np.ndarray | None = None, kind: str = "general") -> Taylor:
    """A Taylor object with the structure code of ``structure_code``."""
    M0 = np.asarray(M0, dtype=float)
    return Taylor(M0, None if M1 is None else np.asarray(M1, dtype=float), structure_code(M0, kind))


def eigen_label(mode_number: int, frequency_hz: float) -> str:
    """SIMPACK-style ielastq label ``Eigen Mode %4d : %12.3f Hz`` (sid-spec.md 3.1, 7.4 rule 10)."""
    return f"Eigen Mode {mode_number:4d} : {frequency_hz:12.3f} Hz"


#: what the ielastq label of a non-eigen coordinate adds behind "Hz": readers take the frequency
#: between ":" and "Hz" and some require the prefix "Eigen Mode" (sid-spec.md 3.1, 10 item 7), so
#: the kind goes last; a .SID_FEM file keeps it only there
KIND_LABEL_SUFFIX = {"frm": " (frequency response mode)"}


def mode_label(mode_number: int, frequency_hz: float, kind: str = "eigen") -> str:
    """The ielastq label of one coordinate: ``eigen_label`` plus the kind's suffix."""
    return eigen_label(mode_number, frequency_hz) + KIND_LABEL_SUFFIX.get(kind, "")


def kind_of_label(label: str) -> str:
    """"eigen", "frm", ... from an ielastq label written by ``mode_label``; "other" for free text."""
    text = label.strip().lower()
    for kind, suffix in KIND_LABEL_SUFFIX.items():
        if text.endswith(suffix.strip().lower()):
            return kind
    return "eigen" if text.startswith("eigen mode") else "other"


def frequencies_from_stiffness(Me: np.ndarray, Ke: np.ndarray) -> np.ndarray:
    """sqrt(Ke_kk / Me_kk) / 2 pi for an M- and K-diagonal basis, NaN elsewhere; (nq,) Hz."""
    nq = len(Ke)
    f = np.full(nq, np.nan)
    if nq == 0:
        return f
    scale = max(np.max(np.abs(Ke)), np.max(np.abs(Me)))
    diag_ok = (np.max(np.abs(Ke - np.diag(np.diag(Ke))), initial=0.0) <= DIAGONAL_BASIS_TOL * scale
               and np.max(np.abs(Me - np.diag(np.diag(Me))), initial=0.0) <= DIAGONAL_BASIS_TOL * scale)
    if diag_ok:
        lam = np.diag(Ke) / np.diag(Me)
        f = np.where(lam >= 0, np.sqrt(np.abs(lam)) / (2 * np.pi), np.nan)
    return f


def node_frame(node_id: int, position, phi_n, psi_n, *, K0F=None, K0M=None, name: str = "") -> SIDNode:
    """One SID node frame (sid-spec.md 3.2, 4.6).

    position (3,) m; phi_n, psi_n (3, nq) translational / small-rotation mode shapes at the node;
    K0F, K0M (3, nq, nq) geometric stiffness of unit node forces / moments, K0F[a, k, j] placed at
    phi.M1[a, j, k].  origin.M1 = phi.M0, AP0 = E, AP.M1[:, k, :] = skew(psi_k).
    """
    phi_n = np.asarray(phi_n, dtype=float)
    psi_n = np.asarray(psi_n, dtype=float)
    nq = phi_n.shape[1]
    origin = taylor(np.asarray(position, dtype=float).reshape(3, 1), phi_n[:, :, None])
    phi = taylor(phi_n, None if K0F is None else np.asarray(K0F).transpose(0, 2, 1))
    psi = taylor(psi_n, None if K0M is None else np.asarray(K0M).transpose(0, 2, 1))
    ap1 = np.stack([skew(psi_n[:, k]) for k in range(nq)], 1) if nq else np.zeros((3, 0, 3))
    AP = Taylor(np.eye(3), ap1, GENERAL)
    return SIDNode(int(node_id), origin, phi, psi, AP, None, name)


def sid_invariants(points, Ms, Phi, nodes, *, labels=None, frequencies_hz=None, mode_kinds=None,
                   Ke=None, De=None, stiffening=None, metadata=None, units="SI") -> SID:
    """The exact SID of a solid FE body from its scalar mass matrix (sid-spec.md 4.2-4.7).

    Parameters
    ----------
    points : (n, 3) float
        Undeformed FE node positions in the body frame K, m.
    Ms : (n, n) sparse or dense
        Scalar mass matrix, kg (the full mass matrix is Ms (x) E3, sid-spec.md 4.2).
    Phi : (3n, nq) float
        Reduction basis, node-interleaved (dof 3 i + c), no rigid-body modes.
    nodes : sequence of (node_id, position (3,), phi_n (3, nq)[, psi_n (3, nq)[, name]])
        The SID node frames (interface masters, output nodes) in file order.
    labels, frequencies_hz, mode_kinds : per coordinate, optional
        Defaults: frequencies sqrt(Ke_kk/Me_kk)/2pi where the basis is M- and K-diagonal,
        labels ``Eigen Mode k : f Hz`` (``Mode k`` where the frequency is unknown), kinds "eigen".
    Ke : (nq, nq), N/m per unit q
        Phi^T K Phi; Ms carries no stiffness.  Default diag((2 pi f)^2) Me from frequencies_hz.
    De : (nq, nq), default zero
    stiffening : dict, optional
        Raw geometric-stiffness parts (sid-spec.md 6.3): "K0t" (3,nq,nq) -> Ct.M1, "K0r" (3,nq,nq)
        -> Cr.M1 (added to Kr), "K0omega" (6,nq,nq) -> Oe.M1 (added to Kom), "K0F/<i>", "K0M/<i>"
        (3,nq,nq) -> phi.M1 / psi.M1 of node i (0-based index in ``nodes``).
    metadata : dict, optional
    units : str

    Returns
    -------
    SID with every member of sid-spec.md 3.3-3.14; ``stiffening`` holds the raw parts plus the
    kinematic "Kom" (6,nq,nq) and "Kr" (3,nq,nq).
    """
    X = np.asarray(points, dtype=float)
    n = len(X)
    Phi = np.asarray(Phi, dtype=float)
    nq = Phi.shape[1]
    Phi3 = Phi.reshape(n, 3, nq)
    stiff = {k: np.asarray(v, dtype=float) for k, v in (stiffening or {}).items()}

    Ms1 = np.asarray(Ms @ np.ones(n)).ravel()
    mass = float(Ms1.sum())
    md0 = X.T @ Ms1                                          # integral of c dm
    C = X.T @ np.asarray(Ms @ X).reshape(n, 3)               # C_ab = x_a^T Ms x_b
    I0 = np.trace(C) * np.eye(3) - C
    Ct0 = np.einsum("nak,n->ka", Phi3, Ms1)                  # integral of phi_k dm
    S = first_moments(Ms, X, Phi3)
    P = mode_pair_integrals(Ms, Phi3)
    Kr = rotational_coupling(P)
    Kom = centrifugal_softening(P)
    Me = P[0, 0] + P[1, 1] + P[2, 2]

    if Ke is None:
        if frequencies_hz is None or not np.all(np.isfinite(frequencies_hz)):
            raise ValueError("sid_invariants: give Ke (Phi^T K Phi) or finite frequencies_hz")
        Ke = np.diag((2 * np.pi * np.asarray(frequencies_hz, dtype=float)) ** 2) @ Me
    Ke = np.asarray(Ke, dtype=float)
    De = np.zeros((nq, nq)) if De is None else np.asarray(De, dtype=float)
    if frequencies_hz is None:
        frequencies_hz = frequencies_from_stiffness(Me, Ke)
    frequencies_hz = np.asarray(frequencies_hz, dtype=float)
    if mode_kinds is None:
        mode_kinds = tuple("eigen" if np.isfinite(f) else "other" for f in frequencies_hz)
    if labels is None:
        labels = tuple(eigen_label(k + 1, f) if np.isfinite(f) else f"Mode {k + 1}"
                       for k, f in enumerate(frequencies_hz))

    def with_stiffening(base, key):          # (r, nq, nq) parts -> M1 (nq, nq, r)
        return (base + stiff[key] if key in stiff else base).transpose(1, 2, 0)

    frames = []
    for i, entry in enumerate(nodes):
        node_id, position, phi_n = entry[:3]
        psi_n = entry[3] if len(entry) > 3 else np.zeros((3, nq))
        frames.append(node_frame(node_id, position, phi_n, psi_n, K0F=stiff.get(f"K0F/{i}"),
                                 K0M=stiff.get(f"K0M/{i}"),
                                 name=str(entry[4]) if len(entry) > 4 else ""))

    return SID(
        mass=mass,
        labels=tuple(labels),
        nodes=tuple(frames),
        mdCM=taylor(md0[:, None], Ct0.T[:, :, None]),
        J=taylor(j6(I0)[:, None], j6(inertia_first_order(S)).T[:, :, None]),
        Ct=taylor(Ct0, stiff["K0t"].transpose(1, 2, 0) if "K0t" in stiff else None),
        Cr=taylor(axial(S), with_stiffening(Kr, "K0r")),
        Me=taylor(Me, kind="mass"),
        Gr=taylor(gr_matrix(gyroscopic_tensor(S))),
        Ge=taylor(ge_matrix(2 * Kr)),
        Oe=taylor(omega_hat_combination(S), with_stiffening(Kom, "K0omega")),
        ksigma=taylor(np.zeros((nq, 1))),
        Ke=taylor(Ke, kind="stiffness"),
        De=taylor(De, kind="stiffness"),
        frequencies_hz=frequencies_hz,
        mode_kinds=tuple(mode_kinds),
        units=units,
        stiffening={**stiff, "Kom": Kom, "Kr": Kr},
        metadata=dict(metadata or {}),
    )
