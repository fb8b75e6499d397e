"""A consistent start: assembly of the positions onto the constraints, removal of redundant
rows, velocities onto g_dot = 0, index-1 accelerations and multipliers, and an optional
quasi-static elastic start.

Assembly is a damped Gauss-Newton (Levenberg-Marquardt) least-squares projection in
length-weighted coordinates, first over the rigid-body coordinates only, then over all: it
closes loops whose matrix B is nearly singular (e.g. a planar loop of 3D revolute joints with
bodies placed a few micrometres out of plane), where a plain Gauss-Newton step diverges.
"""

from __future__ import annotations

import numpy as np

from sidprep.errors import InputError
from sidprep.solver.core import assemble, records, steps
from sidprep.solver.core.records import layout_record
from sidprep.solver.integrators.base import constraint_rows, contiguous, evaluate, moved_pose

#: assembly tolerance: constraint residual, m or rad
POSITION_TOL = 1e-12
#: redundant rows may contradict the others by at most this fraction of the system length (m/m
#: or rad) and be dropped at assembly (e.g. the pins of a rigid loop micrometres out of plane)
REDUNDANT_MISMATCH = 1e-4
#: assembly: maximum damped Gauss-Newton iterations
ASSEMBLY_ITERATIONS = 100
#: the rigid-body pass of the assembly ends when its linearised step would lower the residual by
#: less than this fraction: the rest of g is outside what the rigid coordinates move (a modal
#: change of a body jointed at its nodes), and damping the step more cannot help
RIGID_STALL = 1e-3
#: quasi-static start: finite-difference step of the Jacobian of the modal accelerations, as the
#: fraction of the system length a modal coordinate moves the body's nodes by; the reassembly's
#: response is nonlinear beyond ~1e-7 (examples/slider_crank: with 1e-6 the Newton iteration did
#: not converge, |q_ddot| 8.8 -> 46 after 10 iterations; with 1e-8 it falls to 4e-12 in 5)
QUASI_STATIC_STEP = 1e-8
#: a constraint row is redundant when its component independent of the rows kept before it is
#: below this fraction of its norm (Gram-Schmidt at the assembled state)
REDUNDANCY_TOL = 1e-8


def length_weights(system, terms, L) -> tuple[np.ndarray, float]:
    """Per-coordinate factors converting coordinate changes to lengths (m per unit), and the
    system length L (m).

    Translations 1, rotations L, modal coordinate k: max over SID nodes of |Phi_n[:, k]|, at
    least sqrt(2) times the mass-weighted RMS displacement sqrt(Me_kk / m) of the mode (the peak
    of a sine-shaped form; e.g. when the SID nodes sit where the modes vanish, at clamped or
    pinned ends).
    """
    radii = [1e-3]
    for b, t in zip(system.bodies, terms):
        radii.append(float(np.sqrt(np.trace(t.I0) / (2 * t.mass))))
        radii += [float(np.linalg.norm(m.position)) for m in b.markers]
    length = max(radii)
    w = np.ones(int(L.uoff[-1]))
    for i, (b, t) in enumerate(zip(system.bodies, terms)):
        s = int(L.uoff[i])
        w[s + 3:s + 6] = length
        if t.nq:
            rms = np.sqrt(2.0 * np.abs(np.diag(t.Me)) / t.mass)
            phi = np.array([np.linalg.norm(n.phi.M0, axis=0) for n in b.sid.nodes] + [rms]).max(axis=0)
            w[s + 6:s + 6 + t.nq] = np.maximum(phi, 1e-300)
    return w, length


def body_sizes(system, terms) -> np.ndarray:
    """Size of every body (nb,), m: the largest distance between its SID nodes, at least twice
    its radius of gyration about its centre of mass (the scale of its small-deformation range)."""
    sizes = []
    for b, t in zip(system.bodies, terms):
        c = t.md0 / t.mass
        i_cm = t.I0 - t.mass * (c @ c * np.eye(3) - np.outer(c, c))
        size = 2.0 * float(np.sqrt(max(np.trace(i_cm), 0.0) / (2 * t.mass)))
        if t.nq:
            nodes = np.array([n.origin.M0.ravel() for n in b.sid.nodes]).reshape(-1, 3)
            span = np.linalg.norm(nodes[:, None] - nodes[None], axis=2).max() if len(nodes) else 0.0
            size = max(size, float(span))
        sizes.append(size)
    return np.array(sizes)


def rigid_columns(L) -> np.ndarray:
    """Boolean mask of the rigid-body coordinates (6 per body) among the n velocities."""
    rigid = np.zeros(int(L.uoff[-1]), bool)
    for s in L.uoff[:-1]:
        rigid[s:s + 6] = True
    return rigid


