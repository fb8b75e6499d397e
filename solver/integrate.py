"""Time integration of the constrained FFR equations (system.py docstring).

* ``genalpha`` (default): Lie-group generalised-alpha of Arnold & Bruls (2007) / Bruls, Cardona
  & Arnold (2012) for the index-3 DAE, on R^3 x SO(3) x R^nq per body:

      x_{n+1} = x_n (+) h dx,  dx = u_n + h (1/2 - beta) a_n + h beta a_{n+1}
      u_{n+1} = u_n + h (1 - gamma) a_n + h gamma a_{n+1}
      (1 - alpha_m) a_{n+1} + alpha_m a_n = (1 - alpha_f) ud_{n+1} + alpha_f ud_n
      M ud_{n+1} - f + B_F^T lambda = 0,   g(x_{n+1}, t_{n+1}) / (h^2 beta') = 0

  (Chung-Hulbert parameters from rho_inf; beta' = beta (1-alpha_f)/(1-alpha_m) scales the
  constraint rows so that the iteration matrix is O(1)).  Unknowns ud_{n+1}, lambda; modified
  Newton with a finite-difference iteration matrix (exact tangent operator of the update)
  re-used over steps until convergence slows.  Local error estimate
  e = h^2 |beta - 1/6| |ud_{n+1} - ud_n| (Geradin & Cardona) drives the optional step-size
  control.  Constraints hold at position level exactly (no drift).
* ``rk45`` / ``dop853``: explicit scipy ``solve_ivp`` on the index-1 ODE with quaternions and
  Baumgarte stabilisation, for non-stiff scenes.

Consistent initial conditions: Gauss-Newton projection of the positions onto g = 0, removal of
redundant constraint rows, mass-weighted projection of the velocities onto g_dot = 0, then the
index-1 accelerations and multipliers; optional quasi-static elastic start.
"""

from __future__ import annotations

import time

import numpy as np

from sidprep.errors import InputError

from sidprep.solver.bodies import RigidBody
from sidprep.solver.effects import EFFECTS, build_report, choose_effects, estimate_sizes, parse_effects
from sidprep.solver.kinematics import exp_so3, jit, matrix_to_quaternion, quaternion_rate, quaternion_to_matrix
from sidprep.solver.system import REDUNDANCY_TOL, BodyHistory, Context, JointHistory, Pose, Result, _Kernel, _system_kernel

#: Gauss-Newton tolerance of the initial position projection (constraint residual, m or rad)
POSITION_TOL = 1e-12
#: maximum Newton iterations of one generalised-alpha step before the iteration matrix is renewed
MAX_NEWTON = 6
#: contraction factor above which the iteration matrix is renewed
SLOW_CONTRACTION = 0.3
#: fixed-step mode: successful steps after a step cut before the step is doubled again
RECOVER_STEPS = 4
#: step-size factor limits of the error control
H_GROW, H_SHRINK, SAFETY = 2.0, 0.2, 0.9
#: output samples per call of the compiled integration loop (it resumes until t_end)
CHUNK = 4096
#: planar detection: relative size below which an out-of-plane coupling counts as zero (the
#: couplings that FE-mesh asymmetry leaves in nominally planar modes are ~1e-4 of the mode)
PLANAR_TOL = 1e-3
#: planar detection: tolerance of the geometry (parallel joint axes, plane normal along a
#: coordinate axis, gravity and initial velocities in the plane), relative
PLANAR_AXIS_TOL = 1e-9
#: planar detection: random in-plane test states, at times evenly spread over [0, t_end],
#: checked against the full 3D equations (time-dependent loads)
PLANAR_SAMPLES = 8
#: planar detection: size of the random in-plane test displacements, in system lengths L
PLANAR_MOTION = 1e-4


# ---------------------------------------------------------------------------- set-up helpers
def genalpha_parameters(rho_inf: float) -> tuple[float, float, float, float]:
    """(alpha_m, alpha_f, gamma, beta) of Chung & Hulbert (1993) for spectral radius rho_inf."""
    if not 0.0 <= rho_inf <= 1.0:
        raise ValueError(f"rho_inf must be in [0, 1], got {rho_inf}")
    am = (2 * rho_inf - 1) / (rho_inf + 1)
    af = rho_inf / (rho_inf + 1)
    gamma = 0.5 + af - am
    return am, af, gamma, 0.25 * (gamma + 0.5) ** 2


def length_weights(system) -> tuple[np.ndarray, float]:
    """Per-coordinate factors converting coordinate errors to lengths, and the system length L.

    Translations 1, rotations L, modal coordinate k: max over SID nodes of |Phi_n[:, k]|, at
    least the mass-weighted RMS displacement sqrt(Me_kk / m) of the mode (e.g. when the only
    SID node is a clamped interface where all modes vanish).
    """
    radii = [1e-3]
    for b in system.bodies:
        model = b.model
        radii.append(float(np.sqrt(np.trace(model.I0) / (2 * model.mass))))
        radii += [float(np.linalg.norm(m.position)) for m in b.markers]
    length = max(radii)
    w = np.ones(system.n)
    for i, b in enumerate(system.bodies):
        sl = system._slices[i]
        w[sl][3:6] = length
        if b.nq:
            rms = np.sqrt(np.abs(np.diag(b.model.Me)) / b.model.mass)
            phi = np.array([np.linalg.norm(n.phi.M0, axis=0) for n in b.sid.nodes] + [rms]).max(axis=0)
            w[sl.start + 6:sl.stop] = np.maximum(phi, 1e-300)
    return w, length


def configure_effects(system, spec) -> dict:
    """Resolve and switch the effects of every body; returns {name: (body, chosen, reasons)}."""
    parsed = parse_effects(spec)
    gravity_on = parsed == "auto" or "gravity" in parsed
    choices = {}
    for b in system.bodies:
        if isinstance(b, RigidBody):
            b.configure(set(EFFECTS), gravity=gravity_on and bool(np.any(system.gravity)))
            continue
        own = parse_effects(b.effects) if b.effects is not None else parsed
        chosen, reasons = choose_effects(system, b, own)
        b.configure(chosen, gravity="gravity" in chosen)
        choices[b.name] = (b, chosen, reasons)
    return choices


def independent_rows(B: np.ndarray, tol: float = REDUNDANCY_TOL) -> np.ndarray:
    """Boolean mask of the rows of B kept by Gram-Schmidt in order (earlier rows win)."""
    kept = np.zeros(B.shape[0], bool)
    basis: list[np.ndarray] = []
    for i, row in enumerate(B):
        norm = np.linalg.norm(row)
        if norm == 0.0:
            continue
        v = row.copy()
        for e in basis:
            v -= (e @ v) * e
        for e in basis:  # second pass for orthogonality
            v -= (e @ v) * e
        rn = np.linalg.norm(v)
        if rn > tol * norm:
            basis.append(v / rn)
            kept[i] = True
    return kept


def rigid_columns(system) -> np.ndarray:
    """Boolean mask of the rigid-body coordinates (6 per body) among the n velocities."""
    rigid = np.zeros(system.n, bool)
    for sl in system._slices:
        rigid[sl.start:sl.start + 6] = True
    return rigid


