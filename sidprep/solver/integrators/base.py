"""What every integrator shares: the problem it integrates, its state, the samples it hands
back, the stepper contract, and the compiled linear algebra and Lie-group update.

The contract follows scipy's ``OdeSolver``: a stepper is made for one run from the problem,
the consistent initial state and the settings, owns its state from then on, and is driven by
``advance(t_stop)``, which integrates up to t_stop (or until its sample buffer is full) and
returns the output samples of that stretch; ``status`` is "running", "finished" or "failed"
(``message`` says why).  A stepper whose compiled loop also computes its samples' outputs
(integrators/outputs.py) keeps them in ``outputs`` (a list, one SampledOutputs per stretch) and
records the start (t = 0) as its first sample; otherwise ``outputs`` is None and the run adds
the start and post-processing computes the outputs.
"""

from __future__ import annotations

from collections import namedtuple
from dataclasses import dataclass

import numpy as np

from sidprep.solver.core import steps as core_steps
from sidprep.solver.core.records import Layout, layout_record
from sidprep.solver.equations.assemble import evaluate_into, evaluation_arrays
from sidprep.solver.equations.forces import FE_FRICTION
from sidprep.solver.equations.aot import NumbaValue
from sidprep.solver.equations.rotations import add, exp_so3, jit, matvec, put, put2, se3_jacobian

#: output samples per call of a compiled integration loop (the stepper resumes it)
CHUNK = 4096
#: time step of the central difference giving gamma = d/dt (B u + b_t), s
GAMMA_STEP = 1e-6
#: friction reads the multipliers: the index-1 solve is repeated until they change by less than
#: this, relative to the largest (a fixed count left an error of the order of the previous call's
#: change, and RK4 fell to order 1.2-1.4 on the seed slider crank; docs/accuracy-cost.md)
MULTIPLIER_RTOL = 1e-10
#: friction couples the forces to the multipliers: most fixed-point iterations per evaluation
#: (base.index1_accelerations stops once the multipliers settle to MULTIPLIER_RTOL)
MULTIPLIER_ITERATIONS = 30

#: contacts: a step from an open bump stop that is closing reaches at most this multiple of the
#: time to close its gap (genalpha.py, explicit.py; the kink itself is then located)
APPROACH_REACH = 2.0

#: the output samples of one call of a compiled loop: t (k,), R (k, nb, 3), A (k, nb, 3, 3),
#: Q (k, nq), u, ud (k, n), lam (k, m), refs (k, nj), work (k, 3); ``sample_buffers`` makes them
SampleBuffers = namedtuple("SampleBuffers", ["t", "R", "A", "Q", "u", "ud", "lam", "refs", "work"])
#: a compiled loop's status, one record (``new_status``): counters, step sizes (s), the run
#: status code (RUNNING, ...), max_steps, and the body that left its small-deformation range
#: with its deflection (m)
STATUS = np.dtype([("steps", np.int64), ("rejected", np.int64), ("newton_iterations", np.int64),
                   ("jacobians", np.int64), ("h_min", np.float64), ("h_max", np.float64), ("code", np.int64),
                   ("max_steps", np.int64), ("body", np.int64), ("deflection", np.float64)])
#: status codes of the compiled loops (core steps.pxd)
RUNNING, FINISHED, MAX_STEPS, NEWTON_FAILED, LARGE_DEFORMATION = (core_steps.RUNNING, core_steps.FINISHED,
                                                                  core_steps.MAX_STEPS, core_steps.NEWTON_FAILED,
                                                                  core_steps.LARGE_DEFORMATION)


def new_status(max_steps: int) -> np.ndarray:
    """A fresh loop status (one STATUS record in an array the loop updates in place)."""
    status = np.zeros(1, STATUS)
    status[0]["h_min"], status[0]["max_steps"] = np.inf, max_steps
    return status


@dataclass
class Problem:
    """A run's compiled problem: the layout L (compile/layout.py), the integrated coordinates
    ``free`` (indices into u; all but the out-of-plane ones of a planar run), the kept
    constraint rows ``kept`` (indices; redundant rows dropped), per-coordinate length weights
    (m per unit), the system length (m), the joints' angle references ``refs`` (nj,), updated
    by the stepper after every accepted step, t_end (s), the bodies' sizes (nb,), m (the
    scale of their small-deformation range), and the PostSetup of the samples' outputs
    (integrators/outputs.py)."""

    L: tuple
    free: np.ndarray
    kept: np.ndarray
    weights: np.ndarray
    length: float
    refs: np.ndarray
    t_end: float
    sizes: np.ndarray
    post: tuple

    @property
    def m_all(self) -> int:
        return constraint_rows(self.L)


