"""Modal analysis of a tetrahedral FE model: natural frequencies and modes, free or clamped.

K phi = omega^2 M phi by shift-invert Lanczos (CHOLMOD / SuperLU) or AMG-LOBPCG (sidprep.fe.linalg);
rigid-body modes are counted by connected part and returned first.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sidprep.errors import InputError
from sidprep.fe.assemble import stiffness_and_mass
from sidprep.fe.linalg import clamp_dofs, eigen_modes, node_dofs, rigid_body_modes
from sidprep.fe.topology import connected_parts
from sidprep.fe.plausibility import unit_warnings
from sidprep.jobs.options import DEFAULT_MODAL_COUNT, ModalOptions
from sidprep.jobs.reduce import load_mesh, model_material
from sidprep.progress import Phases


#: a part whose clamped nodes span a plane (rank 2 about their centroid) has no rigid-body mode
PLANAR_RANK = 2


@dataclass(frozen=True)
class ModalResult:
    """Result of ``modal_analysis``.

    frequencies_hz : (n,) rigid modes first, then elastic; modes : (n_free_dof, n) mass-normalised
    shapes on the free DOFs; residuals : (n,) relative ||K phi - lambda M phi||; n_rigid : count of
    rigid-body modes; mass_kg; n_dof / n_free_dof; mesh (FEMesh in metres); material (SI);
    notes; backend; sigma_rad2_s2 : the shift; timings_s : wall seconds per phase.
    """

    frequencies_hz: np.ndarray
    modes: np.ndarray
    residuals: np.ndarray
    n_rigid: int
    mass_kg: float
    n_dof: int
    n_free_dof: int
    mesh: object
    material: object
    notes: tuple[str, ...]
    backend: str
    sigma_rad2_s2: float
    timings_s: dict


def clamped_nodes(mesh, groups) -> np.ndarray:
    """Sorted node indices of the node sets ``groups``; InputError naming the available sets."""
    for g in groups:
        if g not in mesh.node_sets:
            available = ", ".join(sorted(mesh.node_sets)) or "none"
            raise InputError(f"clamp {g}: {mesh.source or 'mesh'} has no node set '{g}'; available: {available}")
    if not len(groups):
        return np.zeros(0, dtype=np.int64)
    return np.unique(np.concatenate([mesh.node_sets[g] for g in groups]))


def rigid_mode_bound(mesh, clamped) -> int:
    """Upper bound of the rigid-body mode count: 6 per free part, 0 for a part clamped at nodes that
    span a plane, 3 otherwise (a point or a line of clamped nodes leaves rotations free)."""

    n_parts, labels = connected_parts(mesh)
    bound = 0
    for part in range(n_parts):
        x = mesh.points[clamped[labels[clamped] == part]]
        if len(x) == 0:
            bound += 6
        elif np.linalg.matrix_rank(x - x.mean(axis=0), tol=1e-9 * np.ptp(mesh.points)) < PLANAR_RANK:
            bound += 3
    return bound


def modal_analysis(mesh, options: ModalOptions = ModalOptions(), *, phases=None) -> ModalResult:
    """Natural frequencies (Hz) and mass-normalised modes of ``mesh`` (an FEMesh or a path).

    ``options.count`` elastic modes (default DEFAULT_MODAL_COUNT) or all up to ``options.fmax`` Hz;
    ``phases`` : sidprep.progress.Phases for progress and timings (default silent).
    """

    o = options
    if o.count is not None and o.fmax is not None:
        raise InputError("count and fmax: give one of them, not both")
    if o.count is not None and o.count < 1:
        raise InputError(f"count = {o.count}: must be >= 1")
    ph = phases or Phases(verbose=False)
    material, notes = model_material(o)
    mesh, _ = load_mesh(mesh, o, ph)
    notes = list(mesh.notes) + notes
    count = o.count if o.count is not None or o.fmax is not None else DEFAULT_MODAL_COUNT
    clamped = clamped_nodes(mesh, o.clamp)
    restriction = clamp_dofs(mesh.n_dof, node_dofs(clamped))
    n_free = len(restriction.free)
    n_rigid_max = rigid_mode_bound(mesh, clamped)
    if count is not None and count + n_rigid_max >= n_free:
        raise InputError(f"count = {count}: the model has {n_free} free DOF, so at most "
                         f"{max(n_free - n_rigid_max - 1, 0)} elastic modes; ask for fewer")
    with ph("assemble", f"{mesh.n_dof} DOF, tet{4 if mesh.order == 1 else 10}"):
        K, M = stiffness_and_mass(mesh, material)
    mass_kg = float(M.sum() / 3.0)
    if len(clamped):
        K, M = restriction.restrict(K), restriction.restrict(M)
    near_null = rigid_body_modes(mesh.points)[restriction.free] if o.backend in ("auto", "lobpcg") else None
    res = eigen_modes(K, M, count=count, fmax=o.fmax, backend=o.backend, n_rigid_max=n_rigid_max,
                      near_null=near_null, extent=np.ptp(mesh.points, axis=0), phases=ph)
    elastic_hz = res.frequencies_hz[res.n_rigid:]
    notes += unit_warnings(mesh.points, material, mass_kg, float(elastic_hz[0]) if len(elastic_hz) else None)
    return ModalResult(res.frequencies_hz, res.vectors, res.residuals, res.n_rigid, mass_kg, mesh.n_dof,
                       int(K.shape[0]), mesh, material, tuple(notes), res.backend, res.sigma, dict(ph.timings_s))
