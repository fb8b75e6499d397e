"""The compiled kernels of the absolute-nodal beams (Kisu Lee): beam kinematics and elastic forces
(eq. 3-10), the drivers, the accelerations and the right-hand side, and the RK4 loop (the stages
and their combination of sidprep/solver/core/runge_kutta.pyx around this rhs).

``BeamSystem`` holds a model's constant arrays (sidprep/solver/absolute_nodal/assembly.py) and the
scratch of its right-hand side; its methods are the kernels' Python entries (one beam, one state).
"""

from libc.math cimport M_PI, atan2, cos, fabs, floor, sin, sqrt, NAN
from libc.stdint cimport int64_t
from scipy.linalg.cython_blas cimport dgemm
from scipy.linalg.cython_lapack cimport dgesv

import numpy as np

from sidprep.solver.core.runge_kutta cimport rk4_combine, rk4_stage

#: rows of a beam's scratch (BeamSystem.work): w, w', w'', theta, theta', theta'' of beam_kinematics;
#: u, f (3 rows each), r.c, r.n, the moments' w_y forces of beam_elastic
WORK_ROWS = 9


cdef class BeamSystem:
    """The kernels' record of an absolute-nodal model (``assembly.Assembly`` ``asm``) with the
    driver constraints' Baumgarte rate ``alpha`` (1/s)."""

    def __init__(self, asm, double alpha):
        self.X0 = np.array(asm.X0, dtype=np.float64, order="C")
        self.free = np.ascontiguousarray(asm.free, dtype=np.int64)
        self.Minv = np.ascontiguousarray(asm.Minv, dtype=np.float64)
        self.f0 = np.ascontiguousarray(asm.f0, dtype=np.float64)
        self.beam_nodes = np.ascontiguousarray(asm.beam_nodes, dtype=np.int64)
        self.beam_n = np.ascontiguousarray(asm.beam_n, dtype=np.int64)
        self.beam_e = np.ascontiguousarray(asm.beam_e, dtype=np.float64)
        self.beam_K = np.ascontiguousarray(asm.beam_K, dtype=np.float64)
        self.drv = np.ascontiguousarray(asm.drv, dtype=np.float64).reshape(-1, 6)
        self.alpha = alpha
        N, nf, nd = self.X0.shape[0], self.free.shape[0], self.drv.shape[0]
        self.X = np.array(self.X0)                   # the fixed nodes keep X0, the free ones are set per state
        self.V, self.A, self.Q, self.Z = (np.zeros((N, 2)) for _ in range(4))
        self.lam = np.zeros(nd)
        self.work = np.zeros((WORK_ROWS, self.beam_nodes.shape[1]))
        self.G, self.MG = np.zeros((nd, 2 * nf)), np.zeros((2 * nf, nd))
        self.S, self.LU = np.zeros((nd, nd)), np.zeros((nd, nd))
        self.res = np.zeros(nd)
        self.pivots = np.zeros(nd, dtype=np.intc)
        self.stages = np.zeros((5, 4 * nf))

    def accelerations(self, double t, const double[::1] y):
        """Node accelerations A (N, 2), driver multipliers (nd,) (N m) and strain energy (J) at state y."""
        strain = accelerations(self, t, y)
        return np.array(self.A), np.array(self.lam), strain

    def beam_elastic(self, const double[:, ::1] X, Py_ssize_t j, double[:, ::1] Q):
        """Add beam j's elastic force to Q (N, 2) at positions X (N, 2); its strain energy (J)."""
        return beam_elastic(X, self.beam_nodes[j], self.beam_n[j], self.beam_e[j], self.beam_K[j], Q, self.work)

    def beam_kinematics(self, const double[:, ::1] X, const double[:, ::1] V, const double[:, ::1] A, Py_ssize_t j):
        """phi, phid, phidd and theta, thetad, thetadd (n,) of beam j (``beam_kinematics``)."""
        n = self.beam_n[j]
        phi, phid, phidd = beam_kinematics(X, V, A, self.beam_nodes[j], n, self.beam_e[j], self.work)
        slopes = np.array(self.work[3:6, :n])
        return phi, phid, phidd, slopes[0], slopes[1], slopes[2]

    def driver_value(self, const double[:, ::1] X, const double[:, ::1] V, const double[:, ::1] A, Py_ssize_t j,
                     bint at_end):
        """Tangent angle of beam j at its driven end and its derivatives (``driver_value``)."""
        return driver_value(X, V, A, self.beam_nodes[j], self.beam_n[j], self.beam_e[j], at_end, self.work)


