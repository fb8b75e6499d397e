# The named structures the compiled kernels take (records.pyx builds them).
from libc.stdint cimport int64_t


cdef class Layout:
    """A System as flat arrays (sidprep/solver/compile/layout.py builds it; field meanings there)."""
    cdef readonly const int64_t[::1] qoff, uoff            # (nb+1,) body offsets in Q and u
    cdef readonly const double[::1] gravity                 # (3,) m/s^2 inertial
    cdef readonly const double[::1] body_F                  # packed SID terms of all bodies
    cdef readonly const int64_t[:, ::1] body_off            # (nb, N_TERMS) offsets in body_F, -1 absent
    cdef readonly const int64_t[:, ::1] body_flags          # (nb, N_FLAGS)
    cdef readonly const double[::1] body_mass               # (nb,) kg
    cdef readonly const int64_t[::1] mk_body                # (nmk,) body index, -1 ground
    cdef readonly const double[:, ::1] mk_pos               # (nmk, 3)
    cdef readonly const double[:, :, ::1] mk_rot            # (nmk, 3, 3)
    cdef readonly const int64_t[::1] mk_shape               # (nmk,) offset of Phi, Psi in shapes
    cdef readonly const int64_t[:, ::1] mk_k0               # (nmk, 2) offsets of K0F, K0M or -1
    cdef readonly const int64_t[::1] mk_active              # (nmk,) used by joints / forces
    cdef readonly const int64_t[:, ::1] mk_path             # (nmk, 3) [first path curve, motion curve, partner]
    cdef readonly const double[:, ::1] mk_motion            # (nmk, 4) [kind, start, speed, ramp_time]
    cdef readonly const double[::1] shapes
    cdef readonly const int64_t[:, ::1] jrows               # (rows, 3)
    cdef readonly const int64_t[::1] joint_off              # (nj+1,)
    cdef readonly const int64_t[:, ::1] joint_mk            # (nj, 2)
    cdef readonly const int64_t[::1] joint_kind             # (nj,)
    cdef readonly const int64_t[::1] drv_joint, drv_kind    # (nd,)
    cdef readonly const double[:, ::1] drv_par              # (nd, 3)
    cdef readonly const int64_t[::1] drv_curve              # (nd,)
    cdef readonly const double[::1] curve_x, curve_c
    cdef readonly const int64_t[:, ::1] curve_meta          # (ncurves, 4) [x_off, nx, c_off, degree+1]
    cdef readonly const double[::1] curve_period
    cdef readonly const int64_t[:, ::1] fe_int              # (nfe, FE_INT_COLUMNS)
    cdef readonly const double[:, ::1] fe_par               # (nfe, FE_PAR_COLUMNS)
    cdef readonly object arrays                             # the namedtuple of numpy arrays it was made of


cdef class MarkerKinematics:
    """Kinematics of the markers at a state (assemble.markers_into writes them)."""
    cdef readonly double[:, ::1] P, VEL, OMG, VC, WC        # (nmk, 3)
    cdef readonly double[:, :, ::1] AM                      # (nmk, 3, 3)
    cdef readonly double[:, :, ::1] JT, JR, JTF, JRF        # (nmk, 3, w_max); JTF is JT unless load-stiffened
    cdef readonly bint stiffened                            # JTF, JRF are arrays of their own
    cdef readonly double[:, ::1] work                       # (w_max + 24, w_max) scratch of the kernels that write kin


cdef class Evaluation:
    """The system at a state (assemble.evaluate_into writes it; made once per run)."""
    cdef readonly double[:, ::1] M                          # (n, n)
    cdef readonly double[::1] f                             # (n,)
    cdef readonly double[::1] g, bt                         # (m,)
    cdef readonly double[:, ::1] B, BF                      # (m, n); BF is B unless load-stiffened
    cdef readonly double[:, :, ::1] C                       # (m, 4, 3)
    cdef readonly double[:, ::1] coords                     # (nj, 2)
    cdef readonly double[:, ::1] loads                      # (nmk, 6)
    cdef readonly double[::1] flows                         # (4,)
    cdef readonly MarkerKinematics kin
    cdef readonly double[:, :, ::1] crows                   # (nj, 4, 3)
    cdef readonly double[::1] convective                    # (nj,)


cpdef bint load_stiffened(const int64_t[:, ::1] mk_k0) noexcept nogil