@dataclass
class State:
    """Positions R (nb, 3), A (nb, 3, 3), Q (sum nq,), velocities u (n,), accelerations ud (n,)
    and multipliers lam (kept rows) at time t."""

    t: float
    R: np.ndarray
    A: np.ndarray
    Q: np.ndarray
    u: np.ndarray
    ud: np.ndarray
    lam: np.ndarray

    def copy(self) -> "State":
        return State(self.t, self.R.copy(), self.A.copy(), self.Q.copy(), self.u.copy(), self.ud.copy(),
                     self.lam.copy())


@dataclass
class Samples:
    """Output samples of one stretch: t (k,), R, A, Q, u, ud, lam (kept rows), refs (k, nj) the
    angle references, work (k, 3) = [work of applied loads, dissipated energy, work of drivers]
    since t = 0, J."""

    t: np.ndarray
    R: np.ndarray
    A: np.ndarray
    Q: np.ndarray
    u: np.ndarray
    ud: np.ndarray
    lam: np.ndarray
    refs: np.ndarray
    work: np.ndarray


class Stepper:
    """Base of the integrators (module doc).  Subclasses set ``name`` and implement advance."""

    name = ""

    def __init__(self, problem: Problem, state: State, settings):
        self.problem, self.state, self.settings = problem, state, settings
        self.status, self.message = "running", ""
        #: (body index, deflection m, time s) when a body left its small-deformation range
        self.large_deformation = None
        #: the SampledOutputs of each stretch when the compiled loop computes them (module doc)
        self.outputs: list | None = None
        self.stats = {"steps": 0, "rejected": 0, "rhs_evaluations": 0, "newton_iterations": 0, "jacobians": 0,
                      "h_min": np.inf, "h_max": 0.0}

    @property
    def t(self) -> float:
        return self.state.t

    def advance(self, t_stop: float) -> Samples:  # pragma: no cover - interface
        raise NotImplementedError


@jit
def sample_buffers(capacity, R, Q, u, lam, refs):  # pragma: no cover - compiled
    """Empty SampleBuffers of ``capacity`` rows for states shaped like R, Q, u, lam, refs."""
    n = u.shape[0]
    return SampleBuffers(np.empty(capacity), np.empty((capacity,) + R.shape), np.empty((capacity, R.shape[0], 3, 3)),
                         np.empty((capacity, Q.shape[0])), np.empty((capacity, n)), np.empty((capacity, n)),
                         np.empty((capacity, lam.shape[0])), np.empty((capacity, refs.shape[0])),
                         np.empty((capacity, 3)))


@jit
def first_samples(buf, count):  # pragma: no cover - compiled
    """The first ``count`` rows of the SampleBuffers buf."""
    return SampleBuffers(buf.t[:count], buf.R[:count], buf.A[:count], buf.Q[:count], buf.u[:count], buf.ud[:count],
                         buf.lam[:count], buf.refs[:count], buf.work[:count])


@jit
def store_sample(buf, k, t, R, A, Q, u, ud, lam, refs, work):  # pragma: no cover - compiled
    """Write one output sample into row k of the SampleBuffers buf (by loops: see rotations.put)."""
    buf.t[k] = t
    put2(buf.R[k], 0, 0, R)
    for i in range(R.shape[0]):
        put2(buf.A[k, i], 0, 0, A[i])
    put(buf.Q[k], 0, Q)
    put(buf.u[k], 0, u)
    put(buf.ud[k], 0, ud)
    put(buf.lam[k], 0, lam)
    put(buf.refs[k], 0, refs)
    put(buf.work[k], 0, work)


@jit
def expand(lam, kept, out):  # pragma: no cover - compiled
    """Multipliers of all rows, written into out (m_all,; zero on the dropped rows), from those
    of the kept rows; returns out."""
    out.fill(0.0)
    for k in range(kept.shape[0]):
        out[kept[k]] = lam[k]
    return out


