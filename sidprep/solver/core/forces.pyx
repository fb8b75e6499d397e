"""Force elements (model/forces.py describes them): marker loads, power and potential.

Each element adds forces / torques (inertial components) at markers into ``loads`` (nmk, 6)
and its power into ``flows`` = [power put in by applied loads, power dissipated, spring
potential energy, power put in by drives] (W, W, J, W).  Loads along a joint coordinate act
through the coordinate's velocity row c (constraints.joint_coordinate): F1 = Q cT1,
T1 = Q cR1, F2 = Q cT2, T2 = Q cR2.  The columns of the layout's element tables fe_int and
fe_par are named in forces.pxd.
"""

from libc.math cimport INFINITY, pow, sqrt, tanh

from sidprep.solver.core.curves cimport curve_value
from sidprep.solver.core.records cimport Layout, MarkerKinematics
from sidprep.solver.core.rotations cimport dot3, matvec3

#: the breakpoints and coefficients standing for a closed-form motion profile's curve (unused)
cdef double NO_CURVE_X[2]
cdef double NO_CURVE_C[1]
NO_CURVE_X[:] = [0.0, 0.0]
NO_CURVE_C[0] = 0.0


cdef (const double*, Py_ssize_t, const double*, Py_ssize_t) curve_arrays(Layout L, Py_ssize_t index) noexcept nogil:
    """Breakpoints x (nx,) and coefficients c (rows, nx - 1) (rows = degree + 1) of the layout's
    curve ``index``, as (x, nx, c, rows)."""
    return &L.curve_x[L.curve_meta[index, 0]], L.curve_meta[index, 1], &L.curve_c[L.curve_meta[index, 2]], \
        L.curve_meta[index, 3]


cdef (const double*, Py_ssize_t, const double*, Py_ssize_t) motion_curve(Layout L, Py_ssize_t index) noexcept nogil:
    """(x, nx, c, rows) of a motion profile's curve (TABULATED), placeholders when ``index`` < 0
    (the closed-form profiles of curves.motion_state do not use them)."""
    if index >= 0:
        return curve_arrays(L, index)
    return NO_CURVE_X, 2, NO_CURVE_C, 1


cdef double curve(Layout L, Py_ssize_t index, double at) noexcept nogil:
    """Value of the layout's curve ``index`` at ``at``."""
    cdef const double* x
    cdef const double* c
    cdef Py_ssize_t nx, rows
    x, nx, c, rows = curve_arrays(L, index)
    return curve_value(x, nx, c, rows, L.curve_period[index], at, 0)


cdef void add_joint_load(double[:, ::1] loads, Py_ssize_t mk1, Py_ssize_t mk2, const double* crow,
                         double value) noexcept nogil:
    """A generalised force ``value`` along a joint coordinate with velocity row crow (4, 3)
    between markers mk1 and mk2."""
    cdef Py_ssize_t a
    for a in range(3):
        loads[mk1, a] += value * crow[a]
        loads[mk1, 3 + a] += value * crow[3 + a]
        loads[mk2, a] += value * crow[6 + a]
        loads[mk2, 3 + a] += value * crow[9 + a]


cdef double stop_penetration(const double* par, double x) noexcept nogil:
    """Penetration of a spring-damper's bump stop, m: -(x + clearance) for the deflection x (m);
    the stop pushes while it is > 0."""
    return -(x + par[FE_PAR_CLEARANCE])


cdef (double, double, double) spring_tension(const double* par, double x, double rate) noexcept nogil:
    """(tension, its dissipative part, its conservative linear part) (N) of a spring-damper with
    deflection x (m) and rate (m/s): k x + c rate, plus the bump stop's
    -k_stop pen^e + c_stop rate while it is engaged (pen > 0)."""
    cdef double damp = par[FE_PAR_DAMPING] * rate
    cdef double t = par[FE_PAR_STIFFNESS] * x + damp
    cdef double pen, stop_damp
    if par[FE_PAR_HAS_STOP] > 0.0:
        pen = stop_penetration(par, x)
        if pen > 0.0:
            stop_damp = par[FE_PAR_STOP_DAMPING] * rate
            t += -par[FE_PAR_STOP_STIFFNESS] * pow(pen, par[FE_PAR_STOP_EXPONENT]) + stop_damp
            damp += stop_damp
    return t, damp, par[FE_PAR_STIFFNESS] * x


cdef double bump_potential(const double* par, double x) noexcept nogil:
    """Elastic energy of an engaged bump stop, J: k_stop pen^(e+1) / (e+1)."""
    cdef double pen, e1
    if par[FE_PAR_HAS_STOP] <= 0.0:
        return 0.0
    pen = stop_penetration(par, x)
    if pen <= 0.0:
        return 0.0
    e1 = par[FE_PAR_STOP_EXPONENT] + 1.0
    return par[FE_PAR_STOP_STIFFNESS] * pow(pen, e1) / e1


