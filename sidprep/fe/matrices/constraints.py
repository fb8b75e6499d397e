"""Constraint equations: the map u = S u of a model whose FE code eliminated dependent DOFs.

An FE code that honours linear multipoint constraints writes K and M on the independent DOFs
only, K_ind = T^T K T and M_ind = T^T M T with u = T u_ind (CalculiX src/cascade.c, Nastran's
m-set elimination).  Each equation sum_k a_k u_k = 0 makes its first DOF d dependent,
u_d = -sum_(k != d) (a_k / a_d) u_k =: A_d u.  A dependent DOF may appear on the right of other
equations (chains); with D the dependent and I the independent DOFs,

    u_D = A_DD u_D + A_DI u_I   =>   u_D = (I - A_DD)^-1 A_DI u_I,

refused when I - A_DD is singular (equations that determine no dependent DOF).  ``S`` is the
identity on the independent DOFs and carries these rows on the dependent ones, so that a field on
the independent DOFs is completed by u = S u.  The reduction composes S with its interface
model (sidprep.reduction.interfaces.tied_interface_model): with K_ind embedded (zero rows on D),
T_model^T S^T K_emb S T_model = T_model^T K_emb T_model is the FE code's energy, and the mode
shapes, the OBJ surface and the stresses get the dependent DOFs from the equations.

A rigid body (CalculiX *RIGID BODY) is the equations u_d = u_ref + theta x (x_d - x_ref) per node
d, theta being the DOFs of the rotation node.  Its nodes' mass is folded by the FE code onto the
reference node (mass, first moment) and the rotation node (rotary inertia): :func:`solid_mass`
unfolds it again onto the nodes, the scalar mass matrix Ms of the SID invariants (sid-spec 4.2).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from sidprep.errors import InputError

#: |S^T (Ms (x) E3) S - M_ind| / max |M_ind| above this: the imported mass is not that of a solid
#: (rotary inertia or offsets on translations); the FE code's 13 digits give ~1e-15
SOLID_MASS_RTOL = 1e-9
#: a dependent DOF's own coefficient below this times the equation's largest: a singular equation
DEPENDENT_COEF_RTOL = 1e-12
#: a pivot of I - A_DD below this times the largest: chained equations that determine no DOF
PIVOT_RTOL = 1e-12


@dataclass(frozen=True)
class Constraints:
    """Multipoint constraints u = S u on the 3n DOFs (3 i + c) of a model's nodes.

    dependent : (nd,) int64 sorted dependent DOFs; S : (3n, 3n) csr (module docstring);
    slaves : nodes with a dependent DOF; masters : the other nodes the equations use.  (The
    protocol of sidprep.fe.ties.Ties that the interface model composes.)
    """

    dependent: np.ndarray
    S: sp.csr_matrix

    @property
    def slaves(self) -> np.ndarray:
        return np.unique(self.dependent // 3)

    @property
    def masters(self) -> np.ndarray:
        used = np.unique(self.S[self.dependent].indices // 3)
        return np.setdiff1d(used, self.slaves)

    def dependent_dofs(self) -> np.ndarray:
        return self.dependent

    def dof_map(self, n_nodes: int) -> sp.csr_matrix:
        return self.S


def constraint_map(equations, n_dof: int, path, describe) -> Constraints:
    """Constraints of ``equations``, a list of (DOF indices (k,), coefficients (k,)) whose first DOF
    is the dependent one (module docstring); ``describe(dof)`` names a DOF in messages."""
    dep = np.array([int(e[0][0]) for e in equations], np.int64)
    values, counts = np.unique(dep, return_counts=True)
    if (counts > 1).any():
        raise InputError(f"{path}: {describe(values[counts > 1][0])} is the dependent DOF of "
                         f"{int(counts[counts > 1][0])} equations; each DOF may be dependent once: fix the deck")
    order = np.argsort(dep)
    row_of = np.full(n_dof, -1)
    row_of[dep[order]] = np.arange(len(dep))
    rows, cols, vals = [], [], []
    for r, k in enumerate(order):
        dofs, coefs = np.asarray(equations[k][0], np.int64), np.asarray(equations[k][1], float)
        own = dofs == dep[k]
        a = coefs[own].sum()
        if not abs(a) > DEPENDENT_COEF_RTOL * np.abs(coefs).max(initial=0.0):
            raise InputError(f"{path}: the equation of {describe(dep[k])} has a zero coefficient on its dependent "
                             "(first) term: a singular constraint; give the dependent DOF a nonzero coefficient")
        rows.append(np.full(int((~own).sum()), r)), cols.append(dofs[~own]), vals.append(-coefs[~own] / a)
    dep = dep[order]
    A = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(len(dep), n_dof))
    A.sum_duplicates()
    on_dep = np.isin(A.indices, dep)
    A_DI = sp.csr_matrix((np.where(on_dep, 0.0, A.data), A.indices.copy(), A.indptr.copy()), shape=A.shape)
    A_DI.eliminate_zeros()
    if on_dep.any():
        A_DD = A[:, dep].tocsc()
        X = resolved_chains(A_DD, A_DI, path, describe(dep[0]))
    else:
        X = A_DI
    independent = np.setdiff1d(np.arange(n_dof), dep)
    X = X.tocoo()
    S = sp.csr_matrix((np.r_[np.ones(len(independent)), X.data], (np.r_[independent, dep[X.row]],
                                                                   np.r_[independent, X.col])), shape=(n_dof, n_dof))
    return Constraints(dep, S)


def resolved_chains(A_DD: sp.csc_matrix, A_DI: sp.csr_matrix, path, first: str) -> sp.csr_matrix:
    """(I - A_DD)^-1 A_DI (module docstring), on the columns A_DI uses; InputError when singular."""
    used = np.unique(A_DI.indices)
    try:
        lu = spla.splu((sp.identity(A_DD.shape[0], format="csc") - A_DD).tocsc())
        pivots = np.abs(lu.U.diagonal())
        X = lu.solve(np.asarray(A_DI[:, used].todense())) if pivots.min() > PIVOT_RTOL * pivots.max() else None
    except RuntimeError:                                  # splu: "Factor is exactly singular"
        X = None
    if X is None or not np.isfinite(X).all():
        raise InputError(f"{path}: the constraint equations are singular (dependent DOFs that determine each "
                         f"other, from {first}); make every dependent DOF depend on independent ones")
    C = sp.coo_matrix(X)
    return sp.csr_matrix((C.data, (C.row, used[C.col])), shape=A_DI.shape)


def rigid_equations(points: np.ndarray, nodes: np.ndarray, ref: int, rot: int, components=(0, 1, 2)):
    """Equations u_d,c - u_ref,c - (theta x (x_d - x_ref))_c = 0 of a rigid body, per node row d of
    ``nodes`` and component c; ``ref``, ``rot``: node rows of the reference and rotation nodes
    (theta = DOFs 3 rot + j).  List of (DOFs (5,), coefficients (5,))."""
    out = []
    for d in nodes:
        rho = points[d] - points[ref]
        for c in components:
            # (theta x rho)_c = sum_j theta_j (e_j x rho)_c
            lever = np.cross(np.eye(3), rho)[:, c]
            out.append((np.r_[3 * d + c, 3 * ref + c, 3 * rot + np.arange(3)], np.r_[1.0, -1.0, -lever]))
    return out


def skew_vector(B: np.ndarray) -> np.ndarray:
    """v with B = skew(v) (B v' = v x v') from the skew part of 3 x 3 blocks B (3, ..., 3): (3, ...)."""
    return 0.5 * np.stack([B[2, ..., 1] - B[1, ..., 2], B[0, ..., 2] - B[2, ..., 0], B[1, ..., 0] - B[0, ..., 1]])


def solid_mass(M: sp.csr_matrix, constraints: Constraints | None, points: np.ndarray, bodies, path) -> sp.csr_matrix:
    """Ms (n, n) kg with S^T (Ms (x) E3) S = M (the embedded M_ind, 3n x 3n), checked to
    SOLID_MASS_RTOL; ``bodies``: (ref row, rot row, dependent node rows) per rigid body.

    Where the FE code folded a rigid body's nodes d onto (ref, rot) (module docstring), with
    rho_d = x_d - x_ref: the rotation rows hold skew(sum_d Ms_dj rho_d) towards every other node j,
    -skew(sum_d m_d rho_d) towards ref and sum_d m_d (|rho_d|^2 E - rho_d rho_d^T) on the diagonal.
    The least-norm Ms_dj and m_d that give them are put back on the nodes d and taken off ref: any
    such Ms gives the same SID invariants (they integrate fields that are rigid on the body).
    """
    M = M.tocsr()
    rots = np.array([rot for _, rot, _ in bodies], np.int64)
    rows, cols, vals = [], [], []

    def add(r, c, v):                                      # Ms_rc += v and Ms_cr += v (r != c)
        rows.extend([r, c]), cols.extend([c, r]), vals.extend([v, v])

    for ref, rot, nodes in bodies:
        rho = points[nodes] - points[ref]
        q = 3 * rot + np.arange(3)
        Mq = M[q]
        coupled = np.setdiff1d(np.unique(Mq.indices // 3), [ref, rot])
        if np.isin(coupled, rots).any():
            raise InputError(f"{path}: the mass couples two rotation nodes (the nodes of two rigid bodies share "
                             "elements, or a consistent beam or shell mass couples the rotations of neighbouring "
                             "nodes); merge the rigid bodies into one, or export the lumped mass of beams and shells "
                             "(Nastran PARAM,COUPMASS,-1, the default)")
        blocks = Mq[:, (3 * coupled[:, None] + np.arange(3)).ravel()].toarray().reshape(3, len(coupled), 3)
        W = np.linalg.lstsq(rho.T, skew_vector(blocks), rcond=None)[0]     # (k, nj): sum_d W_dj rho_d = v_j
        v = -skew_vector(Mq[:, 3 * ref:3 * ref + 3].toarray())
        J = Mq[:, q].toarray()
        inertia = np.einsum("d,ab->dab", (rho ** 2).sum(1), np.eye(3)) - np.einsum("da,db->dab", rho, rho)
        upper = np.triu_indices(3)
        G = np.vstack([rho.T, inertia[:, upper[0], upper[1]].T])
        m = np.linalg.lstsq(G, np.r_[v, J[upper]], rcond=None)[0]
        add(np.repeat(nodes, len(coupled)), np.tile(coupled, len(nodes)), W.ravel())
        add(np.full(len(coupled), ref), coupled, -W.sum(axis=0))
        rows.extend([nodes, [ref]]), cols.extend([nodes, [ref]]), vals.extend([m, [-m.sum()]])
    n = M.shape[0] // 3
    Ms = M[0::3, 0::3].tocsr()
    if bodies:
        Ms = Ms + sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n))
        keep = sp.diags(np.where(np.isin(np.arange(n), rots), 0.0, 1.0))
        Ms = (keep @ Ms @ keep).tocsr()
    Ms.eliminate_zeros()
    S = sp.identity(M.shape[0], format="csr") if constraints is None else constraints.S
    back = (S.T @ sp.kron(Ms, sp.identity(3), format="csr") @ S).tocsr()
    worst = float(abs(back - M).max()) / float(abs(M).max())
    if worst > SOLID_MASS_RTOL:
        raise InputError(f"{path}: the mass matrix is not that of solid nodes (relative difference {worst:.1e} from "
                         "a mass that is the same in x, y and z): rotary inertia, offsets or a consistent beam mass "
                         "couple the directions; sidprep reduces consistent or lumped solid mass, point masses with "
                         "inertia, rigid bodies and the lumped mass of beams and shells (Nastran PARAM,COUPMASS,-1)")
    return Ms