cdef class RK4Progress:
    """Where an RK4 run stands (``rk4_loop`` advances it): t (s), y (4 nf,) (a copy of the given
    state), the next output time (s) and the steps so far."""

    def __init__(self, double t, y, double next_out, Py_ssize_t steps):
        self.t, self.y, self.next_out, self.steps = t, np.array(y, dtype=np.float64), next_out, steps


cdef double slope_weight(Py_ssize_t k, Py_ssize_t i, Py_ssize_t n, double e) noexcept nogil:
    """d theta_k / d w_y,i of the quadratic through node k and its neighbours (eq. 4-5), nodes 0..n-1."""
    cdef Py_ssize_t j
    cdef double c0, c1, c2
    if k == 0:
        c0, c1, c2 = -3.0, 4.0, -1.0
        j = i
    elif k == n - 1:
        c0, c1, c2 = 1.0, -4.0, 3.0
        j = i - (n - 3)
    else:
        c0, c1, c2 = -1.0, 0.0, 1.0
        j = i - (k - 1)
    if j < 0 or j > 2:
        return 0.0
    return (c0 if j == 0 else (c1 if j == 1 else c2)) / (2.0 * e)


cdef Py_ssize_t _slope_stencil_start(Py_ssize_t k, Py_ssize_t n) noexcept nogil:
    """First node of the three-node stencil of node k's slope."""
    if k == 0:
        return 0
    if k == n - 1:
        return n - 3
    return k - 1


cdef (double, double, double) beam_kinematics(const double[:, ::1] X, const double[:, ::1] V, const double[:, ::1] A,
                                              const int64_t[::1] nodes, Py_ssize_t n, double e,
                                              double[:, ::1] work) noexcept nogil:
    """Chord angle and slopes of one beam with their first and second time derivatives.

    X, V, A (N, 2) node positions, velocities, accelerations; nodes (n,) its node numbers; e
    element length; work (>= 6, >= n) scratch.  Returns phi, phid, phidd (rad, rad/s, rad/s^2) of
    the chord x_n - x_1 and writes theta, thetad, thetadd (n,) into work rows 3, 4, 5: the slopes
    of the elastic deflection w_y (eq. 4-5, 11), the frame's turning included.
    """
    cdef int64_t first = nodes[0], last = nodes[n - 1], node
    cdef double d0 = X[last, 0] - X[first, 0]
    cdef double d1 = X[last, 1] - X[first, 1]
    cdef double dd0 = V[last, 0] - V[first, 0]
    cdef double dd1 = V[last, 1] - V[first, 1]
    cdef double da0 = A[last, 0] - A[first, 0]
    cdef double da1 = A[last, 1] - A[first, 1]
    cdef double L2 = d0 * d0 + d1 * d1
    cdef double L = sqrt(L2)
    cdef double c0 = d0 / L, c1 = d1 / L
    cdef double n0 = -c1, n1 = c0
    cdef double phi = atan2(d1, d0)
    cdef double cr = d0 * dd1 - d1 * dd0
    cdef double phid = cr / L2
    cdef double phidd = (d0 * da1 - d1 * da0) / L2 - 2.0 * (d0 * dd0 + d1 * dd1) * cr / (L2 * L2)
    cdef double r0, r1, v0, v1, a0, a1, cr_k, nr_k, cv_k, a
    cdef Py_ssize_t k, i, s
    for k in range(n):
        node = nodes[k]
        r0, r1 = X[node, 0] - X[first, 0], X[node, 1] - X[first, 1]
        v0, v1 = V[node, 0] - V[first, 0], V[node, 1] - V[first, 1]
        a0, a1 = A[node, 0] - A[first, 0], A[node, 1] - A[first, 1]
        cr_k, nr_k, cv_k = c0 * r0 + c1 * r1, n0 * r0 + n1 * r1, c0 * v0 + c1 * v1
        work[0, k] = nr_k
        work[1, k] = n0 * v0 + n1 * v1 - phid * cr_k
        work[2, k] = n0 * a0 + n1 * a1 - phidd * cr_k - 2.0 * phid * cv_k - phid * phid * nr_k
    for k in range(n):
        work[3, k] = 0.0
        work[4, k] = 0.0
        work[5, k] = 0.0
        s = _slope_stencil_start(k, n)
        for i in range(s, s + 3):
            a = slope_weight(k, i, n, e)
            work[3, k] += a * work[0, i]
            work[4, k] += a * work[1, i]
            work[5, k] += a * work[2, i]
    return phi, phid, phidd