class PoseConstraints:
    """(g, B) of all rows of the layout L at poses (zero velocities) at time t (s) with the angle
    references refs, evaluated into one workspace (core assemble.evaluate_into): the assembly's
    evaluations."""

    def __init__(self, L, t, refs):
        self.L, self.t, self.refs = layout_record(L), float(t), contiguous(refs)[0]
        self.W = records.evaluation_arrays(self.L)
        self.u, self.lam = np.zeros(int(self.L.uoff[-1])), np.zeros(constraint_rows(self.L))

    def __call__(self, R, A, Q):
        """(g (m_all,), B (m_all, n)) at the pose R, A, Q (new arrays)."""
        assemble.evaluate_into(self.L, self.W, *contiguous(R, A, Q), self.u, self.t, self.lam, self.refs)
        return np.array(self.W.g), np.array(self.W.B)


def assemble_positions(L, R, A, Q, t, refs, kept, weights, names, length):
    """(R, A, Q) moved onto g = 0 on the ``kept`` rows (module doc).  When they cannot all hold,
    on their subset independent at the placed pose, provided the dropped redundant rows then miss
    by less than REDUNDANT_MISMATCH ``length`` (m, the system length; e.g. the pins of a rigid
    loop micrometres out of plane); otherwise InputError naming the worst joint."""
    constraints_at = PoseConstraints(L, t, refs)
    try:
        return damped_gauss_newton(constraints_at, R, A, Q, kept, weights, names)
    except InputError as failure:
        independent = kept[independent_rows(constraints_at(R, A, Q)[1][kept])]
        if independent.size == kept.size:
            raise
        try:
            R2, A2, Q2 = damped_gauss_newton(constraints_at, R, A, Q, independent, weights, names)
        except InputError:
            raise failure from None
        if np.max(np.abs(constraints_at(R2, A2, Q2)[0][kept])) >= REDUNDANT_MISMATCH * length:
            raise failure from None
        return R2, A2, Q2


def damped_gauss_newton(constraints_at, R, A, Q, kept, weights, names, rigid_only=True):
    """(R, A, Q) with g = 0 on the ``kept`` rows (constraints_at: the PoseConstraints of the
    layout): Levenberg-Marquardt over the rigid-body coordinates, then over all (module doc);
    InputError naming the worst joint."""
    L = constraints_at.L
    cols = rigid_columns(L) if rigid_only else np.ones(int(L.uoff[-1]), bool)
    scale = 1.0 / weights[cols]
    g, B = constraints_at(R, A, Q)
    res = np.linalg.norm(g[kept])
    mu = 1e-12
    for _ in range(ASSEMBLY_ITERATIONS):
        if g[kept].size == 0 or np.max(np.abs(g[kept])) < POSITION_TOL:
            return R, A, Q
        J = B[kept][:, cols] * scale
        JJ = J @ J.T
        while True:
            step = -J.T @ np.linalg.solve(JJ + mu * (np.trace(JJ) / len(JJ) + 1e-300) * np.eye(len(JJ)), g[kept])
            if rigid_only and np.linalg.norm(g[kept] + J @ step) > (1.0 - RIGID_STALL) * res:
                res2 = res
                break
            delta = np.zeros(int(L.uoff[-1]))
            delta[cols] = scale * step
            R2, A2, Q2 = moved_pose(L, R, A, Q, delta)
            g2, B2 = constraints_at(R2, A2, Q2)
            res2 = np.linalg.norm(g2[kept])
            if res2 < res or mu > 1e6:
                break
            mu *= 10.0
        if res2 >= res:
            break
        R, A, Q, g, B, res = R2, A2, Q2, g2, B2, res2
        mu = max(mu / 10.0, 1e-12)
    if rigid_only:
        return damped_gauss_newton(constraints_at, R, A, Q, kept, weights, names, rigid_only=False)
    worst = int(kept[np.argmax(np.abs(g[kept]))])
    raise InputError(f"joint '{names[worst]}': the initial positions cannot satisfy it (residual "
                     f"{np.max(np.abs(g[kept])):.3g} m or rad); place its markers so that they coincide and their "
                     "z axes align as the joint requires")


def independent_rows(B: np.ndarray, tol: float = REDUNDANCY_TOL) -> np.ndarray:
    """Boolean mask of the rows of B kept by Gram-Schmidt in order (earlier rows win)."""
    kept = np.zeros(B.shape[0], bool)
    basis: list[np.ndarray] = []
    for i, row in enumerate(B):
        norm = np.linalg.norm(row)
        if norm == 0.0:
            continue
        v = row.copy()
        for _ in range(2):  # second pass for orthogonality
            for e in basis:
                v -= (e @ v) * e
        rn = np.linalg.norm(v)
        if rn > tol * norm:
            basis.append(v / rn)
            kept[i] = True
    return kept