def project_positions(system, pose: Pose, t: float, rigid_only: bool = False) -> Pose:
    """Minimum-norm Gauss-Newton projection onto g(x, t) = 0 (kept rows).

    rigid_only moves the rigid-body coordinates only (keeps q); if that cannot satisfy the
    constraints (e.g. a body clamped at two nodes) the modal coordinates are moved as well.
    """
    cols = rigid_columns(system) if rigid_only else np.ones(system.n, bool)
    for _ in range(50):
        ctx = Context(system, pose, np.zeros(system.n), t, None)
        g, B, _, _ = system.constraint_rows(ctx, force_rows=False)
        k = system.kept
        if g[k].size == 0 or np.max(np.abs(g[k])) < POSITION_TOL:
            return pose
        delta = np.zeros(system.n)
        delta[cols] = np.linalg.lstsq(B[k][:, cols], -g[k], rcond=None)[0]
        pose = system.advance(pose, delta)
    if rigid_only:
        return project_positions(system, pose, t)
    worst = int(np.flatnonzero(k)[np.argmax(np.abs(g[k]))])
    name = next(c.name for c in system.constraints if system._row_slices[id(c)].start <= worst
                < system._row_slices[id(c)].stop)
    raise InputError(f"joint '{name}': the initial positions cannot satisfy it (residual "
                     f"{np.max(np.abs(g[k])):.3g} m or rad); place its markers so that they coincide and "
                     "their z axes align as the joint requires")


def solve_kkt(mass, rhs_f, B, BF, rhs_g):
    """[M B_F^T; B 0] [ud; lambda] = [f; rhs_g]."""
    n, m = mass.shape[0], B.shape[0]
    if m == 0:
        return np.linalg.solve(mass, rhs_f), np.zeros(0)
    kkt = np.zeros((n + m, n + m))
    kkt[:n, :n] = mass
    kkt[:n, n:] = BF.T
    kkt[n:, :n] = B
    sol = np.linalg.solve(kkt, np.concatenate([rhs_f, rhs_g]))
    return sol[:n], sol[n:]


def accelerations(system, pose: Pose, u: np.ndarray, t: float, lam=None, iterations: int = 3, free=None):
    """Index-1 accelerations and multipliers (iterated when forces depend on lambda, friction);
    with ``free`` (coordinate indices) the other accelerations are zero (planar scenes)."""
    gam = system.gamma(pose, u, t)
    free = np.arange(system.n) if free is None else free
    ud = np.zeros(system.n)
    for _ in range(iterations if system.m_all else 1):
        mass, f, _, B, BF, _ = system.evaluate(pose, u, t, lam)
        ud[free], lam = solve_kkt(mass[np.ix_(free, free)], f[free], B[:, free], BF[:, free], -gam)
    return ud, lam


def project_velocities(system, pose: Pose, u: np.ndarray, t: float) -> np.ndarray:
    """u corrected onto B u + b_t = 0, changing the rigid-body velocities only where possible.

    Minimum-norm correction over the rigid-body columns (rotations weighted by the system
    length L), so that the given modal velocities stay (a body driven at speed starts spinning
    undeformed, not with the elastic velocities of an impulsive start).  When the rigid columns
    cannot satisfy the constraints, the mass-weighted projection over all coordinates is used.
    """
    if not system.kept.any():
        return u
    err = system.velocity_constraint(pose, u, t)
    ctx = Context(system, pose, u, t, None)
    B = system.constraint_rows(ctx, force_rows=False)[1][system.kept]
    rigid = rigid_columns(system)
    scale = 1.0 / length_weights(system)[0][rigid]
    du = np.zeros(system.n)
    du[rigid] = scale * np.linalg.lstsq(B[:, rigid] * scale, -err, rcond=None)[0]
    if np.max(np.abs(system.velocity_constraint(pose, u + du, t)), initial=0.0) <= POSITION_TOL * (
            1.0 + np.max(np.abs(u))):
        return u + du
    mass, _, _, B, _, _ = system.evaluate(pose, u, t)
    return u + solve_kkt(mass, np.zeros(system.n), B, B, -err)[0]


def quasi_static_elastic(system, pose: Pose, u: np.ndarray, t: float, iterations: int = 10) -> Pose:
    """Modal coordinates with q_ddot = 0 under the initial loads and rigid-body accelerations.

    Gauss-Newton on F(q) = q_ddot(q) (index-1 accelerations; for every q the rigid coordinates
    are re-projected onto the constraints).  Where joints at nodes pin combinations of q, the
    perturbations are projected too: the columns D of actually reachable changes give the
    reduced system (D^T dF) c = -D^T F, solved in the least-squares sense.
    """
    flex = [(i, system._slices[i]) for i, b in enumerate(system.bodies) if b.nq]
    if not flex:
        return pose

    def modal(p, vec=None):
        if vec is None:
            vec = accelerations(system, p, u, t)[0]
        return np.concatenate([vec[sl][6:] if vec.size == system.n else p.q[i] for i, sl in flex])

    def with_q(p, qvec):
        p = p.copy()
        k = 0
        for i, sl in flex:
            nq = sl.stop - sl.start - 6
            p.q[i] = qvec[k:k + nq].copy()
            k += nq
        return project_positions(system, p, t, rigid_only=True)

    def q_of(p):
        return np.concatenate([p.q[i] for i, _ in flex])

    weights, length = length_weights(system)
    scale = np.concatenate([length / weights[sl][6:] for _, sl in flex])  # q moving nodes by L
    for _ in range(iterations):
        q = q_of(pose)
        f0 = modal(pose)
        dmat = np.empty((q.size, q.size))
        dfun = np.empty((q.size, q.size))
        for k in range(q.size):
            trial = q.copy()
            trial[k] += 1e-6 * max(scale[k], abs(q[k]))
            pk = with_q(pose, trial)
            dmat[:, k] = q_of(pk) - q
            dfun[:, k] = modal(pk) - f0
        c = np.linalg.lstsq(dmat.T @ dfun, -dmat.T @ f0, rcond=1e-10)[0]
        step = dmat @ c
        pose = with_q(pose, q + step)
        if np.max(np.abs(step) / np.maximum(np.abs(q + step), scale * 1e-9)) < 1e-8:
            break
    return pose


def consistent_initial_state(system, static_start: bool):
    """(pose, u, ud, lambda) satisfying the constraints at position, velocity, acceleration level."""
    pose, u = system.initial_pose()
    pose = project_positions(system, pose, 0.0, rigid_only=True)
    ctx = Context(system, pose, u, 0.0, None)
    for element in system.forces:  # defaults that depend on the assembled start (spring lengths)
        if hasattr(element, "at_start"):
            element.at_start(ctx)
    _, B, _, _ = system.constraint_rows(ctx, force_rows=False)
    system.kept = independent_rows(B)
    system.accept(pose)
    if static_start:
        pose = quasi_static_elastic(system, pose, project_velocities(system, pose, u, 0.0), 0.0)
    u = project_velocities(system, pose, u, 0.0)
    ud, lam = accelerations(system, pose, u, 0.0)
    return pose, u, ud, lam