cdef double beam_elastic(const double[:, ::1] X, const int64_t[::1] nodes, Py_ssize_t n, double e,
                         const double[:, ::1] Ke, double[:, ::1] Q, double[:, ::1] work) noexcept nogil:
    """Add the elastic force -dV/dx of one beam to Q (N, 2) and return V = 1/2 u^T K u (J), eq. 6-10.

    u_k = (c . r_k - k e, n . r_k, theta_k), r_k = x_k - x_1, (c, n) the chord frame; K u is
    assembled element by element (Ke (6, 6)); dV/dx by the chain rule through w_x, w_y (slopes
    via the stencil weights) and the chord angle phi (d phi = n . d(x_n - x_1) / L).  work
    (WORK_ROWS, >= n) scratch.
    """
    cdef Py_ssize_t width = work.shape[1]
    cdef double* u = &work[0, 0]                 # (3 n,) rows 0-2
    cdef double* f = &work[0, 0] + 3 * width     # (3 n,) rows 3-5
    cdef double* rc = &work[0, 0] + 6 * width
    cdef double* rn = &work[0, 0] + 7 * width
    cdef double* gy = &work[0, 0] + 8 * width
    cdef int64_t first = nodes[0], last = nodes[n - 1]
    cdef double d0 = X[last, 0] - X[first, 0]
    cdef double d1 = X[last, 1] - X[first, 1]
    cdef double L = sqrt(d0 * d0 + d1 * d1)
    cdef double c0 = d0 / L, c1 = d1 / L
    cdef double n0 = -c1, n1 = c0
    cdef double r0, r1, th, acc, V, P, s0, s1, F0, F1
    cdef Py_ssize_t k, i, s, el, o, a, b
    for k in range(n):
        r0, r1 = X[nodes[k], 0] - X[first, 0], X[nodes[k], 1] - X[first, 1]
        rc[k] = c0 * r0 + c1 * r1
        rn[k] = n0 * r0 + n1 * r1
        u[3 * k] = rc[k] - k * e
        u[3 * k + 1] = rn[k]
    for k in range(n):
        s = _slope_stencil_start(k, n)
        th = 0.0
        for i in range(s, s + 3):
            th += slope_weight(k, i, n, e) * rn[i]
        u[3 * k + 2] = th
    for a in range(3 * n):
        f[a] = 0.0
    for el in range(n - 1):
        o = 3 * el
        for a in range(6):
            acc = 0.0
            for b in range(6):
                acc += Ke[a, b] * u[o + b]
            f[o + a] += acc
    V = 0.0
    for a in range(3 * n):
        V += 0.5 * u[a] * f[a]
    for k in range(n):
        gy[k] = f[3 * k + 1]
    for k in range(n):                       # moments act on w_y through the slope stencils
        s = _slope_stencil_start(k, n)
        for i in range(s, s + 3):
            gy[i] += slope_weight(k, i, n, e) * f[3 * k + 2]
    P = 0.0                                  # dV/dphi at fixed r_k
    s0 = 0.0
    s1 = 0.0
    for k in range(1, n):
        F0 = f[3 * k] * c0 + gy[k] * n0
        F1 = f[3 * k] * c1 + gy[k] * n1
        Q[nodes[k], 0] -= F0
        Q[nodes[k], 1] -= F1
        s0 += F0
        s1 += F1
        P += f[3 * k] * rn[k] - gy[k] * rc[k]
    Q[first, 0] += s0
    Q[first, 1] += s1
    Q[last, 0] -= P * n0 / L
    Q[last, 1] -= P * n1 / L
    Q[first, 0] += P * n0 / L
    Q[first, 1] += P * n1 / L
    return V


cpdef (double, double, double) driver_angle(double t, double psi0, double speed, double delta,
                                            double duration) noexcept nogil:
    """psi(t), psi'(t), psi''(t) of a driver (rest-to-rest cycloid over ``duration`` plus a constant speed)."""
    cdef double psi = psi0 + speed * t, psid = speed, psidd = 0.0, tau
    if duration > 0.0 and delta != 0.0:
        tau = t / duration
        if 1.0 < tau:
            tau = 1.0
        psi += delta * (tau - sin(2.0 * M_PI * tau) / (2.0 * M_PI))
        if tau < 1.0:
            psid += delta * (1.0 - cos(2.0 * M_PI * tau)) / duration
            psidd += delta * 2.0 * M_PI * sin(2.0 * M_PI * tau) / (duration * duration)
    return psi, psid, psidd


