"""The compiled kernels of the absolute-nodal beams: beam kinematics and elastic forces (eq. 3-10),
the drivers, the accelerations and the right-hand side, and the RK4 loop (the stages and their
combination of sidprep/solver/integrators/runge_kutta.py around this rhs, cached)."""

from __future__ import annotations

import math

import numpy as np

from sidprep.solver.equations.rotations import jit
from sidprep.solver.integrators.runge_kutta import rk4_combine, rk4_stage


@jit
def slope_weight(k, i, n, e):  # pragma: no cover - compiled
    """d theta_k / d w_y,i of the quadratic through node k and its neighbours (eq. 4-5), nodes 0..n-1."""
    if k == 0:
        c = (-3.0, 4.0, -1.0)
        j = i
    elif k == n - 1:
        c = (1.0, -4.0, 3.0)
        j = i - (n - 3)
    else:
        c = (-1.0, 0.0, 1.0)
        j = i - (k - 1)
    if j < 0 or j > 2:
        return 0.0
    return c[j] / (2.0 * e)


@jit
def _slope_stencil_start(k, n):  # pragma: no cover - compiled
    """First node of the three-node stencil of node k's slope."""
    if k == 0:
        return 0
    if k == n - 1:
        return n - 3
    return k - 1


@jit
def beam_kinematics(X, V, A, nodes, n, e):  # pragma: no cover - compiled
    """Chord angle and slopes of one beam with their first and second time derivatives.

    X, V, A (N, 2) node positions, velocities, accelerations; nodes (n,) its node numbers; e
    element length.  Returns phi, phid, phidd (rad, rad/s, rad/s^2) of the chord x_n - x_1 and
    theta, thetad, thetadd (n,) the slopes of the elastic deflection w_y (eq. 4-5, 11), the
    frame's turning included.
    """
    d0 = X[nodes[n - 1], 0] - X[nodes[0], 0]
    d1 = X[nodes[n - 1], 1] - X[nodes[0], 1]
    dd0 = V[nodes[n - 1], 0] - V[nodes[0], 0]
    dd1 = V[nodes[n - 1], 1] - V[nodes[0], 1]
    da0 = A[nodes[n - 1], 0] - A[nodes[0], 0]
    da1 = A[nodes[n - 1], 1] - A[nodes[0], 1]
    L2 = d0 * d0 + d1 * d1
    L = math.sqrt(L2)
    c0, c1 = d0 / L, d1 / L
    n0, n1 = -c1, c0
    phi = math.atan2(d1, d0)
    cr = d0 * dd1 - d1 * dd0
    phid = cr / L2
    phidd = (d0 * da1 - d1 * da0) / L2 - 2.0 * (d0 * dd0 + d1 * dd1) * cr / (L2 * L2)
    w = np.empty(n)
    wd = np.empty(n)
    wdd = np.empty(n)
    for k in range(n):
        r0, r1 = X[nodes[k], 0] - X[nodes[0], 0], X[nodes[k], 1] - X[nodes[0], 1]
        v0, v1 = V[nodes[k], 0] - V[nodes[0], 0], V[nodes[k], 1] - V[nodes[0], 1]
        a0, a1 = A[nodes[k], 0] - A[nodes[0], 0], A[nodes[k], 1] - A[nodes[0], 1]
        cr_k, nr_k, cv_k = c0 * r0 + c1 * r1, n0 * r0 + n1 * r1, c0 * v0 + c1 * v1
        w[k] = nr_k
        wd[k] = n0 * v0 + n1 * v1 - phid * cr_k
        wdd[k] = n0 * a0 + n1 * a1 - phidd * cr_k - 2.0 * phid * cv_k - phid * phid * nr_k
    theta = np.zeros(n)
    thetad = np.zeros(n)
    thetadd = np.zeros(n)
    for k in range(n):
        s = _slope_stencil_start(k, n)
        for i in range(s, s + 3):
            a = slope_weight(k, i, n, e)
            theta[k] += a * w[i]
            thetad[k] += a * wd[i]
            thetadd[k] += a * wdd[i]
    return phi, phid, phidd, theta, thetad, thetadd