# ---------------------------------------------------------------------------- planar scenes
def _plane_normal(system, pose) -> np.ndarray | None:
    """Common unit normal (inertial) of the joint axes: revolute / cylindrical z, planar-joint
    normal; prismatic axes must lie in the plane.  None without such a joint or if they differ."""
    ctx = Context(system, pose, np.zeros(system.n), 0.0, None)

    def axes(kinds):
        return [ctx.kin(j.marker1)[1][:, 2] for j in system.joints if j.kind in kinds]

    normals, slides = axes(("revolute", "cylindrical", "planar")), axes(("prismatic",))
    if not normals:
        return None
    n = normals[0]
    if any(np.linalg.norm(np.cross(n, z)) > PLANAR_AXIS_TOL for z in normals) or any(abs(n @ z) > PLANAR_AXIS_TOL
                                                                                  for z in slides):
        return None
    return n


def _out_of_plane_modes(body, axis: int, length: float) -> np.ndarray:
    """Mask (nq,) of modes that in-plane motion (rotation about K axis ``axis``, translation and
    marker loads in the plane) does not excite, up to PLANAR_TOL of each mode's own size: no
    coupling with the in-plane rigid motion (Ct0 vs sqrt(m Me_kk), Cr0 vs sqrt(tr J Me_kk)), no
    centrifugal load Oe0 w_hat for w along the axis (vs sqrt(tr J Me_kk)), no in-plane motion
    of any marker ([phi; L psi] column of the mode)."""
    model = body.model
    ip = [a for a in range(3) if a != axis]
    me = np.sqrt(np.abs(np.diag(model.Me)))
    inertia = np.sqrt(np.trace(model.I0))
    out = np.ones(body.nq, bool)
    if model.Ct0.size:
        out &= np.all(np.abs(model.Ct0[:, ip]) <= PLANAR_TOL * np.sqrt(model.mass) * me[:, None], axis=1)
        out &= np.abs(model.Cr0[:, axis]) <= PLANAR_TOL * inertia * me
    if model.Oe0 is not None:
        out &= np.abs(model.Oe0[:, axis]) <= PLANAR_TOL * inertia * me
    for mk in body.markers:
        if mk.phi is not None:
            size = np.maximum(np.linalg.norm(np.vstack([mk.phi, length * mk.psi]), axis=0), 1e-300)
            inplane = np.vstack([mk.phi[ip], length * mk.psi[axis]])
            out &= np.all(np.abs(inplane) <= PLANAR_TOL * size, axis=0)
    return out


def planar_coordinates(system, pose, u, t_end: float = 0.0):
    """(free coordinate indices, kept-row mask, note) when the scene moves in one plane, else None.

    Planar: the revolute / cylindrical / planar joint axes share one normal n along an inertial
    axis and along a body axis of every body, gravity and the initial velocities lie in the
    plane, and the out-of-plane coordinates O (translation along n, the two tilts, the modes
    that in-plane motion does not excite) start at zero (modes: within PLANAR_TOL of the
    largest modal deflection; they are then set to zero in ``pose``).  The decoupling is then
    verified on the full 3D equations at random in-plane states, at PLANAR_SAMPLES times evenly
    spread over [0, t_end]: every constraint row acts either on in-plane coordinates or on O
    only, and the O-rows of the equations of motion (mass couplings, forces, reactions of the
    in-plane rows) are balanced by reactions of the O-only rows, so that O stays zero.  Only the in-plane coordinates are
    integrated; the O-only rows are dropped (their reactions are recovered at the output
    samples, ``out_of_plane_reactions``).
    """
    if not system.bodies:
        return None
    n = _plane_normal(system, pose)
    if n is None or abs(system.gravity @ n) > PLANAR_AXIS_TOL * max(np.linalg.norm(system.gravity), 1.0):
        return None
    ax = int(np.argmax(np.abs(n)))
    if abs(abs(n[ax]) - 1.0) > PLANAR_AXIS_TOL:
        return None
    weights, length = length_weights(system)
    free = np.zeros(system.n, bool)
    for i, b in enumerate(system.bodies):
        nk = pose.A[i].T @ n
        axk = int(np.argmax(np.abs(nk)))
        if abs(abs(nk[axk]) - 1.0) > PLANAR_AXIS_TOL:
            return None
        sl = system._slices[i]
        idx = np.arange(sl.start, sl.stop)
        free[idx[[a for a in range(3) if a != ax]]] = True
        free[idx[3 + axk]] = True
        if b.nq:
            free[idx[6:]] = ~_out_of_plane_modes(b, axk, length)
            deflection = np.abs(pose.q[i]) * weights[idx[6:]]  # node motion of each mode, m
            if np.any(deflection[~free[idx[6:]]] > PLANAR_TOL * max(np.max(deflection), PLANAR_AXIS_TOL * length)):
                return None
    out = ~free
    scale = max(np.max(np.abs(u)), 1e-300)
    if np.any(np.abs(u[out]) > PLANAR_AXIS_TOL * scale):
        return None
    rng = np.random.default_rng(0)
    rows = None
    for t in np.linspace(0.0, t_end, PLANAR_SAMPLES):
        trial = system.advance(pose, np.where(free, PLANAR_MOTION * length * rng.standard_normal(system.n)
                                             / weights, 0.0))
        vel = np.where(free, u + rng.standard_normal(system.n) / weights, 0.0)
        mass, f, _, B, _, _ = system.evaluate(trial, vel, t)
        inplane = np.linalg.norm(B[:, free], axis=1) > PLANAR_TOL * np.linalg.norm(B, axis=1)
        if rows is not None and np.any(rows != inplane):
            return None
        rows = inplane
        acc = np.where(free, rng.standard_normal(system.n) / weights, 0.0)
        lam = rng.standard_normal(B.shape[0]) * np.where(inplane, 1.0, 0.0)
        load = mass @ acc - f + B.T @ lam        # out-of-plane rows: must be reactions of out rows
        scale = np.abs(mass @ acc) + np.abs(f) + np.abs(B.T) @ np.abs(lam)
        if not np.all(np.isfinite(scale)):
            return None
        b_out = B[~inplane][:, out]
        react = np.linalg.lstsq(b_out.T, -load[out], rcond=None)[0] if b_out.size else np.zeros(0)
        if np.any(np.abs(load[out] + b_out.T @ react) > PLANAR_TOL * np.max(scale)):
            return None
    keep = system.kept.copy()
    keep[keep] = rows
    for i, sl in enumerate(system._slices):  # out-of-plane modes at coupling round-off (static start)
        pose.q[i][~free[sl][6:]] = 0.0
    names = "xyz"
    modes = [f"{b.name}: {int(np.sum(free[sl][6:]))} of {b.nq} modes" for b, sl in zip(system.bodies, system._slices)
             if b.nq]
    note = (f"planar scene (normal {names[ax]}): integrated {int(free.sum())} of {system.n} coordinates, the "
            f"in-plane translations, the rotation about {names[ax]}" + (" and the in-plane modes (" + ", ".join(modes)
                                                                     + ")" if modes else ""))
    return np.flatnonzero(free), keep, note


def out_of_plane_reactions(system, pose, u, ud, t, lam):
    """Multipliers of all rows kept in 3D (system.kept_3d) from those of a planar run: the
    reactions of the dropped out-of-plane rows balance the out-of-plane equations of motion
    (least squares over the out-of-plane coordinates, planar_coordinates)."""
    planar_rows = system.kept[system.kept_3d]
    out = np.ones(system.n, bool)
    out[system.free] = False
    kept, system.kept = system.kept, system.kept_3d
    try:
        mass, f, _, _, BF, _ = system.evaluate(pose, u, t)
    finally:
        system.kept = kept
    load = mass @ ud - f + BF[planar_rows].T @ lam
    full = np.zeros(planar_rows.size)
    full[planar_rows] = lam
    full[~planar_rows] = np.linalg.lstsq(BF[~planar_rows][:, out].T, -load[out], rcond=None)[0]
    return full