@jit
def advance_pose(L, R, A, Q, dx, body_frame=False):  # pragma: no cover - compiled
    """Positions moved by the increment dx (n,): r + dr, A exp(dtheta), q + dq (Lie group
    R^3 x SO(3)); ``body_frame``: dr in body components, moved along the SE(3) exponential,
    r + A V(dtheta) dr (se3_jacobian; integrators/se3.py)."""
    R2, A2, Q2 = R.copy(), np.empty_like(A), Q.copy()
    for i in range(R.shape[0]):  # in scalars where it costs nothing: this runs at every Newton iteration
        s = L.uoff[i]
        theta = dx[s + 3:s + 6].copy()
        if body_frame:
            V = se3_jacobian(theta)
            y0, y1, y2 = 0.0, 0.0, 0.0  # V dr
            for j in range(3):
                y0 += V[0, j] * dx[s + j]
                y1 += V[1, j] * dx[s + j]
                y2 += V[2, j] * dx[s + j]
            for a in range(3):
                acc = 0.0
                acc += A[i, a, 0] * y0
                acc += A[i, a, 1] * y1
                acc += A[i, a, 2] * y2
                R2[i, a] += acc
        else:
            add(R2[i], 0, dx[s:s + 3])
        E = exp_so3(theta)
        for a in range(3):  # A exp(theta~)
            for k in range(3):
                acc = 0.0
                for j in range(3):
                    acc += A[i, a, j] * E[j, k]
                A2[i, a, k] = acc
        nq = L.qoff[i + 1] - L.qoff[i]
        add(Q2, L.qoff[i], dx[s + 6:s + 6 + nq])
    return R2, A2, Q2


def dgetrf_binding():
    """numba's own binding of LAPACK dgetrf (double precision)."""
    from numba import types  # deferred: import numba 0.17 CPU s, only when lu_factor is JIT-compiled
    from numba.np.linalg import _LAPACK

    return _LAPACK().numba_xxgetrf(types.float64)


#: LAPACK dgetrf through numba's own binding (cacheable): from ~40 unknowns on twice as fast as
#: loops, about as fast below; made when numba first types a kernel that calls it
_DGETRF = NumbaValue(dgetrf_binding)
_REAL = ord("d")


@jit
def lu_factor(a):  # pragma: no cover - compiled
    """LU factors of a (k, k) by LAPACK dgetrf: (lu, piv).  The row-major copy of a is the
    column-major a^T, so lu holds a^T = P L U (piv: LAPACK's 1-based row interchanges);
    lu_solve solves with it."""
    k = a.shape[0]
    lu = a.copy()
    piv = np.empty(k, np.int32)
    _DGETRF(_REAL, k, k, lu.ctypes, k, piv.ctypes)
    return lu, piv


@jit
def lu_solve(lu, piv, b):  # pragma: no cover - compiled
    """x with a x = b from lu_factor(a): a = U^T L^T P^T, so U^T L^T w = b and x = P w (NaN
    where a is singular)."""
    k = b.shape[0]
    x = np.empty(k)
    for i in range(k):  # U^T (lower; U(j, i) is lu[i, j])
        acc = b[i]
        for c in range(i):
            acc -= lu[i, c] * x[c]
        pivot = lu[i, i]  # exactly 0 for a singular a: NaN, not an exception, so the callers'
        x[i] = acc / pivot if pivot != 0.0 else np.nan  # non-finite checks name the cause
    for i in range(k - 1, -1, -1):  # L^T (unit upper; L(j, i) is lu[i, j])
        acc = x[i]
        for c in range(i + 1, k):
            acc -= lu[i, c] * x[c]
        x[i] = acc
    for i in range(k - 1, -1, -1):  # x = P w: the interchanges in reverse order
        p = piv[i] - 1
        x[i], x[p] = x[p], x[i]
    return x


@jit
def restrict(M, f, B, BF, free, kept):  # pragma: no cover - compiled
    """M, f, B, B_F restricted to the integrated coordinates and the kept rows."""
    nf, m = free.shape[0], kept.shape[0]
    Mf = np.empty((nf, nf))
    ff = np.empty(nf)
    Bk = np.empty((m, nf))
    BFk = np.empty((m, nf))
    for i in range(nf):
        ff[i] = f[free[i]]
        for j in range(nf):
            Mf[i, j] = M[free[i], free[j]]
        for k in range(m):
            Bk[k, i] = B[kept[k], free[i]]
            BFk[k, i] = BF[kept[k], free[i]]
    return Mf, ff, Bk, BFk