cpdef bint has_stops(Layout L) noexcept nogil:
    """Whether a force element has a bump stop (a kink the integrators locate)."""
    cdef Py_ssize_t i
    for i in range(L.fe_int.shape[0]):
        if L.fe_int[i, FE_INT_KIND] == FE_SPRING and L.fe_par[i, FE_PAR_HAS_STOP] > 0.0:
            return True
    return False


cdef double spring_axis(MarkerKinematics kin, Py_ssize_t mk1, Py_ssize_t mk2, double* e) noexcept nogil:
    """Length (m) of a spring from marker mk1 to mk2, returned, and its unit direction e (3,)
    written (zero for coincident markers: no direction)."""
    cdef double d[3]
    cdef double length
    cdef Py_ssize_t a
    for a in range(3):
        d[a] = kin.P[mk2, a] - kin.P[mk1, a]
    length = sqrt(dot3(d, d))
    for a in range(3):
        e[a] = d[a] / length if length > 0.0 else 0.0
    return length


cdef double spring_rate(MarkerKinematics kin, Py_ssize_t mk1, Py_ssize_t mk2, const double* e) noexcept nogil:
    """Lengthening rate (m/s) of a spring along its direction e (3,): the markers move at
    VEL + VC."""
    cdef double v[3]
    cdef Py_ssize_t a
    for a in range(3):
        v[a] = kin.VEL[mk2, a] + kin.VC[mk2, a] - kin.VEL[mk1, a] - kin.VC[mk1, a]
    return dot3(e, v)


cpdef void stop_states(Layout L, MarkerKinematics kin, double[::1] pen, double[::1] rate) noexcept nogil:
    """Every force element's bump-stop penetration pen (nfe,; m, > 0 engaged, -inf for elements
    without a stop) and its rate (nfe,; m/s), written in place, from the markers' kinematics kin.
    The stops are the force laws with a kink at pen = 0 that the integrators locate
    (docs/solver.md, "Contacts")."""
    cdef double e[3]
    cdef double length
    cdef Py_ssize_t i, mk1, mk2
    cdef const double* par
    for i in range(L.fe_int.shape[0]):
        par = &L.fe_par[i, 0]
        pen[i], rate[i] = -INFINITY, 0.0
        if L.fe_int[i, FE_INT_KIND] == FE_SPRING and par[FE_PAR_HAS_STOP] > 0.0:
            mk1, mk2 = L.fe_int[i, FE_INT_MARKER1], L.fe_int[i, FE_INT_MARKER2]
            length = spring_axis(kin, mk1, mk2, e)
            pen[i] = stop_penetration(par, length - par[FE_PAR_LENGTH])
            rate[i] = -spring_rate(kin, mk1, mk2, e)


cdef void marker_load(Layout L, Py_ssize_t i, double t, MarkerKinematics kin, const double[:, ::1] coords,
                      double[:, ::1] loads, double[::1] flows) noexcept nogil:
    """Force (FE_FORCE) or torque (FE_TORQUE) element i at its marker: a constant or a table
    of time or of a joint coordinate, along a direction or not, in the marker's frame or
    inertial; its power v . VEL (or . OMG) into flows[0]."""
    cdef const double* par = &L.fe_par[i, 0]
    cdef Py_ssize_t mk = L.fe_int[i, FE_INT_MARKER1], joint = L.fe_int[i, FE_INT_JOINT]
    cdef Py_ssize_t columns = L.fe_int[i, FE_INT_TABLE_COLUMNS], a
    cdef double x = t if joint < 0 else coords[joint, 0]
    cdef double v[3]
    cdef double v0
    cdef Py_ssize_t col = 0 if L.fe_int[i, FE_INT_KIND] == FE_FORCE else 3
    for a in range(3):
        v[a] = 0.0
        if columns == 0:
            v[a] = par[FE_PAR_VALUE + a]
        elif a < columns:
            v[a] = curve(L, L.fe_int[i, FE_INT_TABLE] + a, x)
    if par[FE_PAR_HAS_DIRECTION] > 0.0:
        v0 = v[0]
        for a in range(3):
            v[a] = v0 * par[FE_PAR_DIRECTION + a]
    if par[FE_PAR_MARKER_FRAME] > 0.0:
        matvec3(&kin.AM[mk, 0, 0], v, v)
    for a in range(3):
        loads[mk, col + a] += v[a]
    flows[0] += dot3(v, &kin.VEL[mk, 0]) if col == 0 else dot3(v, &kin.OMG[mk, 0])


