"""Steps 5 and 6 of component mode synthesis (sidprep.reduction.component_modes): exact solves with the
whole model's K_ii by substructuring, and with them the ReducedModel of a model reduced in parts.

``SubstructuredSolver`` solves K_ii x = r from the parts (two rounds of part tasks, each part's K_II
factored once where it is held) around the factor of the exact static Schur complement S on the cuts
(sidprep.reduction.coarse_space.schur_factor), recovers every model DOF from the assembly's coordinates
in the same rounds and counts the whole model's eigenvalues over the parts.  ``parts_reduced_model``
builds from it what ``craig_bampton`` returns for the model in one piece: the EXACT constraint modes
-K_ii^-1 K_ib, the recovered fixed-interface modes refined by one block inverse iteration
(``refined_modes``; Bathe & Wilson 1972), K and M projected from the model's matrices.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from sidprep.fe.linalg import all_cores_blas
from sidprep.reduction.coarse_space import count_below
from sidprep.reduction.component_modes import Assembly
from sidprep.reduction.craig_bampton import ReducedModel, block_gram, blockwise, interior_operator, project
from sidprep.reduction.part_tasks import InProcess, PartTaskRunner, part_coarse_load, part_interior_solve

#: relative eigenvalue of the Gram matrix below which a direction of [X, K^-1 M X] is dropped
RANK_TOL = 1e-12
#: rows of the Ritz vectors combined at a time (``ritz_vectors``; its temporaries scale with them)
REFINE_ROWS = 65536


class SubstructuredSolver:
    """Exact solves with K_ii of the whole model (i = every model DOF but the boundary b) from the
    parts and ``coarse_factor``, the factor of the exact static Schur complement S on the coarse DOFs
    G \\ b (sidprep.reduction.coarse_space.schur_factor):

        g = r_G - sum_p K_GI K_II^-1 r_p,   S x_G = g,   x_p = K_II^-1 (r_p - K_IG x_G)

    two rounds of part tasks (``part_coarse_load``, ``part_interior_solve`` on ``tasks``, default
    ``InProcess``) around the coarse solve;
    each part's K_II is factored once, where the part is held (the driver holds no part factor).
    It is the ``interior_factor`` of the parts' ReducedModel (``solve``), recovers every model DOF
    from coarse coordinates and modal coordinates in the same second round (``solve_and_recover``)
    and counts eigenvalues over the parts (``eigenvalue_count``).
    """

    def __init__(self, parts, reductions, assembly: Assembly, boundary, n_model: int, coarse_factor,
                 tasks: PartTaskRunner | None = None):

        self.parts, self.reductions, self.assembly = parts, reductions, assembly
        self.tasks = tasks or InProcess(parts)
        self.space = assembly.space
        self.boundary = np.asarray(boundary, dtype=np.int64)
        interior = np.ones(n_model, bool)
        interior[self.boundary] = False
        self.row = np.cumsum(interior) - 1                 # model DOF -> row of K_ii
        self.free_coarse = self.space.free
        self.schur = coarse_factor

    def own_rows(self, p: int) -> np.ndarray:
        """Rows of K_ii of part p's own DOFs."""
        part = self.parts[p]
        return self.row[part.dofs[part.interior]]

    def solve(self, r: np.ndarray, overwrite_r: bool = False) -> np.ndarray:
        """x = K_ii^-1 r, r (ni,) or (ni, k) in the rows of K_ii (model DOFs but b, ascending);
        ``overwrite_r``: x is written into r (float64, C-contiguous), no (ni, k) array more."""
        shape = np.shape(r)
        x, _ = self.solve_and_recover(np.asarray(r, dtype=float).reshape(shape[0], -1), None, overwrite_r)
        return x.reshape(shape)

    def solve_and_recover(self, r: np.ndarray, U: np.ndarray | None, overwrite_r: bool = False,
                          out: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None]:
        """(K_ii^-1 r (ni, k), the model-DOF vectors (n_model, m) of the assembly vectors U (n_asm, m),
        written into ``out`` if given); r (ni, k) in the rows of K_ii; U None: no recovery;
        ``overwrite_r``: see ``solve``.  The recovery (u_G = R c; each part's own DOFs
        u_I = -K_II^-1 K_IB u_B + Phi_p q_p, step 5) rides on the solve's second round."""
        space, n = self.space, len(self.parts)
        coarse, free = space.coarse, self.free_coarse
        slot = np.full(len(coarse), -1)
        slot[free] = np.arange(len(free))
        cols = [slot[space.local[p]] for p in range(n)]
        g = r[self.row[coarse[free]]].copy()

        def subtract(p: int, load: np.ndarray) -> None:
            keep = cols[p] >= 0
            g[cols[p][keep]] -= load[keep]

        r_parts = [r[self.own_rows(p)] for p in range(n)]      # each part's load, sent in both rounds
        if r.shape[1]:
            self.tasks(part_coarse_load, [(r_p,) for r_p in r_parts], subtract)
        with all_cores_blas():                            # between two rounds of part tasks
            x_G = np.asarray(self.schur.solve(g)).reshape(g.shape) if self.schur is not None and r.shape[1] else g
        x = r if overwrite_r else np.empty_like(r)       # every row of x is written below; r is in g, r_parts
        x[self.row[coarse[free]]] = x_G
        u_B = [np.where((c >= 0)[:, None], x_G[np.maximum(c, 0)], 0.0) for c in cols]
        if U is None:
            out = None
        else:                                              # recovery: u_G = R c, no load on the parts
            out = np.zeros((len(self.row), U.shape[1])) if out is None else out
            u_G = space.R @ U[:space.R.shape[1]]
            out[coarse] = u_G
            u_B = [np.hstack([u, u_G[space.local[p]]]) for p, u in enumerate(u_B)]
        k = r.shape[1]

        def place(p: int, x_p: np.ndarray) -> None:
            x[self.own_rows(p)] = x_p[:, :k]
            if U is not None:
                a, part = self.assembly, self.parts[p]
                out[part.dofs[part.interior]] = self.reductions[p].modes @ U[a.offsets[p]:a.offsets[p + 1]] + x_p[:, k:]

        self.tasks(part_interior_solve, list(zip(r_parts, u_B)), place)
        return x, out

    def constraint_modes_and_recovery(self, K_model, U: np.ndarray, out: np.ndarray | None = None) -> tuple:
        """((ni, nb) the whole model's exact constraint modes on the interior, -K_ii^-1 K_ib; the
        model-DOF vectors of the assembly vectors U, written into ``out`` if given): two rounds of part
        tasks for both."""
        interior = np.ones(K_model.shape[0], bool)
        interior[self.boundary] = False
        K_ib = K_model[self.boundary][:, interior].T      # K symmetric: no copy of K's interior rows
        return self.solve_and_recover(-K_ib.toarray(), U, overwrite_r=True, out=out)

    def eigenvalue_count(self, red, sigma: float) -> int | None:
        """Eigenvalues of the whole model below ``sigma`` (held DOFs removed), over the parts (``count_below``)."""
        return count_below(self.parts, self.space.coarse, red.held, sigma, self.tasks)