# ---------------------------------------------------------------------------- generalised alpha
class _Recorder:
    """Samples (t, pose, u, ud, lambda) at the output times, plus the energy-flow integrals."""

    def __init__(self, output_dt: float | None, angle_refs=()):
        self.dt = output_dt
        self.angle_refs = list(angle_refs)  # joint angles at the start (unwrapping references)
        self.next = 0.0
        self.samples = []
        self.dissipated = self.external = 0.0
        self.flows = []
        self._last_power = None

    def power_step(self, system, ctx, h: float) -> None:
        """Trapezoidal integration of dissipated / external power over the last step."""
        p = power(system, ctx)
        if self._last_power is not None:
            self.external += 0.5 * h * (p[0] + self._last_power[0])
            self.dissipated += 0.5 * h * (p[1] + self._last_power[1])
        self._last_power = p

    def offer(self, t, pose, u, ud, lam, force: bool = False) -> None:
        if force or self.dt is None or t >= self.next - 1e-12 * max(1.0, abs(t)):
            self.samples.append((t, pose.copy(), u.copy(), ud.copy(), lam.copy()))
            self.flows.append((self.dissipated, self.external))
            if self.dt is not None:
                while self.next <= t + 1e-12 * max(1.0, abs(t)):
                    self.next += self.dt


def power(system, ctx) -> tuple[float, float]:
    """(external power in, power dissipated), W, at an evaluated context (modal damping,
    force elements, drivers)."""
    p_in = p_diss = 0.0
    for i, b in enumerate(system.bodies):
        if b.nq and b.model.De is not None:
            qd = ctx.u[system._slices[i]][6:]
            p_diss += float(qd @ b.model.De @ qd)
    for fe in system.forces:
        a, d = fe.power(ctx)
        p_in += a
        p_diss += d
    if system.drivers and ctx.lam is not None:
        full = np.zeros(system.m_all)
        full[system.kept] = ctx.lam
        for d in system.drivers:
            lam = full[system._row_slices[id(d)]][0]
            p_in += -lam * ctx.joint_coordinate(d.joint)[1]
    return p_in, p_diss


def _genalpha(system, pose, u, ud, lam, t_end, h, rho_inf, rtol, atol, newton_tol, rec, max_steps):
    am, af, gamma, beta = genalpha_parameters(rho_inf)
    ca = (1 - af) / (1 - am)
    h_nominal = h
    w, length = length_weights(system)
    n = system.n
    m = int(system.kept.sum())
    free = system.free
    nf = free.size
    t = 0.0
    a = ud.copy()
    stats = {"steps": 0, "rejected": 0, "newton_iterations": 0, "jacobians": 0, "h_min": np.inf, "h_max": 0.0}
    adaptive = rtol is not None
    ctx0 = system.evaluate(pose, u, t, lam)[5]
    rec.power_step(system, ctx0, 0.0)
    rec.offer(t, pose, u, ud, lam, force=True)

    def state(udn):
        an = (af * ud + (1 - af) * udn - am * a) / (1 - am)
        dx = h * u + h * h * ((0.5 - beta) * a + beta * an)
        return an, system.advance(pose, dx), u + h * ((1 - gamma) * a + gamma * an)

    def residual(udn, lamn, tn):
        """r over the free coordinates and the kept rows; M, B, B_F restricted to them."""
        an, pn, un = state(udn)
        mass, f, g, B, BF, ctx = system.evaluate(pn, un, tn, lamn)
        r = np.empty(nf + m)
        r[:nf] = (mass @ udn - f + BF.T @ lamn)[free]
        r[nf:] = g / (h * h * beta * ca)
        return r, mass[np.ix_(free, free)], B[:, free], BF[:, free], ctx

    def tangent(udn, lamn, tn):
        """D = d r1 / d ud - M by finite differences: the damping / stiffness part of the
        iteration matrix (h gamma' C_t + h^2 beta' K_t), re-used over steps."""
        r0, mass, _, _, _ = residual(udn, lamn, tn)
        d = np.empty((nf, nf))
        eps_pos = np.sqrt(np.finfo(float).eps) / (h * h * beta * ca)
        for col, i in enumerate(free):
            e = max(1e-7 * abs(udn[i]), eps_pos)
            x = udn.copy()
            x[i] += e
            d[:, col] = (residual(x, lamn, tn)[0][:nf] - r0[:nf]) / e
        stats["jacobians"] += 1
        return d - mass

    def newton_matrix(mass, B, BF):
        """[M + D, B_F^T; B, 0]: mass and constraint blocks exact at the current iterate."""
        jac = np.zeros((nf + m, nf + m))
        jac[:nf, :nf] = mass + dmat
        jac[:nf, nf:] = BF.T
        jac[nf:, :nf] = B
        return jac

    steps = 0
    dmat, dmat_h = None, None
    ud_prev = lam_prev = h_prev = None
    while t < t_end - 1e-12 * max(1.0, t_end):
        if steps >= max_steps:
            raise InputError(f"generalised-alpha: max_steps = {max_steps} reached at t = {t:.6g} s; "
                             "raise max_steps or the step size h")
        h = min(h, t_end - t)
        if adaptive and rec.dt is not None and rec.next - t > 1e-12 * max(1.0, t_end):
            h = min(h, rec.next - t)  # step-size control lands on the output times
        tn = t + h
        if ud_prev is not None and h == h_prev:  # linear extrapolation predictor
            udn, lamn = 2.0 * ud - ud_prev, 2.0 * lam - lam_prev
        else:
            udn, lamn = ud.copy(), lam.copy()
        converged, renewed = False, False
        if dmat is None:
            dmat, dmat_h, renewed = tangent(udn, lamn, tn), h, True
        elif dmat_h != h:  # stiffness part scales with h^2; a poor fit is caught by the monitor
            dmat, dmat_h = dmat * (h / dmat_h) ** 2, h
        last = np.inf
        it = 0
        while True:
            r, mass, B, BF, ctx = residual(udn, lamn, tn)
            dz = -_dense_solve(newton_matrix(mass, B, BF), r)
            udn[free] += dz[:nf]
            lamn += dz[nf:]
            it += 1
            err = np.max(np.abs(dz[:nf]) * w[free], initial=0.0) * h * h * beta * ca / length
            if not np.isfinite(err):
                break
            if err <= newton_tol:
                converged = True
                break
            if it >= MAX_NEWTON or (it > 1 and err > SLOW_CONTRACTION * last):
                if renewed:
                    break
                dmat, dmat_h, renewed = tangent(udn, lamn, tn), h, True
                it, last = 0, np.inf
                continue
            last = err
        stats["newton_iterations"] += it
        if not converged:
            stats["rejected"] += 1
            h *= 0.5
            dmat = None
            if h < 1e-14 * max(1.0, t_end):
                raise InputError(f"generalised-alpha: Newton did not converge at t = {t:.6g} s even with tiny "
                                 "steps; check the scene (joint axes, loads, units) or raise newton_tol")
            continue
        an, pn, un = state(udn)
        if adaptive:
            e = h * h * abs(beta - 1.0 / 6.0) * np.abs(udn - ud) * w
            est = float(np.sqrt(np.mean((e / (atol + rtol * length)) ** 2))) if n else 0.0
            factor = SAFETY * est ** (-1.0 / 3.0) if est > 0 else H_GROW
            if est > 1.0:
                stats["rejected"] += 1
                h *= max(H_SHRINK, factor)
                continue
        ud_prev, lam_prev, h_prev = ud, lam, h
        t, pose, u, ud, a, lam = tn, pn, un, udn, an, lamn
        steps += 1
        stats["steps"] = steps
        stats["h_min"] = min(stats["h_min"], h)
        stats["h_max"] = max(stats["h_max"], h)
        system._accept_ctx = ctx
        system.accept(pose)
        rec.power_step(system, ctx, h)
        rec.offer(t, pose, u, ud, lam, force=t >= t_end - 1e-12 * max(1.0, t_end))
        if adaptive:
            h *= min(H_GROW, max(H_SHRINK, factor))
        elif h < h_nominal and steps % RECOVER_STEPS == 0:  # fixed step: return to h after a cut
            h = min(2.0 * h, h_nominal)
    return stats