@jit
def kkt_solve(M, f, B, BF, rhs):  # pragma: no cover - compiled
    """[M B_F^T; B 0] [x; lambda] = [f; rhs] -> (x, lambda)."""
    n, m = M.shape[0], B.shape[0]
    K = np.zeros((n + m, n + m))
    put2(K, 0, 0, M)
    put2(K, 0, n, BF.T)
    put2(K, n, 0, B)
    b = np.empty(n + m)
    put(b, 0, f)
    put(b, n, rhs)
    lu, piv = lu_factor(K)
    z = lu_solve(lu, piv, b)
    return z[:n], z[n:]


@jit
def constraint_convection(L, W, R, A, Q, u, t, refs, kept):  # pragma: no cover - compiled
    """gamma (kept,) = d/dt (B u + b_t) at constant u: the central difference of B u + b_t
    between the evaluations (into the workspace W) at the poses moved by +-GAMMA_STEP u (at
    t +- GAMMA_STEP), exact to O(1e-12) relative for the smooth constraint functions."""
    zero = np.zeros(W.g.shape[0])
    Rp, Ap, Qp = advance_pose(L, R, A, Q, GAMMA_STEP * u)
    evaluate_into(L, W, Rp, Ap, Qp, u, t + GAMMA_STEP, zero, refs)
    plus = matvec(W.B, u) + W.bt
    Rm, Am, Qm = advance_pose(L, R, A, Q, -GAMMA_STEP * u)
    evaluate_into(L, W, Rm, Am, Qm, u, t - GAMMA_STEP, zero, refs)
    minus = matvec(W.B, u) + W.bt
    gam = np.empty(kept.shape[0])
    for k in range(kept.shape[0]):
        gam[k] = (plus[kept[k]] - minus[kept[k]]) / (2 * GAMMA_STEP)
    return gam


@jit
def has_friction(L):  # pragma: no cover - compiled
    """Whether a force element depends on the multipliers (friction): the index-1 solve then
    iterates on lambda."""
    for i in range(L.fe_int.shape[0]):
        if L.fe_int[i, 0] == FE_FRICTION:
            return True
    return False


@jit
def multipliers_settled(lam, lam_new):  # pragma: no cover - compiled
    """|lam_new - lam| <= MULTIPLIER_RTOL max |lam_new| (or no multipliers)."""
    return lam.shape[0] == 0 or np.max(np.abs(lam_new - lam)) <= MULTIPLIER_RTOL * np.max(np.abs(lam_new))


@jit
def index1_solve(e, gam, u, free, kept, baumgarte):  # pragma: no cover - compiled
    """Accelerations ud (n,; zero outside ``free``) and kept multipliers of the index-1 form

        M ud + B_F^T lambda = f,   B ud = -gamma - 2 a g_dot - a^2 g   (a = baumgarte, 1/s)

    at the Evaluation e (u (n,) its velocities, gam (kept,) from constraint_convection)."""
    Mf, ff, Bk, BFk = restrict(e.M, e.f, e.B, e.BF, free, kept)
    rhs = -gam
    if baumgarte > 0.0 and kept.shape[0]:
        gd = (matvec(e.B, u) + e.bt)[kept]
        rhs = rhs - 2.0 * baumgarte * gd - baumgarte * baumgarte * e.g[kept]
    x, lam = kkt_solve(Mf, ff, Bk, BFk, rhs)
    ud = np.zeros(u.shape[0])
    for i in range(free.shape[0]):
        ud[free[i]] = x[i]
    return ud, lam


@jit
def index1_accelerations(L, W, R, A, Q, u, t, refs, free, kept, baumgarte, lam_guess):  # pragma: no cover
    """Accelerations ud (n,) and kept multipliers of the index-1 form (index1_solve) at the
    state (R, A, Q, u, t), evaluated into the workspace W (assemble.evaluation_arrays; it holds
    the evaluation at the last guess of the multipliers afterwards); iterated when forces depend on
    lambda (friction) until lambda changes by less than MULTIPLIER_RTOL of its largest entry, at
    most MULTIPLIER_ITERATIONS times (lam_guess (kept,) the first guess).  The start
    (initial.accelerations) and the explicit loops call it."""
    gam = np.zeros(kept.shape[0])
    if kept.shape[0]:
        gam = constraint_convection(L, W, R, A, Q, u, t, refs, kept)
    lam = lam_guess.copy()
    lam_all = np.zeros(W.g.shape[0])
    ud = np.zeros(u.shape[0])
    for _ in range(MULTIPLIER_ITERATIONS if has_friction(L) else 1):
        evaluate_into(L, W, R, A, Q, u, t, expand(lam, kept, lam_all), refs)
        ud, lam_new = index1_solve(W, gam, u, free, kept, baumgarte)
        settled = multipliers_settled(lam, lam_new)
        lam = lam_new
        if settled:
            break
    return ud, lam


