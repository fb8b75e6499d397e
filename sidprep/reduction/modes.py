"""The FEMBS second step: choose the modal basis of the flexible body from a (Craig-Bampton)
reduced model.

* Eigenmodes in the range of interest (the first ``n_modes`` elastic modes, or all up to ``fmax``).
* Frequency-response modes (FRM, Heckmann et al. 2006 eq. 11): (K - Omega^2 M) u_i = p_i for a unit load p_i
  at every interface master DOF, with Omega = 2 pi f_low / 2, f_low = the LOWEST eigenfrequency of
  interest (the first kept elastic eigenfrequency) - "half the minimum eigenfrequency of
  interest".  Omega stays below every eigenfrequency, so the matrix is regular.  The FRMs are
  M-orthogonalised against the rigid-body modes and the kept eigenmodes, then get their own
  modal analysis (Rayleigh-Ritz in their span); those below the cut-off
  ``cutoff_factor`` x the highest frequency of interest (default 5, as FEMBS) are kept.
* The final basis is M-orthonormal with Ke diagonal: every coordinate is an eigenvector of the
  reduced problem, labelled ``Eigen Mode n : f Hz`` (sid-spec 4.7), its kind kept apart.

Reference frames: ``free`` (the 6 rigid-body modes removed, elastic modes M-orthogonal to them:
mean axes to first order) or attached to an interface master, whose 6 DOF are held (the frame
follows that master; "Tangentensystem").
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla

from sidprep.errors import InputError
from sidprep.sid.model import mode_label

#: default cut-off of the FRM selection, as a multiple of the highest frequency of interest (FEMBS)
CUTOFF_FACTOR = 5.0
#: the FRM excitation frequency as a fraction of the lowest frequency of interest (Heckmann et al. 2006)
OMEGA_FRACTION = 0.5
#: directions whose M-norm falls below this fraction of their original norm are linearly dependent
DEPENDENCE_TOL = 1e-8
#: an eigenvalue within this factor of the round-off level (the energy of the exact rigid-body
#: motions, sidprep.reduction.modes.rigid_energy) is a zero-energy mode; piston rod and bar: the rigid
#: eigenvalues sit at ~1e-13 x lambda_max, the first elastic one at ~1e-4
ZERO_ENERGY_MARGIN = 1e4


@dataclass(frozen=True)
class ModalBasis:
    """The selected coordinates in the reduced coordinates of the model.

    Z : (nr, nq) M-orthonormal vectors (Z^T M Z = E, Z^T K Z = diag((2 pi f)^2));
    frequencies_hz : (nq,); kinds : per coordinate, "eigen" or "frm";
    frm_omega_hz : the FRM excitation frequency Omega / 2pi (NaN when no FRM was computed);
    cutoff_hz : FRM cut-off (NaN when none); rejected_frm_hz : frequencies of the dropped FRMs;
    zero_energy_modes : zero-energy modes of the reduced model (held DOFs removed).
    """

    Z: np.ndarray
    frequencies_hz: np.ndarray
    kinds: tuple[str, ...]
    frm_omega_hz: float = float("nan")
    cutoff_hz: float = float("nan")
    rejected_frm_hz: np.ndarray = field(default_factory=lambda: np.zeros(0))
    zero_energy_modes: int = 0

    @property
    def labels(self) -> tuple[str, ...]:
        return mode_labels(self.frequencies_hz, kinds=self.kinds)


def hz(lam: np.ndarray) -> np.ndarray:
    """Frequencies in Hz from eigenvalues lambda = omega^2 (negative round-off clipped)."""
    return np.sqrt(np.clip(lam, 0.0, None)) / (2 * np.pi)


def mode_labels(frequencies_hz, first: int = 1, kinds=None) -> tuple[str, ...]:
    """SIMPACK-style ielastq labels ``Eigen Mode    n :     f Hz`` (sid-spec 3.1), the kind of a
    frequency-response mode behind them (``mode_label``)."""
    kinds = kinds or ("eigen",) * len(frequencies_hz)
    return tuple(mode_label(first + k, f, kind) for k, (f, kind) in enumerate(zip(frequencies_hz, kinds)))


def m_orthogonalize(V: np.ndarray, A: np.ndarray, M: np.ndarray) -> np.ndarray:
    """V minus its M-projection on the M-orthonormal columns of A (twice, for round-off)."""
    for _ in range(2):
        V = V - A @ (A.T @ (M @ V))
    return V


def orthonormalize(K: np.ndarray, M: np.ndarray, V: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rayleigh-Ritz in span(V): (frequencies Hz ascending, vectors M-orthonormal and K-diagonal).

    Linearly dependent directions of V (relative M-norm below DEPENDENCE_TOL) are dropped.
    """
    if V.shape[1] == 0:
        return np.zeros(0), V
    G = V.T @ M @ V
    g, U = np.linalg.eigh(0.5 * (G + G.T))
    keep = g > DEPENDENCE_TOL * g.max()
    Q = V @ (U[:, keep] / np.sqrt(g[keep]))            # M-orthonormal basis of span(V)
    lam, Y = np.linalg.eigh(_sym(Q.T @ K @ Q))
    return hz(lam), Q @ Y