# ---------------------------------------------------------------------------- compiled loop
@jit
def _advance_arrays(R, A, Q, dx, data):  # pragma: no cover - compiled
    """System.advance on the flat arrays of _Kernel: r + dr, A exp(dtheta), q + dq."""
    qoff, uoff = data[0], data[1]
    R2, A2, Q2 = R.copy(), np.empty_like(A), Q.copy()
    for i in range(R.shape[0]):
        s = uoff[i]
        R2[i] += dx[s:s + 3]
        A2[i] = A[i] @ exp_so3(dx[s + 3:s + 6].copy())
        nq = qoff[i + 1] - qoff[i]
        Q2[qoff[i]:qoff[i + 1]] += dx[s + 6:s + 6 + nq]
    return R2, A2, Q2


@jit
def _dense_solve(a, b):  # pragma: no cover - compiled
    """x with a x = b: Gaussian elimination with partial pivoting by loops (for the small Newton
    matrices a LAPACK call costs more than the arithmetic); a, b are not modified."""
    k = b.shape[0]
    lu = a.copy()
    x = b.copy()
    for j in range(k):
        p = j
        for i in range(j + 1, k):
            if abs(lu[i, j]) > abs(lu[p, j]):
                p = i
        if p != j:
            for c in range(k):
                lu[j, c], lu[p, c] = lu[p, c], lu[j, c]
            x[j], x[p] = x[p], x[j]
        pivot = lu[j, j]
        for i in range(j + 1, k):
            factor = lu[i, j] / pivot
            if factor != 0.0:
                for c in range(j + 1, k):
                    lu[i, c] -= factor * lu[j, c]
                x[i] -= factor * x[j]
    for i in range(k - 1, -1, -1):
        acc = x[i]
        for c in range(i + 1, k):
            acc -= lu[i, c] * x[c]
        x[i] = acc / lu[i, i]
    return x


@jit
def _ga_state(udn, R, A, Q, u, ud, a, h, prm, data):  # pragma: no cover - compiled
    """(a_{n+1}, R, A, Q, u_{n+1}) of the generalised-alpha update for ud_{n+1} (module doc)."""
    am, af, gamma, beta = prm[0], prm[1], prm[2], prm[3]
    an = (af * ud + (1 - af) * udn - am * a) / (1 - am)
    R2, A2, Q2 = _advance_arrays(R, A, Q, h * u + h * h * ((0.5 - beta) * a + beta * an), data)
    return an, R2, A2, Q2, u + h * ((1 - gamma) * a + gamma * an)


@jit
def _ga_residual(udn, lamn, R, A, Q, u, ud, a, h, t, refs, prm, kept, free, data):  # pragma: no cover - compiled
    """[M ud - f + B^T lambda; g / (h^2 beta')] over the free coordinates and kept rows, with M
    and B restricted to them, at the updated state and time t; also the driven coordinates."""
    _, R2, A2, Q2, un = _ga_state(udn, R, A, Q, u, ud, a, h, prm, data)
    mass, f, g, B, coords = _system_kernel(R2, A2, Q2, un, t, refs, data)
    nf, m = free.shape[0], kept.shape[0]
    Bk = np.empty((m, nf))
    mf = np.empty((nf, nf))
    r = np.empty(nf + m)
    for i in range(nf):
        fi = free[i]
        ri = -f[fi]
        for j in range(udn.shape[0]):
            ri += mass[fi, j] * udn[j]
        for j in range(nf):
            mf[i, j] = mass[fi, free[j]]
        for k in range(m):
            Bk[k, i] = B[kept[k], fi]
            ri += Bk[k, i] * lamn[k]
        r[i] = ri
    for k in range(m):
        r[nf + k] = g[kept[k]] / (h * h * prm[4])
    return r, mf, Bk, coords


@jit
def _ga_tangent(udn, lamn, R, A, Q, u, ud, a, h, t, refs, prm, kept, free, data):  # pragma: no cover - compiled
    """D = d r1 / d ud - M by forward differences (damping and stiffness part of the iteration
    matrix, the same as ``tangent`` in _genalpha)."""
    nf = free.shape[0]
    r0, mass, _, _ = _ga_residual(udn, lamn, R, A, Q, u, ud, a, h, t, refs, prm, kept, free, data)
    d = np.empty((nf, nf))
    eps_pos = np.sqrt(np.finfo(np.float64).eps) / (h * h * prm[4])
    for col in range(nf):
        i = free[col]
        e = max(1e-7 * abs(udn[i]), eps_pos)
        x = udn.copy()
        x[i] += e
        d[:, col] = (_ga_residual(x, lamn, R, A, Q, u, ud, a, h, t, refs, prm, kept, free, data)[0][:nf]
                     - r0[:nf]) / e
    return d - mass


