"""Modal stresses of a flexible body and the invariants of a stress tensor (numpy, and scipy for
the nearest-node search; the solver imports this module).

A body's stress at a node is linear in its modal coordinates (linear elasticity about the
undeformed state, the same assumption as the SID's mode shapes):

    sigma(t) = sum_k sigma_k q_k(t),

with ``sigma_k`` the stress of the k-th coordinate's shape at the node (Pa per unit q_k).  Tensors
are held as 6-vectors in ``STRESS_ORDER`` (the component order of Nastran's and CalculiX's nodal
stress output: xx, yy, zz, xy, yz, zx; shear entries are tensor components sigma_ij, not
engineering strains).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: order of the six stress components in every array of this module (Nastran / CalculiX .frd)
STRESS_ORDER = ("xx", "yy", "zz", "xy", "yz", "zx")
#: (row, column) of each component in the symmetric 3x3 tensor
_TENSOR_INDEX = ((0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (2, 0))


@dataclass(frozen=True)
class StressModes:
    """Stress per unit modal coordinate at nodes of a body (SID.stress; HDF5 group ``/stress``).

    node_ids : (ns,) int64 FE node numbers (or stress-point numbers of an analytical Beam);
    points : (ns, 3) undeformed positions in the body frame K, m; modes : (ns, 6, nq) stress
    components in ``STRESS_ORDER`` per unit q_k, Pa; scope : "surface" (the outer surface's
    nodes) or "all" (every node of the mesh); method : how they were computed (one line).
    """

    node_ids: np.ndarray
    points: np.ndarray
    modes: np.ndarray
    scope: str = "surface"
    method: str = ""

    @property
    def n_nodes(self) -> int:
        return int(self.points.shape[0])

    def at(self, q: np.ndarray, nodes=slice(None)) -> np.ndarray:
        """sigma = sum_k sigma_k q_k for every sample of q at once: q (nt, nq) -> (nt, n, 6) Pa,
        one matrix product ((nt, nq) x (nq, n 6)); ``nodes`` selects rows of the stress points."""
        S = self.modes[nodes]
        n = S.shape[0]
        return (np.atleast_2d(q) @ S.reshape(n * 6, -1).T).reshape(-1, n, 6)


#: rows of W: sigma_v^2 = |W sigma|^2 (the deviator in an orthonormal basis, scaled by sqrt(3/2)):
#: ((xx - yy)^2 + (yy - zz)^2 + (zz - xx)^2) / 2 = 3/4 (xx - yy)^2 + 1/4 (xx + yy - 2 zz)^2
DEVIATOR_ROWS = np.array([[math.sqrt(3) / 2, -math.sqrt(3) / 2, 0, 0, 0, 0],
                          [0.5, 0.5, -1.0, 0, 0, 0],
                          [0, 0, 0, math.sqrt(3), 0, 0],
                          [0, 0, 0, 0, math.sqrt(3), 0],
                          [0, 0, 0, 0, 0, math.sqrt(3)]])


def stress_on_points(stress: StressModes, points: np.ndarray) -> np.ndarray:
    """The modal stresses of the stress node nearest to each point (e.g. the animation surface's
    points: the same nodes for a meshed body, the section outline's for a Beam); (n, 6, nq) Pa/[q]."""
    # scipy.spatial (with scipy.special) costs 0.15 s CPU to import: only pages and animations of
    # bodies with stress modes pay it
    from scipy.spatial import cKDTree  # deferred: 0.15 s import

    _, rows = cKDTree(stress.points).query(np.asarray(points, dtype=float))
    return stress.modes[rows]


def von_mises(sigma: np.ndarray) -> np.ndarray:
    """Von Mises equivalent stress of 6-vectors in STRESS_ORDER: (..., 6) -> (...), Pa.

    sigma_v = sqrt(((s_xx - s_yy)^2 + (s_yy - s_zz)^2 + (s_zz - s_xx)^2) / 2 + 3 (s_xy^2 + s_yz^2 + s_zx^2))
    = |W sigma| with W = DEVIATOR_ROWS.
    """
    return np.linalg.norm(np.asarray(sigma) @ DEVIATOR_ROWS.T, axis=-1)


def stress_tensor(sigma: np.ndarray) -> np.ndarray:
    """Symmetric 3x3 tensors from 6-vectors in STRESS_ORDER: (..., 6) -> (..., 3, 3)."""
    s = np.asarray(sigma)
    T = np.empty(s.shape[:-1] + (3, 3))
    for c, (i, j) in enumerate(_TENSOR_INDEX):
        T[..., i, j] = T[..., j, i] = s[..., c]
    return T


def principal_stresses(sigma: np.ndarray) -> np.ndarray:
    """Principal stresses, largest first: (..., 6) -> (..., 3), Pa (eigenvalues of the tensor)."""
    return np.linalg.eigvalsh(stress_tensor(sigma))[..., ::-1]
