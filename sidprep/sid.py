"""The SID data model (Standard Input Data, Wallrapp 1994): Taylor objects, nodes, the body.

Conventions (../shared/design/sid-spec.md sections 1-3, 8):

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
