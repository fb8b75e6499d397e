"""What every integrator shares: the problem it integrates, its state, the samples it hands
back, the stepper contract, and the Python side's calls of the compiled equations (core/steps.pyx:
the linear algebra, the Lie-group update and the index-1 solve).

The contract follows scipy's ``OdeSolver``: a stepper is made for one run from the problem,
the consistent initial state and the settings, owns its state from then on, and is driven by
``advance(t_stop)``, which integrates up to t_stop (or until its sample buffer is full) and
returns the output samples of that stretch; ``status`` is "running", "finished" or "failed"
(``message`` says why).  A stepper whose compiled loop also computes its samples' outputs
(core/outputs.pyx) keeps them in ``outputs`` (a list, one SampledOutputs per stretch) and
records the start (t = 0) as its first sample; otherwise ``outputs`` is None and the run adds
the start and post-processing computes the outputs.
"""

from __future__ import annotations

from collections import namedtuple
from dataclasses import dataclass

import numpy as np

from sidprep.solver.core import steps as core_steps
from sidprep.solver.core.steps import SampleArrays
from sidprep.solver.core.records import layout_record

#: output samples per call of a compiled integration loop (the stepper resumes it)
CHUNK = 4096


@dataclass
class Problem:
    """A run's compiled problem: the layout L (compile/layout.py), the integrated coordinates
    ``free`` (indices into u; all but the out-of-plane ones of a planar run), the kept
    constraint rows ``kept`` (indices; redundant rows dropped), per-coordinate length weights
    (m per unit), the system length (m), the joints' angle references ``refs`` (nj,), updated
    by the stepper after every accepted step, t_end (s), the bodies' sizes (nb,), m (the
    scale of their small-deformation range), and the PostSetup of the samples' outputs
    (postprocess.py)."""

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


@dataclass(frozen=True)
class StepCounts:
    """What a stepper did so far: accepted and rejected steps, right-hand-side evaluations, Newton
    iterations, Jacobian factorisations, and the smallest and largest accepted step h_min, h_max (s;
    inf and 0 before the first step)."""

    steps: int = 0
    rejected: int = 0
    rhs_evaluations: int = 0
    newton_iterations: int = 0
    jacobians: int = 0
    h_min: float = np.inf
    h_max: float = 0.0


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
        #: the counts so far (a StepCounts the stepper replaces as it goes)
        self.stats = StepCounts()

    @property
    def t(self) -> float:
        return self.state.t

    def advance(self, t_stop: float) -> SampleArrays:  # pragma: no cover - interface
        raise NotImplementedError


#: the empty row and coordinate lists of an evaluation without the index-1 solve
NO_INDICES = np.zeros(0, np.int64)
#: a state's MarkerKinematics and Evaluation (core records) as numpy arrays, for callers in Python
MarkerArrays = namedtuple("MarkerArrays", ["P", "AM", "VEL", "OMG", "JT", "JR", "JTF", "JRF", "VC", "WC"])
EvaluationArrays = namedtuple("EvaluationArrays", ["M", "f", "g", "B", "BF", "bt", "C", "coords", "loads", "flows",
                                                   "kin", "crows", "convective"])


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
    W = core_steps.state_equations(layout_record(L), R, A, Q, u, float(t), lam, refs, NO_INDICES, NO_INDICES, False)[0]
    return evaluation_values(W)


def moved_pose(L, R, A, Q, dx, body_frame=False):
    """New (R, A, Q): the pose moved by the increment dx (n,) (core steps.advance_pose), for
    callers in Python."""
    R, A, Q, dx = contiguous(R, A, Q, dx)
    R2, A2, Q2 = np.empty_like(R), np.empty_like(A), np.empty_like(Q)
    core_steps.advance_pose(layout_record(L), R, A, Q, dx, body_frame, R2, A2, Q2)
    return R2, A2, Q2


def constraint_rows(L) -> int:
    """m_all: the constraint rows of the layout L, every joint's then every driver's."""
    return int(L.joint_off[L.joint_off.shape[0] - 1] + L.drv_joint.shape[0])


def marker_kinematics(L, R, A, Q) -> MarkerArrays:
    """Every marker's MarkerKinematics (core assemble.markers_into) at the pose (R, A, Q), at rest at t = 0."""
    L = layout_record(L)
    return evaluate(L.with_every_marker(), R, A, Q, np.zeros(int(L.uoff[L.uoff.shape[0] - 1])),
                    0.0, np.zeros(constraint_rows(L)), np.zeros(L.joint_mk.shape[0])).kin