@jit
def state_equations(L, R, A, Q, u, t, lam, refs, free, kept, solve):  # pragma: no cover - compiled
    """The Evaluation at the state (R, A, Q, u, t) with the multipliers lam (m_all,), in a fresh
    workspace; when ``solve``, also the index-1 accelerations ud (n,) and the kept multipliers
    there (index1_accelerations without Baumgarte, lam[kept] the first guess; the Evaluation is
    then at the last guess), else two empty arrays.  The one compiled entry of the start and the
    other callers in Python (``evaluate``, initial.accelerations): a process loads the
    evaluation's call tree once for all of them (docs/performance.md, "Allocation-free step")."""
    W = evaluation_arrays(L)
    if solve:
        guess = np.empty(kept.shape[0])
        for k in range(kept.shape[0]):
            guess[k] = lam[kept[k]]
        ud, lam_kept = index1_accelerations(L, W, R, A, Q, u, t, refs, free, kept, 0.0, guess)
        return W, ud, lam_kept
    evaluate_into(L, W, R, A, Q, u, t, lam, refs)
    return W, np.zeros(0), np.zeros(0)


#: the empty row and coordinate lists of an evaluation without the index-1 solve
NO_INDICES = np.zeros(0, np.int64)
#: a state's MarkerKinematics and Evaluation (core records) as numpy arrays, for callers in Python
MarkerArrays = namedtuple("MarkerArrays", ["P", "AM", "VEL", "OMG", "JT", "JR", "JTF", "JRF", "VC", "WC"])
EvaluationArrays = namedtuple("EvaluationArrays", ["M", "f", "g", "B", "BF", "bt", "C", "coords", "loads", "flows",
                                                   "kin", "crows", "convective"])


def core_layout(L) -> Layout:
    """The compiled core's Layout record of L (compile/layout.py's Layout namedtuple, or a record)."""
    return L if isinstance(L, Layout) else layout_record(L)


def contiguous(*arrays) -> list[np.ndarray]:
    """The arrays as C-contiguous float64 (the core's kernels take them so; no copy when they are)."""
    return [np.ascontiguousarray(a, dtype=np.float64) for a in arrays]


def evaluation_values(W) -> EvaluationArrays:
    """The core Evaluation W as numpy arrays (views of its memory; B_F is B unless load-stiffened)."""
    kin = MarkerArrays(*(np.asarray(getattr(W.kin, name)) for name in MarkerArrays._fields))
    return EvaluationArrays(*(kin if name == "kin" else np.asarray(getattr(W, name)) for name in EvaluationArrays._fields))


def evaluate(L, R, A, Q, u, t, lam, refs) -> EvaluationArrays:
    """The Evaluation (core assemble.evaluate_into) at a state in a fresh workspace, as numpy
    arrays, for callers in Python (start, planar check, linearisation); compiled code passes its
    per-run workspace to evaluate_into."""
    R, A, Q, u, lam, refs = contiguous(R, A, Q, u, lam, refs)
    W = core_steps.state_equations(core_layout(L), R, A, Q, u, float(t), lam, refs, NO_INDICES, NO_INDICES, False)[0]
    return evaluation_values(W)


def moved_pose(L, R, A, Q, dx, body_frame=False):
    """New (R, A, Q): the pose moved by the increment dx (n,) (core steps.advance_pose), for
    callers in Python."""
    R, A, Q, dx = contiguous(R, A, Q, dx)
    R2, A2, Q2 = np.empty_like(R), np.empty_like(A), np.empty_like(Q)
    core_steps.advance_pose(core_layout(L), R, A, Q, dx, body_frame, R2, A2, Q2)
    return R2, A2, Q2


def constraint_rows(L) -> int:
    """m_all: the constraint rows of the layout L, every joint's then every driver's."""
    return int(L.joint_off[L.joint_off.shape[0] - 1] + L.drv_joint.shape[0])


def marker_kinematics(L, R, A, Q) -> MarkerArrays:
    """Every marker's MarkerKinematics (core assemble.markers_into) at the pose (R, A, Q), at rest at t = 0."""
    L = core_layout(L)
    return evaluate(L.with_every_marker(), R, A, Q, np.zeros(int(L.uoff[L.uoff.shape[0] - 1])),
                    0.0, np.zeros(constraint_rows(L)), np.zeros(L.joint_mk.shape[0])).kin
