# Force elements (forces.pyx): marker loads, power and potential; the columns of the layout's
# force-element tables fe_int (nfe, FE_INT_COLUMNS) and fe_par (nfe, FE_PAR_COLUMNS) by name.
# A parameter row par is a pointer to fe_par[i, 0]; a joint coordinate's velocity row crow (4, 3)
# = (cT1, cR1, cT2, cR2) is row-major by pointer.
from sidprep.solver.core.records cimport Layout, MarkerKinematics

#: force element kinds, column FE_INT_KIND of fe_int (compile/layout.py writes them)
cpdef enum:
    FE_FORCE = 0
    FE_TORQUE = 1
    FE_SPRING = 2
    FE_JOINT_FORCE = 3
    FE_FRICTION = 4
    FE_MOVING_MASS = 5

#: the columns of fe_int (-1 where unused)
cpdef enum:
    FE_INT_KIND = 0            # FE_FORCE ... FE_MOVING_MASS
    FE_INT_MARKER1 = 1         # marker of a load or moving mass, first marker of a spring
    FE_INT_MARKER2 = 2         # second marker of a spring
    FE_INT_JOINT = 3           # joint of a joint force / friction; argument joint of a load (-1: time)
    FE_INT_TABLE = 4           # first curve of the element's table
    FE_INT_TABLE_COLUMNS = 5   # curves of a load's table (one per component), 0: constant value
    FE_INT_COLUMNS = 6

#: the columns of fe_par, per kind (zero where unused)
cpdef enum:
    # FE_FORCE, FE_TORQUE: value (3,) N or N m, direction (3,) and its flag, marker-frame flag
    FE_PAR_VALUE = 0
    FE_PAR_DIRECTION = 3
    FE_PAR_HAS_DIRECTION = 6   # 1: the load is value[0] * direction
    FE_PAR_MARKER_FRAME = 7    # 1: components in the marker's frame, 0: inertial
    # FE_SPRING: k N/m, c N s/m, free length m (NaN: the initial distance), the bump stop
    # (contact law) flag, clearance m, stiffness N/m^e, exponent e, damping N s/m;
    # FE_JOINT_FORCE: stiffness N/m or N m/rad, damping, reference coordinate, constant load
    FE_PAR_STIFFNESS = 0
    FE_PAR_DAMPING = 1
    FE_PAR_LENGTH = 2
    FE_PAR_REFERENCE = 2
    FE_PAR_CONSTANT = 3
    FE_PAR_HAS_STOP = 3
    FE_PAR_CLEARANCE = 4
    FE_PAR_STOP_STIFFNESS = 5
    FE_PAR_STOP_EXPONENT = 6
    FE_PAR_STOP_DAMPING = 7
    # FE_MOVING_MASS: mass kg
    FE_PAR_MASS = 0
    # FE_FRICTION: friction coefficient, lever m (1 for sliding joints), preload N,
    # regularisation velocity (m/s or rad/s)
    FE_PAR_MU = 0
    FE_PAR_LEVER = 1
    FE_PAR_PRELOAD = 2
    FE_PAR_REGULARISATION = 3
    FE_PAR_COLUMNS = 10

cdef (const double*, Py_ssize_t, const double*, Py_ssize_t) curve_arrays(Layout L, Py_ssize_t index) noexcept nogil
cdef (const double*, Py_ssize_t, const double*, Py_ssize_t) motion_curve(Layout L, Py_ssize_t index) noexcept nogil
cdef double curve(Layout L, Py_ssize_t index, double at) noexcept nogil
cdef void add_joint_load(double[:, ::1] loads, Py_ssize_t mk1, Py_ssize_t mk2, const double* crow,
                         double value) noexcept nogil
cdef double stop_penetration(const double* par, double x) noexcept nogil
cdef (double, double, double) spring_tension(const double* par, double x, double rate) noexcept nogil
cdef double bump_potential(const double* par, double x) noexcept nogil
cpdef bint has_stops(Layout L) noexcept nogil
cpdef void stop_states(Layout L, MarkerKinematics kin, double[::1] pen, double[::1] rate) noexcept nogil
cpdef void force_elements(Layout L, double t, MarkerKinematics kin, const double[:, ::1] coords,
                          const double[:, :, ::1] crows, const double[::1] convective, const double[::1] lam,
                          double[:, ::1] loads, double[::1] flows) noexcept nogil