cpdef double wrapped_angle(double a) noexcept nogil:
    """a (rad) wrapped into [-pi, pi)."""
    return a - 2.0 * M_PI * floor((a + M_PI) / (2.0 * M_PI))


cdef (double, double, double) driver_value(const double[:, ::1] X, const double[:, ::1] V, const double[:, ::1] A,
                                           const int64_t[::1] nodes, Py_ssize_t n, double e, bint at_end,
                                           double[:, ::1] work) noexcept nogil:
    """Tangent angle phi + theta at the driven end and its derivatives (beam_kinematics; work its scratch)."""
    cdef double phi, phid, phidd
    phi, phid, phidd = beam_kinematics(X, V, A, nodes, n, e, work)
    cdef Py_ssize_t k = n - 1 if at_end else 0
    return phi + work[3, k], phid + work[4, k], phidd + work[5, k]


cdef void driver_multipliers(BeamSystem s, double t) noexcept nogil:
    """Add the drivers' constraint accelerations to s.A and write their multipliers s.lam (N m):
    G a = rhs (Baumgarte), G (nd, 2 nf) by differences of the driven tangent's acceleration
    (linear in A), lam = (G M^-1 G^T)^-1 (rhs - G a), a += M^-1 G^T lam.  A singular
    G M^-1 G^T gives NaN multipliers and accelerations."""
    cdef Py_ssize_t nd = s.drv.shape[0], nf = s.free.shape[0], r, i, k, c, j, n
    cdef double val, vald, quad, psi, psid, psidd, err, errd, unit, e
    cdef bint at_end
    cdef int m = <int>nd, kk = <int>(2 * nf), one = 1, info = 0
    cdef double alpha_one = 1.0, beta_zero = 0.0
    for r in range(nd):
        j = <Py_ssize_t>s.drv[r, 0]
        at_end = s.drv[r, 1] > 0.5
        n, e = s.beam_n[j], s.beam_e[j]
        val, vald, quad = driver_value(s.X, s.V, s.Z, s.beam_nodes[j], n, e, at_end, s.work)
        psi, psid, psidd = driver_angle(t, s.drv[r, 2], s.drv[r, 3], s.drv[r, 4], s.drv[r, 5])
        err, errd = wrapped_angle(val - psi), vald - psid
        s.res[r] = psidd - quad - 2.0 * s.alpha * errd - s.alpha * s.alpha * err
        for i in range(nf):
            for c in range(2):
                s.Z[s.free[i], c] = 1.0
                unit = driver_value(s.X, s.V, s.Z, s.beam_nodes[j], n, e, at_end, s.work)[2]
                s.Z[s.free[i], c] = 0.0
                s.G[r, 2 * i + c] = unit - quad
    for r in range(nd):                      # MG = M^-1 G^T
        for i in range(nf):
            s.MG[2 * i, r] = 0.0
            s.MG[2 * i + 1, r] = 0.0
    for r in range(nd):
        for i in range(nf):
            for k in range(nf):
                s.MG[2 * i, r] += s.Minv[i, k] * s.G[r, 2 * k]
                s.MG[2 * i + 1, r] += s.Minv[i, k] * s.G[r, 2 * k + 1]
    # S = G MG by BLAS as numpy's matmul of C-ordered arrays: S^T = MG^T G^T in column order
    if kk > 0:
        dgemm("n", "n", &m, &m, &kk, &alpha_one, &s.MG[0, 0], &m, &s.G[0, 0], &kk, &beta_zero, &s.S[0, 0], &m)
    for r in range(nd):
        for i in range(nf):
            s.res[r] -= s.G[r, 2 * i] * s.A[s.free[i], 0] + s.G[r, 2 * i + 1] * s.A[s.free[i], 1]
        s.lam[r] = s.res[r]
        for c in range(nd):
            s.LU[c, r] = s.S[r, c]           # column order for LAPACK
    dgesv(&m, &one, &s.LU[0, 0], &m, &s.pivots[0], &s.lam[0], &m, &info)
    if info != 0:
        for r in range(nd):
            s.lam[r] = NAN
    for i in range(nf):
        for r in range(nd):
            s.A[s.free[i], 0] += s.MG[2 * i, r] * s.lam[r]
            s.A[s.free[i], 1] += s.MG[2 * i + 1, r] * s.lam[r]