def eigen_pairs(K: np.ndarray, M: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """All eigenpairs of a small dense model: (lambda ascending, M-normalised vectors)."""
    lam, Z = sla.eigh(_sym(K), _sym(M))
    return lam, Z


def frequency_response_modes(K, M, loads: np.ndarray, omega: float) -> np.ndarray:
    """U = (K - omega^2 M)^-1 P for the unit loads P (nr, nl); omega in rad/s (Heckmann et al. 2006 eq. 11)."""
    return sla.solve(_sym(K) - omega ** 2 * _sym(M), loads, assume_a="sym")


def select_by_cutoff(frequencies_hz: np.ndarray, cutoff_hz: float) -> np.ndarray:
    """Mask of the coordinates whose frequency is at or below the cut-off."""
    return np.asarray(frequencies_hz) <= cutoff_hz


def interest_range(elastic_hz: np.ndarray, n_modes=None, fmax=None) -> tuple[np.ndarray, float]:
    """(mask of the eigenmodes of interest, highest frequency of interest in Hz)."""
    if n_modes is not None:
        if n_modes > len(elastic_hz):
            raise InputError(f"--modes {n_modes}: the reduced model has only {len(elastic_hz)} elastic modes; "
                             "ask for fewer or refine the first reduction")
        keep = np.arange(len(elastic_hz)) < n_modes
        return keep, float(elastic_hz[n_modes - 1])
    keep = elastic_hz <= fmax
    if not keep.any():
        raise InputError(f"--fmax {fmax:g} Hz: no elastic mode below it (the first is {elastic_hz[0]:.4g} Hz); "
                         "raise --fmax or use --modes N")
    return keep, float(fmax)


def modal_basis(K, M, *, rigid=None, held=(), loads=None, n_modes=None, fmax=None,
                frm=True, cutoff_factor=CUTOFF_FACTOR) -> ModalBasis:
    """The FEMBS second step on a small reduced model (module docstring).

    Parameters
    ----------
    K, M : (nr, nr) dense reduced stiffness (N/m) and mass (kg)
    rigid : (nr, 6) rigid-body motions for the free frame (None for an attached frame)
    held : reduced DOF indices fixed by the attached frame (its master's 6 DOF)
    loads : (nr, nl) FRM unit loads in reduced coordinates (rows of held DOFs are ignored)
    n_modes | fmax : eigenmodes of interest (count, or all up to fmax Hz)
    frm : compute frequency-response modes; cutoff_factor : FRM cut-off / highest frequency of interest
    """
    nr = K.shape[0]
    free = np.setdiff1d(np.arange(nr), np.asarray(held, dtype=np.int64))
    Kf, Mf = K[np.ix_(free, free)], M[np.ix_(free, free)]
    lam, Z = eigen_pairs(Kf, Mf)
    R = np.zeros((len(free), 0)) if rigid is None else orthonormalize(Kf, Mf, rigid[free])[1]
    n_zero = zero_energy_count(lam, rigid_energy(Kf, R) if R.shape[1] else None)
    if n_zero != (0 if rigid is None else 6) or R.shape[1] not in (0, 6):
        raise InputError(f"the reduced body has {n_zero} zero-energy modes instead of {0 if rigid is None else 6}; "
                         "it is a mechanism or falls apart — check the mesh (sidprep info) and the interfaces")
    if R.shape[1]:
        C = sla.null_space(R.T @ Mf)                  # M-orthogonal complement of rigid motion
        lam, Y = eigen_pairs(C.T @ Kf @ C, C.T @ Mf @ C)
        Z = C @ Y
    elastic_hz = hz(lam)
    keep, f_high = interest_range(elastic_hz, n_modes, fmax)
    E = Z[:, keep]
    f_eig = elastic_hz[keep]
    kinds = ["eigen"] * len(f_eig)
    vectors, freqs = [E], [f_eig]
    omega_hz = cutoff = float("nan")
    rejected = np.zeros(0)
    P = np.zeros((len(free), 0)) if loads is None else np.asarray(loads, dtype=float)[free]
    P = P[:, np.abs(P).max(axis=0, initial=0.0) > 0] if P.shape[1] else P
    if frm and P.shape[1]:
        omega_hz = OMEGA_FRACTION * float(f_eig[0])
        cutoff = cutoff_factor * f_high
        U = frequency_response_modes(Kf, Mf, P, 2 * np.pi * omega_hz)
        U = U / np.sqrt(np.einsum("ij,ij->j", U, Mf @ U))     # unit M-norm: forces and moments alike
        against = np.hstack([R, E])
        f_frm, F = orthonormalize(Kf, Mf, m_orthogonalize(U, against, Mf))
        ok = select_by_cutoff(f_frm, cutoff)
        rejected = f_frm[~ok]
        vectors.append(F[:, ok]), freqs.append(f_frm[ok])
        kinds += ["frm"] * int(ok.sum())
    Zfull = np.zeros((nr, len(kinds)))
    Zfull[free] = np.hstack(vectors)
    return ModalBasis(Zfull, np.concatenate(freqs), tuple(kinds), omega_hz, cutoff, rejected, n_zero)


def rigid_energy(K: np.ndarray, R: np.ndarray) -> float:
    """Largest eigenvalue of R^T K R for M-orthonormal rigid motions R: the round-off level at
    which this pencil shows a zero-energy mode, (rad/s)^2."""
    return float(np.abs(np.linalg.eigvalsh(_sym(R.T @ K @ R))).max())


def zero_energy_count(lam: np.ndarray, noise: float | None = None) -> int:
    """Eigenvalues within ZERO_ENERGY_MARGIN x the round-off level ``noise`` (default: machine
    epsilon x the largest eigenvalue); measured noise keeps soft bodies (f1 << f_max) elastic."""
    if noise is None:
        noise = np.finfo(float).eps * np.abs(lam).max()
    return int((np.abs(lam) <= ZERO_ENERGY_MARGIN * noise).sum())


def modal_damping(frequencies_hz: np.ndarray, damping) -> np.ndarray:
    """De (nq, nq) for an M-orthonormal basis (sid-spec 4.7).

    damping : float (one ratio zeta for all: De = diag(2 zeta omega)), sequence of nq ratios, or
    {"rayleigh": (alpha, beta)} (De = alpha Me + beta Ke = diag(alpha + beta omega^2)).
    """
    w = 2 * np.pi * np.asarray(frequencies_hz, dtype=float)
    if isinstance(damping, dict):
        if set(damping) != {"rayleigh"} or np.shape(damping["rayleigh"]) != (2,):
            raise InputError(f"damping {damping}: a table must be {{rayleigh = [alpha, beta]}} "
                             "(De = alpha Me + beta Ke); or give one ratio or one per mode")
        alpha, beta = damping["rayleigh"]
        return np.diag(alpha + beta * w ** 2)
    zeta = np.broadcast_to(np.asarray(damping, dtype=float), w.shape) if np.ndim(damping) == 0 \
        else np.asarray(damping, dtype=float)
    if zeta.shape != w.shape:
        raise InputError(f"damping: {len(zeta)} ratios given for {len(w)} modes; give one ratio or one per mode")
    return np.diag(2 * zeta * w)


def _sym(A):
    return 0.5 * (A + A.T)