@jit
def _ga_loop(R, A, Q, u, ud, a, lam, t, t_end, h, h_nominal, prm, kept, free, w, length, tol, adaptive, rtol, atol,
             out_dt, next_out, carry, refs, drv_kept, stats, damping, capacity, data):  # pragma: no cover - compiled
    """The loop of _genalpha for a _Kernel system, compiled; stops at t_end or after ``capacity``
    output samples (the caller resumes it).

    carry = [ud_prev (n), lam_prev (m), D (n*n), h_prev, dmat_h, have_prev, have_d, dissipated,
    last dissipated power, external work, last external power] packed in one float array; refs
    (nd,) the drivers' angle-unwrapping references; drv_kept (nd,) the kept-row index of each
    driver (-1: dropped); stats = [steps, rejected, newton it., jacobians, h_min, h_max, status,
    max_steps] (status 0 done, 1 max_steps, 2 Newton failure, 3 buffer full).  damping (nb,):
    body has modal damping (De = packed[17]).  carry, refs and stats are updated in place.
    """
    qoff, uoff, bodies = data[0], data[1], data[3]
    n, m = u.shape[0], kept.shape[0]
    ca = prm[4] / prm[3]
    ud_prev = carry[:n].copy()
    lam_prev = carry[n:n + m].copy()
    nf = free.shape[0]
    dmat = carry[n + m:n + m + nf * nf].reshape(nf, nf).copy()
    h_prev, dmat_h = carry[-8], carry[-7]
    have_prev, have_d = carry[-6] > 0, carry[-5] > 0
    dissipated, last_power, external, last_in = carry[-4], carry[-3], carry[-2], carry[-1]
    ts = np.empty(capacity)
    Rs = np.empty((capacity,) + R.shape)
    As = np.empty((capacity,) + A.shape)
    Qs = np.empty((capacity, Q.shape[0]))
    us = np.empty((capacity, n))
    uds = np.empty((capacity, n))
    lams = np.empty((capacity, m))
    diss = np.empty(capacity)
    ext = np.empty(capacity)
    coords = refs.copy()
    ns = 0
    factor = 1.0
    end_tol = 1e-12 * max(1.0, t_end)
    jac = np.zeros((nf + m, nf + m))
    stats[6] = 0.0
    while t < t_end - end_tol:
        if stats[0] >= stats[7]:
            stats[6] = 1.0
            break
        h = min(h, t_end - t)
        if adaptive and out_dt > 0.0 and next_out - t > end_tol:
            h = min(h, next_out - t)
        if have_prev and h == h_prev:
            udn, lamn = 2.0 * ud - ud_prev, 2.0 * lam - lam_prev
        else:
            udn, lamn = ud.copy(), lam.copy()
        renewed = False
        if not have_d:
            dmat = _ga_tangent(udn, lamn, R, A, Q, u, ud, a, h, t + h, refs, prm, kept, free, data)
            dmat_h, renewed, have_d = h, True, True
            stats[3] += 1
        elif dmat_h != h:
            dmat = dmat * (h / dmat_h) ** 2
            dmat_h = h
        last = np.inf
        it = 0
        converged = False
        while True:
            r, mass, Bk, coords = _ga_residual(udn, lamn, R, A, Q, u, ud, a, h, t + h, refs, prm, kept, free, data)
            jac[:nf, :nf] = mass + dmat
            jac[:nf, nf:] = Bk.T
            jac[nf:, :nf] = Bk
            dz = -_dense_solve(jac, r)
            for i in range(nf):
                udn[free[i]] += dz[i]
            lamn += dz[nf:]
            it += 1
            err = (np.max(np.abs(dz[:nf]) * w[free]) if nf else 0.0) * h * h * prm[3] * ca / length
            if not np.isfinite(err):
                break
            if err <= tol:
                converged = True
                break
            if it >= MAX_NEWTON or (it > 1 and err > SLOW_CONTRACTION * last):
                if renewed:
                    break
                dmat = _ga_tangent(udn, lamn, R, A, Q, u, ud, a, h, t + h, refs, prm, kept, free, data)
                dmat_h, renewed = h, True
                stats[3] += 1
                it, last = 0, np.inf
                continue
            last = err
        stats[2] += it
        if not converged:
            stats[1] += 1
            h *= 0.5
            have_d = False
            if h < 1e-14 * max(1.0, t_end):
                stats[6] = 2.0
                break
            continue
        an, R2, A2, Q2, un = _ga_state(udn, R, A, Q, u, ud, a, h, prm, data)
        if adaptive:
            e = h * h * abs(prm[3] - 1.0 / 6.0) * np.abs(udn - ud) * w / (atol + rtol * length)
            est = np.sqrt(np.mean(e * e)) if n else 0.0
            factor = SAFETY * est ** (-1.0 / 3.0) if est > 0 else H_GROW
            if est > 1.0:
                stats[1] += 1
                h *= max(H_SHRINK, factor)
                continue
        ud_prev, lam_prev, h_prev, have_prev = ud, lam, h, True
        t += h
        R, A, Q, u, ud, a, lam = R2, A2, Q2, un, udn, an, lamn
        stats[0] += 1
        stats[4] = min(stats[4], h)
        stats[5] = max(stats[5], h)
        power = 0.0
        for i in range(R.shape[0]):
            if damping[i]:
                qd = u[uoff[i] + 6:uoff[i] + 6 + qoff[i + 1] - qoff[i]]
                power += qd @ (bodies[i][17] @ qd)
        dissipated += 0.5 * h * (power + last_power)
        last_power = power
        refs[:] = coords
        power = 0.0
        for d in range(drv_kept.shape[0]):  # driver power -lambda * coordinate rate
            if drv_kept[d] >= 0:
                rate = 0.0
                for i in range(free.shape[0]):
                    rate += Bk[drv_kept[d], i] * u[free[i]]
                power -= lam[drv_kept[d]] * rate
        external += 0.5 * h * (power + last_in)
        last_in = power
        final = t >= t_end - end_tol
        if final or out_dt <= 0.0 or t >= next_out - 1e-12 * max(1.0, abs(t)):
            ts[ns], Rs[ns], As[ns], Qs[ns], us[ns], uds[ns], lams[ns] = t, R, A, Q, u, ud, lam
            diss[ns], ext[ns] = dissipated, external
            ns += 1
            while out_dt > 0.0 and next_out <= t + 1e-12 * max(1.0, abs(t)):
                next_out += out_dt
        if adaptive:
            h *= min(H_GROW, max(H_SHRINK, factor))
        elif h < h_nominal and int(stats[0]) % RECOVER_STEPS == 0:
            h = min(2.0 * h, h_nominal)
        if ns == capacity and not final:
            stats[6] = 3.0
            break
    carry[:n], carry[n:n + m], carry[n + m:n + m + nf * nf] = ud_prev, lam_prev, dmat.ravel()
    carry[-8], carry[-7] = h_prev, dmat_h
    carry[-6] = 1.0 if have_prev else 0.0
    carry[-5] = 1.0 if have_d else 0.0
    carry[-4], carry[-3], carry[-2], carry[-1] = dissipated, last_power, external, last_in
    return (R, A, Q, u, ud, a, lam, t, h, next_out, ts[:ns], Rs[:ns], As[:ns], Qs[:ns], us[:ns], uds[:ns],
            lams[:ns], diss[:ns], ext[:ns])