def parts_reduced_model(K_model, M_model, solver: SubstructuredSolver, level2: ReducedModel) -> ReducedModel:
    """Steps 5 and 6: the ReducedModel of the whole model in model DOFs, as ``craig_bampton`` returns it
    (basis with the boundary columns first: the EXACT constraint modes by the substructured
    ``solver``; then the second level's (``level2``) fixed-interface modes recovered and refined; K, M
    projected from the model matrices), with ``solver`` as its factor.  The solver's list of the
    parts' reductions is emptied once the basis is recovered: the parts' modes, (n, ~60) together,
    are not kept beside it (the driver's peak)."""

    n, boundary = K_model.shape[0], solver.boundary
    nb = len(boundary)
    basis = np.zeros((n, level2.basis.shape[1]))
    psi, _ = solver.constraint_modes_and_recovery(K_model, level2.basis[:, nb:], out=basis[:, nb:])
    solver.reductions.clear()                             # the recovery is done
    interior = np.ones(n, bool)
    interior[boundary] = False
    basis[boundary, :nb] = np.eye(nb)
    basis[interior, :nb] = psi
    f, basis[interior, nb:] = refined_modes(K_model, M_model, interior, solver, basis[interior, nb:])
    return ReducedModel(basis, project(K_model, basis), project(M_model, basis), boundary, f, solver)


def refined_modes(K, M, interior, solver, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Step 6: the lowest len(X.T) eigenpairs of K_ii, M_ii in span[X, K_ii^-1 M_ii X] (Rayleigh-Ritz
    after one block inverse iteration); (frequencies Hz (nm,), modes (ni, nm) M_ii-normalised,
    written over X).
    V = [X, Y] is never formed: its Gram matrices are formed GRAM_BLOCK columns at a time from X and
    Y, Y = K_ii^-1 (M_ii X) is solved in the buffer of M_ii X (``blockwise``), and the Ritz vectors X R_X + Y R_Y
    ([R_X; R_Y] = diag(d) C Z, small) are written over X: the peak is about 2 x (ni, nm) beside X
    (Y and the solve's per-part loads)."""

    nm = X.shape[1]
    if nm == 0:
        return np.zeros(0), X
    m_ii, k_ii = interior_operator(M, interior).matmat, interior_operator(K, interior).matmat
    Y = solver.solve(blockwise(m_ii, X), overwrite_r=True)
    with all_cores_blas():                                # no part task runs
        G, H = block_gram(m_ii, (X, Y)), block_gram(k_ii, (X, Y))
    d = 1.0 / np.sqrt(np.diag(G))                          # columns of unit M_ii norm
    G, H = d[:, None] * G * d, d[:, None] * H * d
    s, W = np.linalg.eigh(0.5 * (G + G.T))
    keep = s > RANK_TOL * s.max()                        # X and K^-1 M X are nearly parallel
    C = W[:, keep] / np.sqrt(s[keep])                    # V diag(d) C is M_ii-orthonormal
    lam, Z = sla.eigh(C.T @ (0.5 * (H + H.T)) @ C, subset_by_index=(0, nm - 1))
    R = d[:, None] * (C @ Z)                             # (2 nm, nm): the Ritz vectors in V's columns
    return np.sqrt(np.abs(lam)) / (2 * np.pi), ritz_vectors(X, Y, R)


def ritz_vectors(X: np.ndarray, Y: np.ndarray, R: np.ndarray) -> np.ndarray:
    """X R[:nm] + Y R[nm:] written over X (ni, nm), REFINE_ROWS rows at a time: no (ni, nm) temporary."""
    nm = X.shape[1]
    for s in range(0, len(X), REFINE_ROWS):
        X[s:s + REFINE_ROWS] = X[s:s + REFINE_ROWS] @ R[:nm] + Y[s:s + REFINE_ROWS] @ R[nm:]
    return X
