"""Geometric stiffening: unit load cases, their stress states and the projected K_G (sid-spec 6).

For each unit load p (sid-spec 6.3) the static field u_p = K^-1 (-p) (the unified sign rule,
6.2) is solved with ONE statically determinate support set for all cases (6.4): the 6 DOF of the
frame's interface master for an attached frame, 3-2-1 supports (the 6 boundary DOFs that hold
the rigid-body motions best, by pivoted QR) for a free body.  The solve is the exact static
condensation through the Craig-Bampton factor of K_ii (ReducedModel.static_solve).  The stress
sigma = D eps(u_p) at the Gauss points gives the geometric stiffness, block
(grad N_a . sigma grad N_b) E3 (6.5), projected K0_p = Phi^T K_G(u_p) Phi.

Cases and SID slots: "K0t" (3: p = M St e_a), "K0r" (3: p = M Sr e_a, the field e_a x x),
"K0omega" (6: p = M w_i, omega_hat order xx yy zz xy yz xz), and per interface master n
"K0F/<n>" (3 unit forces) and "K0M/<n>" (3 unit moments), n = the master's SID node index.
"""

from __future__ import annotations

import numpy as np

from sidprep.fe.assemble import CHUNK, MASS_QUAD_DEGREE, shape_gradients, quadrature_rule
from sidprep.reduction.interfaces import best_columns, rigid_rows

#: quadrature of K_G: degree 4 integrates grad N sigma grad N of affine tet10 (cubic) exactly
KG_QUAD_DEGREE = MASS_QUAD_DEGREE


def gauss_stress(G: np.ndarray, Ue: np.ndarray, lam: float, mu: float) -> np.ndarray:
    """Cauchy stress sigma = lam tr(eps) E + 2 mu eps at the Gauss points; (ne, nq, 3, 3) Pa.

    G : (ne, nq, nn, 3) shape-function gradients (1/m); Ue : (ne, nn, 3) nodal displacements (m).
    """
    grad = np.einsum("eqak,eai->eqik", G, Ue, optimize=True)      # du_i / dx_k
    eps = 0.5 * (grad + grad.transpose(0, 1, 3, 2))
    tr = np.trace(eps, axis1=2, axis2=3)
    return 2 * mu * eps + lam * tr[..., None, None] * np.eye(3)


def projected_geometric_stiffness(mesh, material, U: np.ndarray, Phi: np.ndarray) -> np.ndarray:
    """K0[c] = Phi^T K_G(U[:, c]) Phi for every displacement field; (nc, nq, nq), N/m per unit q.

    K_G(u) has the node blocks (int grad N_a . sigma(u) grad N_b dV) E3 (sid-spec 6.5); it is
    projected element by element (vectorised over chunks of elements), never assembled.
    U : (3n, nc) node-interleaved displacements, m; Phi : (3n, nq).
    """
    U = np.asarray(U, dtype=float).reshape(mesh.n_dof, -1)
    n, nc = mesh.n_nodes, U.shape[1]
    U3, P3 = U.reshape(n, 3, nc), np.asarray(Phi, dtype=float).reshape(n, 3, -1)
    lam, mu = material.lame
    _, dN, w = quadrature_rule(mesh.order, KG_QUAD_DEGREE)
    K0 = np.zeros((nc, P3.shape[2], P3.shape[2]))
    for start in range(0, len(mesh.cells), CHUNK):
        cells = mesh.cells[start:start + CHUNK]
        G, wdet = shape_gradients(mesh.points[cells], dN, w, start)
        Pe = P3[cells]                                               # (ne, nn, 3, nq)
        for c in range(nc):
            sigma = gauss_stress(G, U3[cells, :, c], lam, mu)
            S = np.einsum("eq,eqak,eqkl,eqbl->eab", wdet, G, sigma, G, optimize=True)
            K0[c] += np.einsum("eab,eaim,ebij->mj", S, Pe, Pe, optimize=True)
    return 0.5 * (K0 + K0.transpose(0, 2, 1))


def centrifugal_fields(points: np.ndarray) -> np.ndarray:
    """(3n, 6) nodal vectors w_i = coefficient of omega_hat_i in omega~ omega~ x (sid-spec 6.3)."""
    x, y, z = points.T
    o = np.zeros_like(x)
    fields = [(o, -y, -z), (-x, o, -z), (-x, -y, o), (y, x, o), (o, z, y), (z, o, x)]
    return np.stack([np.stack(f, axis=1).ravel() for f in fields], axis=1)


def unit_loads(points, M_fe, im) -> dict[str, np.ndarray]:
    """Model-DOF load vectors of every unit case, {slot: (n_model, ncases)} (sid-spec 6.3)."""
    R = rigid_rows(points).reshape(-1, 6)
    loads = {"K0t": im.T.T @ (M_fe @ R[:, :3]),
             "K0r": im.T.T @ (M_fe @ R[:, 3:]),
             "K0omega": im.T.T @ (M_fe @ centrifugal_fields(points))}
    for n, m in enumerate(im.master_dofs):
        unit = np.zeros((im.n_model, 6))
        unit[m, np.arange(6)] = 1.0
        loads[f"K0F/{n}"], loads[f"K0M/{n}"] = unit[:, :3], unit[:, 3:]
    return loads


def support_dofs(rigid: np.ndarray, candidates: np.ndarray, held=None) -> np.ndarray:
    """The statically determinate support of the static solves (sid-spec 6.4): ``held`` (the
    frame master's 6 DOF) for an attached frame, else the 6 of the ``candidates`` DOFs that best
    hold the rigid-body motions ``rigid`` (n, 6) (3-2-1 supports, by pivoted QR)."""
    if held is not None:
        return np.asarray(held, dtype=np.int64)
    return candidates[best_columns(rigid[candidates].T, 6)]


def stiffening_parts(mesh, material, M_fe, im, static_solve, Phi_fe: np.ndarray) -> dict[str, np.ndarray]:
    """The ``stiffening`` dict for sidprep.sid.model.sid_invariants: {slot: (ncases, nq, nq)}.

    Parameters
    ----------
    mesh, material : the FE model; M_fe : (3n, 3n) FE mass; im : InterfaceModel;
    static_solve : callable P (n_model, nc) -> u with K u = P on the supports of sid-spec 6.4
    (sidprep.jobs.reduce.Reduction.static_solve); Phi_fe : (3n, nq) the final basis in FE DOFs.
    """
    loads = unit_loads(mesh.points, M_fe, im)
    names = list(loads)
    P = np.hstack([loads[k] for k in names])
    U_fe = im.T @ static_solve(-P)                                   # sign rule, sid-spec 6.2
    K0 = projected_geometric_stiffness(mesh, material, U_fe, Phi_fe)
    out, start = {}, 0
    for k in names:
        nc = loads[k].shape[1]
        out[k] = np.stack(K0[start:start + nc])
        start += nc
    return out