@jit
def beam_elastic(X, nodes, n, e, Ke, Q):  # pragma: no cover - compiled
    """Add the elastic force -dV/dx of one beam to Q (N, 2) and return V = 1/2 u^T K u (J), eq. 6-10.

    u_k = (c . r_k - k e, n . r_k, theta_k), r_k = x_k - x_1, (c, n) the chord frame; K u is
    assembled element by element (Ke (6, 6)); dV/dx by the chain rule through w_x, w_y (slopes
    via the stencil weights) and the chord angle phi (d phi = n . d(x_n - x_1) / L).
    """
    d0 = X[nodes[n - 1], 0] - X[nodes[0], 0]
    d1 = X[nodes[n - 1], 1] - X[nodes[0], 1]
    L = math.sqrt(d0 * d0 + d1 * d1)
    c0, c1 = d0 / L, d1 / L
    n0, n1 = -c1, c0
    u = np.empty(3 * n)
    rc = np.empty(n)
    rn = np.empty(n)
    for k in range(n):
        r0, r1 = X[nodes[k], 0] - X[nodes[0], 0], X[nodes[k], 1] - X[nodes[0], 1]
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
    f = np.zeros(3 * n)
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
    gy = np.empty(n)
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
    Q[nodes[0], 0] += s0
    Q[nodes[0], 1] += s1
    Q[nodes[n - 1], 0] -= P * n0 / L
    Q[nodes[n - 1], 1] -= P * n1 / L
    Q[nodes[0], 0] += P * n0 / L
    Q[nodes[0], 1] += P * n1 / L
    return V


@jit
def driver_angle(t, psi0, speed, delta, duration):  # pragma: no cover - compiled
    """psi(t), psi'(t), psi''(t) of a driver (rest-to-rest cycloid over ``duration`` plus a constant speed)."""
    psi, psid, psidd = psi0 + speed * t, speed, 0.0
    if duration > 0.0 and delta != 0.0:
        tau = min(t / duration, 1.0)
        psi += delta * (tau - math.sin(2.0 * math.pi * tau) / (2.0 * math.pi))
        if tau < 1.0:
            psid += delta * (1.0 - math.cos(2.0 * math.pi * tau)) / duration
            psidd += delta * 2.0 * math.pi * math.sin(2.0 * math.pi * tau) / duration**2
    return psi, psid, psidd


@jit
def wrapped_angle(a):  # pragma: no cover - compiled
    return a - 2.0 * math.pi * math.floor((a + math.pi) / (2.0 * math.pi))


@jit
def driver_value(X, V, A, nodes, n, e, at_end):  # pragma: no cover - compiled
    """Tangent angle phi + theta at the driven end and its derivatives (beam_kinematics)."""
    phi, phid, phidd, th, thd, thdd = beam_kinematics(X, V, A, nodes, n, e)
    k = n - 1 if at_end else 0
    return phi + th[k], phid + thd[k], phidd + thdd[k]