def _genalpha_compiled(system, pose, u, ud, lam, t_end, h, rho_inf, rtol, atol, newton_tol, rec, max_steps):
    """_genalpha with the whole loop compiled (systems covered by _Kernel): same method, same
    parameters; it runs in chunks of CHUNK output samples.  In a planar scene the kernel holds
    only the in-plane modes (the others are zero), so it evaluates the smaller model."""
    free = set(system.free.tolist())
    kernel = _Kernel(system, [[k for k in range(b.nq) if sl.start + 6 + k in free]
                              for b, sl in zip(system.bodies, system._slices)])
    sub = kernel.u_index
    am, af, gamma, beta = genalpha_parameters(rho_inf)
    prm = np.array([am, af, gamma, beta, beta * (1 - af) / (1 - am)])
    w, length = length_weights(system)
    kept = np.flatnonzero(system.kept).astype(np.int64)
    n, m = sub.size, kept.size
    carry = np.zeros(n + m + n * n + 8)
    refs = np.array([d.joint._angle_ref for d in system.drivers], dtype=float)
    kept_index = np.cumsum(system.kept) - 1
    drv_kept = np.array([kept_index[system._row_slices[id(d)].start] if system.kept[system._row_slices[id(d)].start]
                         else -1 for d in system.drivers], dtype=np.int64)
    stats = np.array([0.0, 0.0, 0.0, 0.0, np.inf, 0.0, 0.0, float(max_steps)])
    damping = np.array([b.model.De is not None for b in system.bodies])
    R, A, Q = kernel.arrays(pose)
    carry[-1], carry[-3] = power(system, system.evaluate(pose, u, 0.0, lam)[5])  # powers at t = 0
    rec.offer(0.0, pose, u, ud, lam, force=True)
    t, next_out, u, ud = 0.0, rec.next, u[sub], ud[sub]
    a = ud.copy()
    while True:
        (R, A, Q, u, ud, a, lam, t, h, next_out, ts, Rs, As, Qs, us, uds, lams, diss, ext) = _ga_loop(
            R, A, Q, u, ud, a, lam, t, t_end, h, h, prm, kept, np.searchsorted(sub, system.free), w[sub], length,
            newton_tol, rtol is not None, rtol or 0.0, atol, rec.dt or 0.0, next_out, carry, refs, drv_kept, stats,
            damping, CHUNK, kernel.data)
        for k in range(ts.size):
            u_full, ud_full = np.zeros(system.n), np.zeros(system.n)
            u_full[sub], ud_full[sub] = us[k], uds[k]
            rec.samples.append((ts[k], kernel.pose(Rs[k], As[k], Qs[k]), u_full, ud_full, lams[k]))
            rec.flows.append((diss[k], ext[k]))
        if stats[6] == 1:
            raise InputError(f"generalised-alpha: max_steps = {max_steps} reached at t = {t:.6g} s; "
                             "raise max_steps or the step size h")
        if stats[6] == 2:
            raise InputError(f"generalised-alpha: Newton did not converge at t = {t:.6g} s even with tiny "
                             "steps; check the scene (joint axes, loads, units) or raise newton_tol")
        if stats[6] == 0:
            break
    keys = ("steps", "rejected", "newton_iterations", "jacobians", "h_min", "h_max")
    out = {k: float(v) if k.startswith("h_") else int(v) for k, v in zip(keys, stats)}
    out["compiled_loop"] = True
    return out


# ---------------------------------------------------------------------------- explicit
#: right-hand-side evaluations per step of the explicit methods (FSAL)
_STAGES = {"rk45": 6, "dop853": 12}


def _explicit(system, pose, u, t_end, method, rtol, atol, baumgarte, rec):
    """scipy solve_ivp on y = [per body r, quaternion, q | u] with Baumgarte stabilisation."""
    from scipy.integrate import solve_ivp

    nb = len(system.bodies)
    sizes = [7 + b.nq for b in system.bodies]
    offs = np.concatenate([[0], np.cumsum(sizes)]).astype(int)
    npos = int(offs[-1])
    alpha = baumgarte
    stats = {"rhs_evaluations": 0}

    def unpack(y):
        r, A, q = [], [], []
        for i in range(nb):
            yi = y[offs[i]:offs[i + 1]]
            r.append(yi[:3])
            A.append(quaternion_to_matrix(yi[3:7]))
            q.append(yi[7:])
        return Pose(r, A, q), y[npos:]

    def rhs(t, y):
        stats["rhs_evaluations"] += 1
        pose_, u_ = unpack(y)
        ydot = np.empty_like(y)
        for i in range(nb):
            sl = system._slices[i]
            ui = u_[sl]
            e = y[offs[i] + 3:offs[i] + 7]
            ydot[offs[i]:offs[i] + 3] = ui[:3]
            ydot[offs[i] + 3:offs[i] + 7] = quaternion_rate(e / np.linalg.norm(e), ui[3:6])
            ydot[offs[i] + 7:offs[i + 1]] = ui[6:]
        mass, f, g, B, BF, _ = system.evaluate(pose_, u_, t)
        if B.shape[0]:
            gd = system.velocity_constraint(pose_, u_, t)
            rhs_g = -system.gamma(pose_, u_, t) - 2 * alpha * gd - alpha**2 * g
        else:
            rhs_g = np.zeros(0)
        ydot[npos:] = solve_kkt(mass, f, B, BF, rhs_g)[0]
        return ydot

    y0 = np.concatenate([np.concatenate([pose.r[i], matrix_to_quaternion(pose.A[i]), pose.q[i]])
                         for i in range(nb)] + [u])
    dt = rec.dt if rec.dt is not None else t_end / 1000
    t_eval = np.append(np.arange(0.0, t_end, dt), t_end)
    sol = solve_ivp(rhs, (0.0, t_end), y0, method=method.upper().replace("DOP853", "DOP853"),
                    t_eval=t_eval, rtol=rtol if rtol is not None else 1e-8, atol=atol)
    if not sol.success:
        raise InputError(f"{method}: {sol.message}; use method = 'genalpha' for stiff scenes")
    for k, t in enumerate(sol.t):
        p, uk = unpack(sol.y[:, k])
        p = Pose(p.r, [a.copy() for a in p.A], p.q)
        system.accept(p)
        ud, lam = accelerations(system, p, uk, t)
        rec.samples.append((t, p, uk.copy(), ud, lam))
        rec.flows.append(None)
    stats["steps"] = stats["rhs_evaluations"] // _STAGES[method]  # approximate: solve_ivp hides it
    return stats


# ---------------------------------------------------------------------------- driver
def integrate(system, t_end, *, h=1e-3, method="genalpha", rho_inf=0.9, rtol=None, atol=1e-9, effects="auto",
              output_dt=None, static_start=False, newton_tol=1e-8, max_steps=10_000_000,
              baumgarte=20.0) -> Result:
    """Run a simulation (see System.simulate for the parameters) and build the Result."""
    if t_end <= 0 or h <= 0:
        raise InputError(f"simulate: t_end = {t_end} and h = {h} must be positive; fix the [solver] values")
    cpu0 = time.process_time()
    system._compile()
    choices = configure_effects(system, effects)
    pose, u, ud, lam = consistent_initial_state(system, static_start)
    system.free, notes = np.arange(system.n), []
    planar = planar_coordinates(system, pose, u, t_end) if system.planar is not False and method == "genalpha" \
        else None
    if planar is None and system.planar:
        raise InputError("simulate: planar = true but the scene is not planar (joint axes parallel to a coordinate "
                         "axis, gravity and initial velocities in the plane, no out-of-plane coupling) or the method "
                         "is not genalpha; remove it")
    if planar is not None:
        system.free, rows, note = planar
        ctx = Context(system, pose, u, 0.0, None)
        _, B, _, _ = system.constraint_rows(ctx, force_rows=False)
        system.kept_3d = system.kept
        system.kept = rows & independent_rows(np.where(rows[:, None], B, 0.0)[:, system.free])
        ud, lam = accelerations(system, pose, u, 0.0, free=system.free)
        notes.append(note)
    rec = _Recorder(output_dt, [j._angle_ref for j in system.joints])
    cpu_setup = time.process_time() - cpu0
    if method == "genalpha":
        run = _genalpha_compiled if _Kernel.usable(system) else _genalpha
        stats = run(system, pose, u, ud, lam, t_end, h, rho_inf, rtol, atol, newton_tol, rec, max_steps)
    elif method in ("rk45", "dop853"):
        stats = _explicit(system, pose, u, t_end, method, rtol, atol, baumgarte, rec)
    else:
        raise InputError(f"unknown integration method {method!r}; use 'genalpha', 'rk45' or 'dop853'")
    cpu_integration = time.process_time() - cpu0 - cpu_setup
    n_constraints = int(system.kept.sum())
    result = postprocess(system, rec, choices, notes)
    dropped = [f"{c.name} row {r - system._row_slices[id(c)].start}" for c in system.constraints
               for r in range(system._row_slices[id(c)].start, system._row_slices[id(c)].stop)
               if not system.kept[r]]
    result.stats.update(stats, method=method, h=h, rho_inf=rho_inf if method == "genalpha" else None,
                        cpu_time=time.process_time() - cpu0, cpu_setup=cpu_setup, cpu_integration=cpu_integration,
                        dropped_constraint_rows=dropped, n_coordinates=int(system.free.size),
                        planar=system.free.size < system.n,
                        n_constraints=n_constraints)
    return result


