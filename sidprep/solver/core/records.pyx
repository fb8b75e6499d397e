"""The named structures the compiled kernels take (records.pxd): a System's Layout as typed
memoryviews, and the per-run workspaces an evaluation writes (the kinematics of the markers and
the system at a state: M, f, g, B, B_F, ...), made once per run."""

import numpy as np

#: fields of the layout of integers (numpy int64); all others are float64
INTEGER_FIELDS = frozenset({"qoff", "uoff", "body_off", "body_flags", "mk_body", "mk_shape", "mk_k0", "mk_active",
                            "mk_path", "jrows", "joint_off", "joint_mk", "joint_kind", "drv_joint", "drv_kind",
                            "drv_curve", "curve_meta", "fe_int"})
#: rows of MarkerKinematics.work beyond w_max (the path markers' Phi, Psi, Phi' and 3-vectors)
WORK_EXTRA_ROWS = 24


cdef class Layout:
    """A System as flat arrays (records.pxd; made by layout_record)."""

    def with_every_marker(self) -> Layout:
        """This layout with every marker active: an Evaluation made of it holds all markers in ``kin``."""
        return layout_record(self.arrays._replace(mk_active=np.ones(self.mk_body.shape[0], dtype=np.int64)))


def layout_record(arrays) -> Layout:
    """The Layout record of compile/layout.py's Layout namedtuple ``arrays`` (its arrays made
    C-contiguous int64 / float64 where they are not; ``arrays`` holds the ones the record views);
    a Layout record itself is returned as it is."""
    if isinstance(arrays, Layout):
        return arrays
    typed = {name: np.ascontiguousarray(a, dtype=np.int64 if name in INTEGER_FIELDS else float)
             for name, a in arrays._asdict().items()}
    if any(a is not getattr(arrays, name) for name, a in typed.items()):
        arrays = arrays._replace(**typed)
    cdef Layout L = Layout.__new__(Layout)
    L.arrays = arrays
    L.qoff, L.uoff, L.gravity = arrays.qoff, arrays.uoff, arrays.gravity
    L.body_F, L.body_off, L.body_flags, L.body_mass = arrays.body_F, arrays.body_off, arrays.body_flags, arrays.body_mass
    L.mk_body, L.mk_pos, L.mk_rot, L.mk_shape = arrays.mk_body, arrays.mk_pos, arrays.mk_rot, arrays.mk_shape
    L.mk_k0, L.mk_active, L.mk_path, L.mk_motion = arrays.mk_k0, arrays.mk_active, arrays.mk_path, arrays.mk_motion
    L.shapes = arrays.shapes
    L.jrows, L.joint_off, L.joint_mk, L.joint_kind = arrays.jrows, arrays.joint_off, arrays.joint_mk, arrays.joint_kind
    L.drv_joint, L.drv_kind, L.drv_par, L.drv_curve = arrays.drv_joint, arrays.drv_kind, arrays.drv_par, arrays.drv_curve
    L.curve_x, L.curve_c, L.curve_meta = arrays.curve_x, arrays.curve_c, arrays.curve_meta
    L.curve_period = arrays.curve_period
    L.fe_int, L.fe_par = arrays.fe_int, arrays.fe_par
    return L


cdef Py_ssize_t widest_body(Layout L):
    """w_max = max over the bodies of 6 + nq (0 without bodies): the width of the marker Jacobians."""
    cdef Py_ssize_t b, wmax = 0
    for b in range(L.uoff.shape[0] - 1):
        wmax = max(wmax, L.uoff[b + 1] - L.uoff[b])
    return wmax


cpdef bint load_stiffened(const int64_t[:, ::1] mk_k0) noexcept nogil:
    """Whether a marker is load-stiffened (K0F / K0M; mk_k0 (nmk, 2) of the layout): only then do
    B_F, JTF, JRF differ from B, JT, JR."""
    cdef Py_ssize_t k
    for k in range(mk_k0.shape[0]):
        if mk_k0[k, 0] >= 0 or mk_k0[k, 1] >= 0:
            return True
    return False


cdef class MarkerKinematics:
    """Kinematics of the markers at a state (records.pxd; made by marker_kinematics)."""


cdef class Evaluation:
    """The system at a state (records.pxd; made by evaluation_arrays)."""


def marker_kinematics(Layout L) -> MarkerKinematics:
    """A MarkerKinematics workspace of zeros for the markers of layout L (JTF, JRF are JT, JR
    unless a marker is load-stiffened); the Jacobians are zero-padded to the widest body,
    w_max = max 6 + nq, and ``work`` (w_max + WORK_EXTRA_ROWS, w_max) is the kernels' scratch."""
    cdef Py_ssize_t nmk = L.mk_body.shape[0], wmax = widest_body(L)
    cdef MarkerKinematics kin = MarkerKinematics.__new__(MarkerKinematics)
    kin.stiffened = load_stiffened(L.mk_k0)
    kin.P, kin.VEL, kin.OMG = np.zeros((nmk, 3)), np.zeros((nmk, 3)), np.zeros((nmk, 3))
    kin.VC, kin.WC = np.zeros((nmk, 3)), np.zeros((nmk, 3))
    kin.AM = np.zeros((nmk, 3, 3))
    kin.JT, kin.JR = np.zeros((nmk, 3, wmax)), np.zeros((nmk, 3, wmax))
    kin.JTF = np.zeros((nmk, 3, wmax)) if kin.stiffened else kin.JT
    kin.JRF = np.zeros((nmk, 3, wmax)) if kin.stiffened else kin.JR
    kin.work = np.zeros((wmax + WORK_EXTRA_ROWS, wmax))
    return kin


def evaluation_arrays(Layout L) -> Evaluation:
    """The per-run workspace of ``evaluate_into`` for layout L: an Evaluation of zeros (B_F is B
    unless a marker is load-stiffened), made once per run (an evaluation writes into it)."""
    cdef Py_ssize_t n = L.uoff[L.uoff.shape[0] - 1]
    cdef Py_ssize_t m_all = L.joint_off[L.joint_off.shape[0] - 1] + L.drv_joint.shape[0]
    cdef Py_ssize_t nj = L.joint_mk.shape[0], nmk = L.mk_body.shape[0]
    cdef Evaluation W = Evaluation.__new__(Evaluation)
    W.kin = marker_kinematics(L)
    W.M, W.f = np.zeros((n, n)), np.zeros(n)
    W.g, W.bt = np.zeros(m_all), np.zeros(m_all)
    W.B = np.zeros((m_all, n))
    W.BF = np.zeros((m_all, n)) if W.kin.stiffened else W.B
    W.C = np.zeros((m_all, 4, 3))
    W.coords, W.crows, W.convective = np.zeros((nj, 2)), np.zeros((nj, 4, 3)), np.zeros(nj)
    W.loads, W.flows = np.zeros((nmk, 6)), np.zeros(4)
    return W