@jit
def accelerations(t, y, params):  # pragma: no cover - compiled
    """Node accelerations A (N, 2), driver multipliers lam (nd,) (N m) and strain energy (J) at state y."""
    X0, free, Minv, f0, beam_nodes, beam_n, beam_e, beam_K, drv, alpha = params
    N, nf = X0.shape[0], free.shape[0]
    X = X0.copy()
    V = np.zeros((N, 2))
    for i in range(nf):
        X[free[i], 0], X[free[i], 1] = y[2 * i], y[2 * i + 1]
        V[free[i], 0], V[free[i], 1] = y[2 * nf + 2 * i], y[2 * nf + 2 * i + 1]
    Q = f0.copy()
    strain = 0.0
    for j in range(beam_n.shape[0]):
        strain += beam_elastic(X, beam_nodes[j], beam_n[j], beam_e[j], beam_K[j], Q)
    A = np.zeros((N, 2))
    for i in range(nf):
        a0, a1 = 0.0, 0.0
        for k in range(nf):
            a0 += Minv[i, k] * Q[free[k], 0]
            a1 += Minv[i, k] * Q[free[k], 1]
        A[free[i], 0], A[free[i], 1] = a0, a1
    nd = drv.shape[0]
    lam = np.zeros(nd)
    if nd > 0:
        # G a = rhs, G (nd, 2 nf) by differences of the driven tangent's acceleration (linear in A)
        G = np.zeros((nd, 2 * nf))
        rhs = np.zeros(nd)
        Z = np.zeros((N, 2))
        for r in range(nd):
            j, at_end = int(drv[r, 0]), drv[r, 1] > 0.5
            nodes, n, e = beam_nodes[j], beam_n[j], beam_e[j]
            val, vald, quad = driver_value(X, V, Z, nodes, n, e, at_end)
            psi, psid, psidd = driver_angle(t, drv[r, 2], drv[r, 3], drv[r, 4], drv[r, 5])
            err, errd = wrapped_angle(val - psi), vald - psid
            rhs[r] = psidd - quad - 2.0 * alpha * errd - alpha * alpha * err
            for i in range(nf):
                for c in range(2):
                    Z[free[i], c] = 1.0
                    _, _, unit = driver_value(X, V, Z, nodes, n, e, at_end)
                    Z[free[i], c] = 0.0
                    G[r, 2 * i + c] = unit - quad
        MG = np.zeros((2 * nf, nd))            # M^-1 G^T
        for r in range(nd):
            for i in range(nf):
                for k in range(nf):
                    MG[2 * i, r] += Minv[i, k] * G[r, 2 * k]
                    MG[2 * i + 1, r] += Minv[i, k] * G[r, 2 * k + 1]
        S = G @ MG
        res = rhs.copy()
        for r in range(nd):
            for i in range(nf):
                res[r] -= G[r, 2 * i] * A[free[i], 0] + G[r, 2 * i + 1] * A[free[i], 1]
        lam = np.linalg.solve(S, res)
        for i in range(nf):
            for r in range(nd):
                A[free[i], 0] += MG[2 * i, r] * lam[r]
                A[free[i], 1] += MG[2 * i + 1, r] * lam[r]
    return A, lam, strain


@jit
def rhs(t, y, params):  # pragma: no cover - compiled
    """y' of y = [free positions (2 nf), free velocities (2 nf)]: eq. 10 solved for x''."""
    free = params[1]
    nf = free.shape[0]
    A, _, _ = accelerations(t, y, params)
    yd = np.empty(4 * nf)
    yd[:2 * nf] = y[2 * nf:]
    for i in range(nf):
        yd[2 * nf + 2 * i], yd[2 * nf + 2 * i + 1] = A[free[i], 0], A[free[i], 1]
    return yd


@jit
def rk4_loop(t, y, t_stop, h, out_dt, next_out, params, capacity, steps):  # pragma: no cover - compiled
    """Classic RK4 steps of ``rhs`` from t (after ``steps`` steps of h from t = 0) to t_stop
    (the last step shortened to land on it) or until ``capacity`` samples, one sample on or
    after every multiple of out_dt (out_dt <= 0: every step) and at t_stop.  Returns t, y,
    next_out, the number of steps so far and the samples (times (k,), states (k, 4 nf))."""
    ts = np.empty(capacity)
    Ys = np.empty((capacity, y.shape[0]))
    ns = 0
    end_tol = 1e-12 * max(1.0, t_stop)
    while t < t_stop - end_tol:
        step = min(h, t_stop - t)
        half = 0.5 * step
        k1 = rhs(t, y, params)
        k2 = rhs(t + half, rk4_stage(y, half, k1), params)
        k3 = rhs(t + half, rk4_stage(y, half, k2), params)
        k4 = rhs(t + step, rk4_stage(y, step, k3), params)
        y = rk4_combine(y, step, k1, k2, k3, k4)
        steps += 1
        t = min((steps * h), t_stop) if step == h else t_stop
        final = t >= t_stop - end_tol
        if final or out_dt <= 0.0 or t >= next_out - 1e-12 * max(1.0, abs(t)):
            ts[ns] = t
            Ys[ns] = y
            ns += 1
            while out_dt > 0.0 and next_out <= t + 1e-12 * max(1.0, abs(t)):
                next_out += out_dt
        if ns == capacity:
            break
    return t, y, next_out, steps, ts[:ns], Ys[:ns]