cdef void spring_damper(Layout L, Py_ssize_t i, MarkerKinematics kin, double[:, ::1] loads,
                        double[::1] flows) noexcept nogil:
    """Spring-damper i between its markers (tension along their line, spring_tension): its
    dissipation into flows[1], its energy into flows[2], the power its loads take from the
    markers' path motions into flows[3]."""
    cdef const double* par = &L.fe_par[i, 0]
    cdef Py_ssize_t mk1 = L.fe_int[i, FE_INT_MARKER1], mk2 = L.fe_int[i, FE_INT_MARKER2], a
    cdef double e[3]
    cdef double vc[3]
    cdef double length = spring_axis(kin, mk1, mk2, e)
    cdef double rate = spring_rate(kin, mk1, mk2, e)
    cdef double x = length - par[FE_PAR_LENGTH]
    cdef double tension, damp, linear
    tension, damp, linear = spring_tension(par, x, rate)
    for a in range(3):
        loads[mk2, a] += -tension * e[a]
        loads[mk1, a] += tension * e[a]
        vc[a] = kin.VC[mk2, a] - kin.VC[mk1, a]
    flows[1] += damp * rate
    flows[3] += tension * dot3(e, vc)
    flows[2] += 0.5 * par[FE_PAR_STIFFNESS] * x * x + bump_potential(par, x)


cpdef void force_elements(Layout L, double t, MarkerKinematics kin, const double[:, ::1] coords,
                          const double[:, :, ::1] crows, const double[::1] convective, const double[::1] lam,
                          double[:, ::1] loads, double[::1] flows) noexcept nogil:
    """Add every force element's marker loads into loads (nmk, 6) and flows (4,).

    kin: the markers' kinematics: positions P, orientations AM, material velocities VEL,
    angular velocities OMG (inertial) and the convective velocities VC (nmk, 3) of markers moved
    along a path (a marker moves at VEL + VC); coords (nj, 2) joint coordinate and rate, crows
    (nj, 4, 3) their velocity rows, convective (nj,) the part of the rates due to path motions;
    lam (m_all,) multipliers (friction reads the transverse reactions).  Springs and joint loads
    see the markers' whole motion; the power their loads take from a path's motion (-load . VC)
    is the drive's, flows[3].
    """
    cdef Py_ssize_t i, kind, joint, r0
    cdef const double* par
    cdef double x, xd, q, dx, normal
    for i in range(L.fe_int.shape[0]):
        kind, joint = L.fe_int[i, FE_INT_KIND], L.fe_int[i, FE_INT_JOINT]
        par = &L.fe_par[i, 0]
        if kind == FE_FORCE or kind == FE_TORQUE:
            marker_load(L, i, t, kin, coords, loads, flows)
        elif kind == FE_SPRING:
            spring_damper(L, i, kin, loads, flows)
        elif kind == FE_JOINT_FORCE:  # -k (x - x_ref) - c xd + constant + table(x)
            x, xd = coords[joint, 0], coords[joint, 1]
            dx = x - par[FE_PAR_REFERENCE]
            q = par[FE_PAR_CONSTANT] - par[FE_PAR_STIFFNESS] * dx - par[FE_PAR_DAMPING] * xd
            if L.fe_int[i, FE_INT_TABLE] >= 0:
                q += curve(L, L.fe_int[i, FE_INT_TABLE], x)
            add_joint_load(loads, L.joint_mk[joint, 0], L.joint_mk[joint, 1], &crows[joint, 0, 0], q)
            flows[3] -= q * convective[joint]
            flows[1] += par[FE_PAR_DAMPING] * xd * xd
            flows[2] += 0.5 * par[FE_PAR_STIFFNESS] * (dx * dx)
            flows[0] += (q + par[FE_PAR_DAMPING] * xd + par[FE_PAR_STIFFNESS] * dx) * xd
        elif kind == FE_FRICTION:  # regularised Coulomb: -mu N lever tanh(xd / v_reg)
            r0 = L.joint_off[joint]
            normal = sqrt(lam[r0] * lam[r0] + lam[r0 + 1] * lam[r0 + 1]) + par[FE_PAR_PRELOAD]
            xd = coords[joint, 1]
            q = -par[FE_PAR_MU] * normal * par[FE_PAR_LEVER] * tanh(xd / par[FE_PAR_REGULARISATION])
            add_joint_load(loads, L.joint_mk[joint, 0], L.joint_mk[joint, 1], &crows[joint, 0, 0], q)
            flows[3] -= q * convective[joint]
            flows[1] -= q * xd