def postprocess(system, rec: _Recorder, choices, notes=()) -> Result:
    """Histories, reactions, energies and the effects report from the recorded samples."""
    nt = len(rec.samples)
    bodies = {}
    for i, b in enumerate(system.bodies):
        sl = system._slices[i]
        bodies[b.name] = BodyHistory(
            b.name,
            np.array([s[1].r[i] for s in rec.samples]),
            np.array([s[1].A[i] for s in rec.samples]),
            np.array([s[2][sl][:3] for s in rec.samples]),
            np.array([s[2][sl][3:6] for s in rec.samples]),
            np.array([s[1].q[i] for s in rec.samples]).reshape(nt, b.nq),
            np.array([s[2][sl][6:] for s in rec.samples]).reshape(nt, b.nq),
            np.array([s[3][sl] for s in rec.samples]),
        )
    markers = {m.name: np.zeros((nt, 3)) for b in [system.ground] + system.bodies for m in b.markers}
    joints = {c.name: JointHistory(c.name, getattr(c, "kind", "driver"), *(np.zeros((nt, 3)) for _ in range(4)),
                                   np.full(nt, np.nan), np.full(nt, np.nan), np.full(nt, np.nan))
              for c in system.constraints}
    energy = {k: np.zeros(nt) for k in ("kinetic", "strain", "gravity", "spring", "dissipated", "external")}
    cerr = np.zeros(nt)
    node_loads = {b.name: {} for b in system.bodies if b.nq}
    acc_in = acc_diss = 0.0
    last = (0.0, 0.0)
    for j, ref in zip(system.joints, rec.angle_refs):  # unwrap the joint angles along the samples
        j._angle_ref = ref
    if system.free.size < system.n:  # planar run: reactions of all 3D rows
        rec.samples = [(t, p, u, ud, out_of_plane_reactions(system, p, u, ud, t, lam))
                       for t, p, u, ud, lam in rec.samples]
        system.kept = system.kept_3d
    for k, (t, pose, u, ud, lam) in enumerate(rec.samples):
        mass, f, g, B, BF, ctx = system.evaluate(pose, u, t, lam)
        system._accept_ctx = ctx
        system.accept(pose)
        cerr[k] = np.max(np.abs(g)) if g.size else 0.0
        full = np.zeros(system.m_all)
        full[system.kept] = lam
        for b in [system.ground] + system.bodies:
            for mk in b.markers:
                markers[mk.name][k] = ctx.kin(mk)[0]
        for c in system.constraints:
            sl = system._row_slices[id(c)]
            ct1, cr1, ct2, cr2 = ctx.coeffs[id(c)]
            lc = full[sl]
            jh = joints[c.name]
            jh.force[k], jh.torque[k] = -lc @ ct2, -lc @ cr2
            a1 = ctx.kin(c.marker1)[1]
            jh.force_local[k], jh.torque_local[k] = a1.T @ jh.force[k], a1.T @ jh.torque[k]
            joint = c.joint if hasattr(c, "joint") else c
            if joint.coordinate_kind:
                jh.coordinate[k], jh.rate[k] = ctx.joint_coordinate(joint)
            if hasattr(c, "joint"):
                jh.effort[k] = -lc[0]
            for mk, ct, cr in ((c.marker1, ct1, cr1), (c.marker2, ct2, cr2)):
                if mk.node is not None and mk.body.name in node_loads:
                    ctx.loads[id(mk)] = (mk, ctx.loads.get(id(mk), (mk, 0, 0))[1] - lc @ ct,
                                         ctx.loads.get(id(mk), (mk, 0, 0))[2] - lc @ cr)
        for mk, force, torque in ctx.loads.values():
            if mk.node is not None and mk.body.name in node_loads:
                i = system._index[id(mk.body)]
                at = pose.A[i].T
                node_loads[mk.body.name].setdefault(id(mk), (mk, np.zeros((nt, 3)), np.zeros((nt, 3))))
                rec_ = node_loads[mk.body.name][id(mk)]
                rec_[1][k], rec_[2][k] = at @ force, at @ torque
        kin, strain, grav = body_energies(system, pose, u)
        energy["kinetic"][k], energy["strain"][k], energy["gravity"][k] = kin, strain, grav
        energy["spring"][k] = sum(fe.potential(ctx) for fe in system.forces if hasattr(fe, "potential"))
        if rec.flows[k] is None:  # explicit methods: trapezoidal rule over the samples
            p_in, p_diss = power(system, ctx)
            if k:
                dt = t - rec.samples[k - 1][0]
                acc_in += 0.5 * dt * (p_in + last[0])
                acc_diss += 0.5 * dt * (p_diss + last[1])
            last = (p_in, p_diss)
            energy["dissipated"][k], energy["external"][k] = acc_diss, acc_in
        else:
            energy["dissipated"][k], energy["external"][k] = rec.flows[k]
    energy["total"] = (energy["kinetic"] + energy["strain"] + energy["gravity"] + energy["spring"]
                       + energy["dissipated"] - energy["external"])
    estimates = {}
    for name, (b, _, _) in choices.items():
        h = bodies[name]
        estimates[name] = estimate_sizes(b, {"q": h.q, "qd": h.qd, "omega": h.omega, "rotation": h.rotation,
                                             "acceleration": h.acceleration,
                                             "node_loads": list(node_loads[name].values())}, system.gravity)
    report = build_report(choices, estimates, notes)
    t = np.array([s[0] for s in rec.samples])
    return Result(t, bodies, joints, markers, energy, cerr, report, {})


def body_energies(system, pose: Pose, u: np.ndarray) -> tuple[float, float, float]:
    """(kinetic, strain, gravity potential) summed over the bodies, J."""
    kin = strain = grav = 0.0
    for i, b in enumerate(system.bodies):
        sl = system._slices[i]
        A, q, ub = pose.A[i], pose.q[i], u[sl]
        model = b.model
        uk = np.concatenate([A.T @ ub[:3], ub[3:]])
        kin += 0.5 * uk @ model.mass_matrix(q) @ uk
        if b.nq:
            strain += 0.5 * q @ model.Ke @ q
            if model.ks0 is not None:
                strain += model.ks0 @ q + 0.5 * q @ model.ks1 @ q
        if model.gravity:
            g = system.gravity
            md = model.md0 + model.Ct0.T @ q
            grav -= g @ (model.mass * pose.r[i] + A @ md)
            if model.Ct1 is not None:
                grav -= 0.5 * q @ np.einsum("kja,a->kj", model.Ct1, A.T @ g) @ q
    return kin, strain, grav