def project_velocities(L, R, A, Q, u, t, refs, kept, weights):
    """u corrected onto B u + b_t = 0, changing the rigid-body velocities only where possible.

    Minimum-norm correction over the rigid-body columns (length-weighted), so that the given
    modal velocities stay (a body driven at speed starts spinning undeformed); when the rigid
    columns cannot satisfy the constraints, the mass-weighted projection over all coordinates.
    """
    if kept.size == 0:
        return u
    L = layout_record(L)
    m_all = constraint_rows(L)

    def error(v):
        e = evaluate(L, R, A, Q, v, t, np.zeros(m_all), refs)
        return (e.B @ v + e.bt)[kept], e

    err, e = error(u)
    B = e.B[kept]
    rigid = rigid_columns(L)
    scale = 1.0 / weights[rigid]
    du = np.zeros_like(u)
    du[rigid] = scale * np.linalg.lstsq(B[:, rigid] * scale, -err, rcond=None)[0]
    if np.max(np.abs(error(u + du)[0]), initial=0.0) <= POSITION_TOL * (1.0 + np.max(np.abs(u))):
        return u + du
    return u + kkt_solution(e.M, np.zeros(u.size), e.B[kept], -err)[:u.size]


def kkt_solution(M, f, B, rhs) -> np.ndarray:
    """[x; lambda] of [M B^T; B 0] [x; lambda] = [f; rhs] (core steps.kkt_solve)."""
    M, f, B, rhs = contiguous(M, f, B, rhs)
    k = M.shape[0] + B.shape[0]
    z = np.empty(k)
    steps.kkt_solve(M, f, B, B, rhs, np.empty((k, k)), np.empty(k, np.intc), z)
    return z


def accelerations(L, R, A, Q, u, t, refs, free, kept, lam=None):
    """Index-1 accelerations (n,) and kept multipliers at a consistent state (no Baumgarte;
    core steps.index1_accelerations through steps.state_equations, lam the first guess of the
    kept multipliers, default zero)."""
    guess = np.zeros(constraint_rows(L))
    if lam is not None:
        guess[kept] = lam
    R, A, Q, u, refs = contiguous(R, A, Q, u, refs)
    free, kept = (np.ascontiguousarray(x, dtype=np.int64) for x in (free, kept))
    return steps.state_equations(layout_record(L), R, A, Q, u, float(t), guess, refs, free, kept, True)[1:]


def quasi_static_elastic(L, pose, u, t, refs, free, kept, weights, length, names, iterations=10):
    """The pose (R, A, Q) with the modal coordinates Q at q_ddot = 0 under the initial loads and
    rigid-body accelerations.

    Gauss-Newton on F(q) = q_ddot(q) (index-1 accelerations; for every q the rigid coordinates
    are re-assembled onto the constraints).  Where joints at nodes pin combinations of q, the
    perturbations are projected too: the columns D of actually reachable changes give the
    reduced system (D^T dF) c = -D^T F, solved in the least-squares sense.
    """
    R, A, Q = pose
    L = layout_record(L)
    modal = ~rigid_columns(L)
    if not modal.any():
        return R, A, Q
    qcols = np.flatnonzero(modal)

    def qdd(R_, A_, Q_):
        return accelerations(L, R_, A_, Q_, u, t, refs, free, kept)[0][qcols]

    def with_q(qvec):
        return assemble_positions(L, R, A, qvec, t, refs, kept, weights, names, length)

    scale = length / weights[qcols]  # q moving nodes by L
    for _ in range(iterations):
        f0 = qdd(R, A, Q)
        dmat = np.empty((Q.size, Q.size))
        dfun = np.empty((Q.size, Q.size))
        for k in range(Q.size):
            trial = Q.copy()
            trial[k] += QUASI_STATIC_STEP * max(scale[k], abs(Q[k]))
            Rk, Ak, Qk = with_q(trial)
            dmat[:, k] = Qk - Q
            dfun[:, k] = qdd(Rk, Ak, Qk) - f0
        c = np.linalg.lstsq(dmat.T @ dfun, -dmat.T @ f0, rcond=1e-10)[0]
        step = dmat @ c
        R, A, Q = with_q(Q + step)
        if np.max(np.abs(step) / np.maximum(np.abs(Q), scale * 1e-9)) < 1e-8:
            break
    return R, A, Q

