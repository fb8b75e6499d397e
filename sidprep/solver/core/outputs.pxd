# The outputs of a run's samples (outputs.pyx): marker positions, constraint error, energies, the
# power of the stiffening terms, joint reactions and coordinates, node loads.
from libc.stdint cimport int64_t

from sidprep.solver.core.records cimport Evaluation, Layout


cdef class PostConstants:
    """What sample_outputs needs besides the layouts and the samples (outputs.py PostConstants,
    same fields and order): kept, kept_3d, dropped, fixed rows / coordinates; per constraint c_off
    (nc + 1,), c_marker (nc, 2), c_joint, c_driver (nc,); node_body (nmk,); stiffening."""
    cdef readonly const int64_t[::1] kept, kept_3d, dropped, fixed, c_off
    cdef readonly const int64_t[:, ::1] c_marker
    cdef readonly const int64_t[::1] c_joint, c_driver, node_body
    cdef readonly bint stiffening


cdef class Outputs:
    """The SampledOutputs arrays of one stretch as typed views (empty_outputs; the namedtuple
    SampledOutputs of numpy arrays is ``arrays``)."""
    cdef readonly double[:, :, ::1] P           # (nt, nmk, 3)
    cdef readonly double[::1] cerr, power       # (nt,)
    cdef readonly double[:, ::1] energy         # (nt, 4)
    cdef readonly double[:, :, ::1] force, torque, force_local, torque_local, coord  # (nt, nc, 3)
    cdef readonly double[:, :, ::1] node_force, node_torque  # (nt, nmk, 3)
    cdef readonly object arrays


cdef double motion_energy(Layout L, const double[:, ::1] R, const double[:, :, ::1] A, const double[::1] Q,
                          const double[::1] u, const double[:, ::1] M) noexcept nogil
cdef double model_power(Evaluation e, const double[::1] u, const double[::1] lam, double energy_plus,
                        double energy_minus) noexcept nogil
cpdef Outputs empty_outputs(Py_ssize_t nt, Py_ssize_t nmk, Py_ssize_t nc)
cdef void constraint_outputs(Outputs out, Py_ssize_t k, Evaluation e, const double[::1] lam, PostConstants c,
                             double[:, ::1] react) noexcept nogil
# s: the samples of a stretch, any object with the SampleBuffers fields t (nt,), R (nt, nb, 3),
# A (nt, nb, 3, 3), Q (nt, nq), u, ud (nt, n), lam (nt, kept), refs (nt, nj) as C-contiguous float64
# arrays; returns the SampledOutputs namedtuple of numpy arrays
cpdef object sample_outputs(Layout L, Layout L0, object s, PostConstants c)
