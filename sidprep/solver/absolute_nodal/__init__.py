"""Interconnected planar flexible beams in absolute nodal coordinates (Kisu Lee).

No floating frame and no joint constraints: the unknowns are the absolute positions x_i (m,
inertial X-Y plane) of the nodes of two-node elements; beams joined by a revolute share one node.

* Mass (eq. 1-2): linear C0 interpolation of the absolute positions, element mass matrix
  m_e/6 [[2, 1], [1, 2]] per direction -- constant.
* Elastic force (eq. 3-9): per beam J, a frame with origin at its first node and x axis through
  its last node (angle phi_J); nodal deformations w_i = A(phi)^T (x_i - x_1) - (s_i, 0); the slope
  theta_i from the quadratic through node i and its neighbours (eq. 5; one-sided at the ends);
  V_J = 1/2 u^T K u with u_i = (w_x, w_y, theta)_i and K the linear Euler-Bernoulli (Hermite) +
  bar stiffness of the beam.  The generalized force R_J K_J u_J of eq. 10 is the exact gradient
  dV_J/dx, the turning of the frame included (the paper's eq. 12-14 drop it), so the discrete
  system is conservative and RK4's energy error is the integration error alone.
* M x'' + sum_J dV_J/dx = f (eq. 10), f = gravity + constant nodal forces; pinned nodes are
  removed; prescribed-angle drivers Phi = phi_J + theta_end - psi(t) = 0 at a support add
  Lagrange multipliers (the paper's remark after eq. 14) with Baumgarte stabilisation.
* Classic RK4 (the stages of sidprep/solver/core/runge_kutta.pyx) with a compiled right-hand side,
  driven under the stepper contract (run.py).

Modules, in the order of the data: model (the description) -> assembly (nodes, constant
matrices) -> the compiled kernels (sidprep/solver/core/absolute_nodal.pyx) -> run (the RK4
stepper) -> results (a ``solver.results.Result``: a body per beam, a marker per point, a
revolute "joint" per support and shared point, energies); scene reads the scene tables.  Import the names from those modules: the package imports nothing,
so that a scene of floating-frame bodies does not load this solver (28 CPU-ms of imports,
docs/performance.md "Fixed cost per process").
"""

from sidprep.lazy import submodule


def __getattr__(name: str):
    """The package's modules on first use (sidprep.lazy)."""
    return submodule(__name__, name)