cdef double accelerations(BeamSystem s, double t, const double[::1] y) noexcept nogil:
    """Node accelerations s.A (N, 2), driver multipliers s.lam (nd,) (N m) at state y; returns the
    strain energy (J).  Also sets s.X, s.V (the state's node positions and velocities)."""
    cdef Py_ssize_t N = s.X0.shape[0], nf = s.free.shape[0], i, k, j
    cdef double strain = 0.0, a0, a1
    for i in range(nf):
        s.X[s.free[i], 0], s.X[s.free[i], 1] = y[2 * i], y[2 * i + 1]
        s.V[s.free[i], 0], s.V[s.free[i], 1] = y[2 * nf + 2 * i], y[2 * nf + 2 * i + 1]
    for i in range(N):
        s.Q[i, 0], s.Q[i, 1] = s.f0[i, 0], s.f0[i, 1]
        s.A[i, 0], s.A[i, 1] = 0.0, 0.0
    for j in range(s.beam_n.shape[0]):
        strain += beam_elastic(s.X, s.beam_nodes[j], s.beam_n[j], s.beam_e[j], s.beam_K[j], s.Q, s.work)
    for i in range(nf):
        a0, a1 = 0.0, 0.0
        for k in range(nf):
            a0 += s.Minv[i, k] * s.Q[s.free[k], 0]
            a1 += s.Minv[i, k] * s.Q[s.free[k], 1]
        s.A[s.free[i], 0], s.A[s.free[i], 1] = a0, a1
    if s.drv.shape[0] > 0:
        driver_multipliers(s, t)
    return strain


cdef void rhs(BeamSystem s, double t, const double[::1] y, double[::1] yd) noexcept nogil:
    """y' (4 nf,) of y = [free positions (2 nf), free velocities (2 nf)]: eq. 10 solved for x''."""
    cdef Py_ssize_t nf = s.free.shape[0], i
    accelerations(s, t, y)
    for i in range(2 * nf):
        yd[i] = y[2 * nf + i]
    for i in range(nf):
        yd[2 * nf + 2 * i], yd[2 * nf + 2 * i + 1] = s.A[s.free[i], 0], s.A[s.free[i], 1]


def rk4_loop(BeamSystem s, RK4Progress p, double t_stop, double h, double out_dt, Py_ssize_t capacity):
    """Classic RK4 steps of ``rhs`` from p.t (after p.steps steps of h from t = 0) to t_stop (the
    last step shortened to land on it) or until ``capacity`` samples, one sample on or after
    every multiple of out_dt (out_dt <= 0: every step) and at t_stop; p advanced in place.
    Returns the samples: times (k,) s, states (k, 4 nf)."""
    cdef Py_ssize_t ny = p.y.shape[0], ns = 0, steps = p.steps, i
    ts_array, Ys_array = np.empty(capacity), np.empty((capacity, ny))
    cdef double[::1] ts = ts_array
    cdef double[:, ::1] Ys = Ys_array
    cdef double[::1] y = p.y
    cdef double[::1] k1 = s.stages[0], k2 = s.stages[1], k3 = s.stages[2], k4 = s.stages[3], arg = s.stages[4]
    cdef double t = p.t, next_out = p.next_out, step, half
    cdef double end_tol = 1e-12 * (t_stop if t_stop > 1.0 else 1.0)
    cdef bint final
    with nogil:
        while t < t_stop - end_tol:
            step = t_stop - t if t_stop - t < h else h
            half = 0.5 * step
            rhs(s, t, y, k1)
            rk4_stage(y, half, k1, arg)
            rhs(s, t + half, arg, k2)
            rk4_stage(y, half, k2, arg)
            rhs(s, t + half, arg, k3)
            rk4_stage(y, step, k3, arg)
            rhs(s, t + step, arg, k4)
            rk4_combine(y, step, k1, k2, k3, k4, arg)
            y[:] = arg
            steps += 1
            if step == h:
                t = steps * h
                if t_stop < t:
                    t = t_stop
            else:
                t = t_stop
            final = t >= t_stop - end_tol
            if final or out_dt <= 0.0 or t >= next_out - 1e-12 * _at_least_one(fabs(t)):
                ts[ns] = t
                Ys[ns, :] = y
                ns += 1
                while out_dt > 0.0 and next_out <= t + 1e-12 * _at_least_one(fabs(t)):
                    next_out += out_dt
            if ns == capacity:
                break
    p.t, p.next_out, p.steps = t, next_out, steps
    return ts_array[:ns], Ys_array[:ns]


cdef inline double _at_least_one(double x) noexcept nogil:
    """max(1, x)."""
    return x if x > 1.0 else 1.0
