# Lie-group generalised-alpha for the index-3 DAE (genalpha.pyx): the method's state, constants and
# workspace, its kernels, and the stepping loop ga_loop (a def entry, called by
# sidprep/solver/integrators/genalpha.py).
from libc.stdint cimport int64_t

from sidprep.solver.core.records cimport Evaluation, Layout


cdef class GaState:
    """The state of the method: positions R (nb, 3), A (nb, 3, 3), Q (nq,), velocities u,
    accelerations ud, the alpha-lagged accelerations a (n,) and the kept multipliers lam (m,)."""
    cdef readonly double[:, ::1] R
    cdef readonly double[:, :, ::1] A
    cdef readonly double[::1] Q, u, ud, a, lam


cdef class GaConstants:
    """A run's constants: alpha_m, alpha_f, gamma, beta and beta' = beta (1 - alpha_f) / (1 - alpha_m);
    the integrated coordinates free and kept rows; length weights w (n,) m per unit; the system
    length (m); the bodies' deflection limits (nb,) m; the Newton tolerance tol; rtol (<= 0:
    fixed step); atol (m); the nominal step h_nominal (s); the output interval out_dt (s; <= 0:
    every step); projected: the velocities are projected after each step (rho_inf > RHO_PROJECTED)."""
    cdef readonly double alpha_m, alpha_f, gamma, beta, beta_p
    cdef readonly bint projected
    cdef readonly const int64_t[::1] free, kept
    cdef readonly const double[::1] w, limits
    cdef readonly double length, tol, rtol, atol, h_nominal, out_dt


cdef class GaWorkspace:
    """A run's workspace (made once per run): the Evaluations of the Newton iterate e and of the
    finite-difference columns e_col; the multipliers of all rows lam_all (m_all,); the Newton
    residuals r, r_col (free + kept,); the iteration matrix jac (LU-factorised in place, pivots piv); the
    damping-stiffness part D (free, free); the run's work integrals work (3,) = [applied loads,
    dissipated, drivers] (J) and power flows at its current state flows (4,) (W; NaN before the
    first step), carried from one call of ga_loop to the next; the force elements' bump-stop
    penetrations pen and rates rate (nfe,; m, m/s) at the current state, those at the end of the
    step on trial pen_new, rate_new, and the largest normal speed of each stop's contact speed
    (nfe,; m/s); the states cur, trial, old (the step's start before the last accepted step),
    col (finite-difference columns) and dense (an output sample), and scratch vectors."""
    cdef readonly Evaluation e, e_col
    cdef readonly double[::1] lam_all, r, r_col, dz
    cdef readonly double[:, ::1] jac, D
    cdef readonly int[::1] piv
    cdef readonly double[::1] work, flows, flows_new, work_old, work_k
    cdef readonly double[::1] pen, rate, pen_new, rate_new, speed
    cdef readonly GaState cur, trial, old, col, dense
    cdef readonly double[::1] dx, udt, u_o, ud_o, vec, conv


cdef class LoopStatus:
    """The loop's status, updated in place over the calls: counters, the step sizes taken (s), the
    status code (steps.pxd: RUNNING, FINISHED, MAX_STEPS, NEWTON_FAILED, LARGE_DEFORMATION), the
    step limit, and the body that left its small-deformation range with its deflection (m)."""
    cdef public long steps, rejected, newton_iterations, jacobians, code, max_steps, body
    cdef public double h_min, h_max, deflection


cdef void ga_state(Layout L, const double[::1] udn, GaState x, double h, GaConstants c, double[::1] dx,
                   GaState out) noexcept nogil
cdef void newton_residual(Evaluation e, const double[::1] udn, const double[::1] lamn, double h, GaConstants c,
                          double[::1] r) noexcept nogil
cdef void dense_state(Layout L, GaState x0, GaState x1, double h, double theta, GaWorkspace ws,
                      GaState out) noexcept nogil
cdef void state_flows(Layout L, Evaluation e, GaState x, const double[::1] lam_all, double mass_power,
                      double[::1] flows) noexcept nogil
cdef void iteration_matrix(Evaluation e, const double[:, ::1] D, const int64_t[::1] free, const int64_t[::1] kept,
                           double[:, ::1] jac) noexcept nogil
cdef double local_error(const double[::1] udn, const double[::1] an, GaState x, double h,
                        GaConstants c) noexcept nogil
cdef double approach_bound(GaWorkspace ws, double h) noexcept nogil
cdef (bint, double) contact_factor(GaWorkspace ws, double speed_floor) noexcept nogil
cdef bint contact_accepted(GaWorkspace ws) noexcept nogil
cdef bint deflection_check(Layout L, const double[::1] Q, GaConstants c, LoopStatus status) noexcept nogil
