"""A model split into parts for component mode synthesis (sidprep.reduction.component_modes): the cells
cut into connected parts of balanced size (METIS k-way on the cells' face graph; Karypis & Kumar 1998),
and each part described in model DOFs (after the RBE2/RBE3 interfaces, sidprep.reduction.interfaces):
part p owns the DOFs its cells touch; the coarse DOFs G are those owned by two or more parts plus the
monolithic reduction's boundary b.  A part travels to its worker as a description (``PartModel`` with
its ``PartFE``); the worker assembles its K = T^T K_fe T and M = T^T M_fe T (``assembled``)."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pymetis
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from sidprep.errors import InputError
from sidprep.fe.assemble import scalar_mass_matrix, stiffness_matrix, vector_mass
from sidprep.fe.mesh import FEMesh
from sidprep.fe.topology import face_table

#: METIS load imbalance allowed between parts (1.03 = 3 %, its default for k-way partitions)
PART_IMBALANCE = 1.03


def face_graph(cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The cells' adjacency through shared faces in CSR form (xadj (ne + 1,), adjncy)."""

    group, counts, _ = face_table(np.asarray(cells)[:, :4])
    order = np.argsort(group, kind="stable")
    g = group[order]
    pair = np.flatnonzero((g[1:] == g[:-1]) & (counts[g[1:]] == 2))
    a, b = order[pair] // 4, order[pair + 1] // 4
    ne = len(cells)
    A = sp.csr_matrix((np.ones(2 * len(a)), (np.r_[a, b], np.r_[b, a])), shape=(ne, ne))
    return A.indptr.astype(np.int64), A.indices.astype(np.int64)


def partition_cells(cells: np.ndarray, n_parts: int) -> np.ndarray:
    """(ne,) part of every cell: N connected parts of balanced cell count whose shared faces are few
    (METIS k-way on the face graph, contiguous parts; Karypis & Kumar 1998)."""

    ne = len(cells)
    if not 2 <= n_parts <= ne // 2:
        raise InputError(f"parts = {n_parts}: must be between 2 and half the cell count ({ne // 2})")
    xadj, adjncy = face_graph(cells)
    graph = sp.csr_matrix((np.ones(len(adjncy)), adjncy, xadj), shape=(ne, ne))
    if connected_components(graph, directed=False)[0] > 1:
        raise InputError("parts: the mesh is not one connected body through shared faces; reduce it in one "
                         "piece (without parts) or join its pieces")
    options = pymetis.Options(seed=1, contig=1, ufactor=int(round(1000 * (PART_IMBALANCE - 1))))
    _, labels = pymetis.part_graph(n_parts, pymetis.CSRAdjacency(xadj, adjncy), options=options)
    labels = np.asarray(labels, dtype=np.int64)
    if len(np.unique(labels)) != n_parts:
        raise InputError(f"parts = {n_parts}: the mesh has too few cells for {n_parts} connected parts; use fewer parts")
    return labels



@dataclass(frozen=True)
class PartFE:
    """A part's FE model as the worker that holds it assembles it (``assembled``): points (np_l, 3) m,
    its nodes; cells (ne_p, nn) into them; material, a Material or GivenMatrices on its nodes' DOFs;
    T (3 np_l, n_p) csr, its nodes' displacements from its model DOFs (rows of the interface
    transformation, sidprep.reduction.interfaces)."""

    points: np.ndarray
    cells: np.ndarray
    material: object
    T: sp.csr_matrix


@dataclass(frozen=True)
class PartModel:
    """One part in model DOFs: what a task needs.

    name : "part k/N"; dofs : (n_p,) its model DOFs (ascending); boundary : (nb_p,) local indices of
    its coarse DOFs (ascending); extent : (3,) bounding-box edges (m) for the memory estimate;
    fe : its FE model (PartFE); K, M : (n_p, n_p) csr, N/m and kg, from its cells only - None in the
    driver, which describes the part; its worker assembles them (``assembled``).
    """

    name: str
    dofs: np.ndarray
    boundary: np.ndarray
    extent: np.ndarray
    fe: PartFE | None = None
    K: sp.csr_matrix | None = None
    M: sp.csr_matrix | None = None

    @property
    def interior(self) -> np.ndarray:
        """(ni_p,) local indices of the part's own DOFs."""
        return np.setdiff1d(np.arange(len(self.dofs)), self.boundary)


def part_dofs(im, cells: np.ndarray) -> np.ndarray:
    """Model DOFs touched by ``cells`` (through the interface transformation T), ascending."""
    nodes = np.unique(cells)
    rows = (3 * nodes[:, None] + np.arange(3)).ravel()
    return np.unique(im.T[rows].indices)


def coarse_dofs(owned: list[np.ndarray], boundary) -> np.ndarray:
    """G: the model DOFs owned by two or more parts, and the monolithic boundary; ascending."""
    count = np.bincount(np.concatenate(owned))
    return np.union1d(np.flatnonzero(count > 1), np.asarray(boundary, dtype=np.int64))


@dataclass(frozen=True)
class GivenMatrices:
    """A part's FE stiffness and mass as given (imported from another FE code, sidprep.fe.matrices)
    on the whole mesh's DOFs: K (3n, 3n) N/m and M (3n, 3n) kg, csr."""

    K: sp.csr_matrix
    M: sp.csr_matrix


def part_fe_matrices(mesh, cells: np.ndarray, material) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """K, M (3n, 3n) of the part of ``cells``: assembled with ``material``, or GivenMatrices."""
    if isinstance(material, GivenMatrices):
        return material.K, material.M
    sub = replace(mesh, cells=cells)
    return stiffness_matrix(sub, material), vector_mass(scalar_mass_matrix(sub, material.rho))


def part_fe(mesh, cells: np.ndarray, material, T: sp.csr_matrix) -> PartFE:
    """The PartFE of ``cells`` (global node indices) with the model DOFs' columns T (3n, n_p) of the
    interface transformation: its nodes renumbered, T's and given matrices' rows cut to them."""
    nodes, local = np.unique(cells, return_inverse=True)
    rows = (3 * nodes[:, None] + np.arange(3)).ravel()
    if isinstance(material, GivenMatrices):
        material = GivenMatrices(material.K[rows][:, rows].tocsr(), material.M[rows][:, rows].tocsr())
    return PartFE(mesh.points[nodes], local.reshape(cells.shape), material, T[rows].tocsr())


def assembled(part: PartModel) -> PartModel:
    """The part with its K = T^T K_fe T and M = T^T M_fe T (K_fe, M_fe from its cells: ``part_fe_matrices``)."""
    if part.K is not None:
        return part
    fe = part.fe
    mesh = FEMesh(fe.points, fe.cells, np.arange(len(fe.points)))
    K_fe, M_fe = part_fe_matrices(mesh, fe.cells, fe.material)
    return replace(part, K=(fe.T.T @ (K_fe @ fe.T)).tocsr(), M=(fe.T.T @ (M_fe @ fe.T)).tocsr())


def part_models(mesh, material, labels: np.ndarray, im, boundary, names=None) -> tuple[list[PartModel], np.ndarray]:
    """Each part described (its DOFs, coarse DOFs and FE model; its matrices T^T K_p T are assembled
    where it is held, ``assembled``) and the coarse DOFs G; ``boundary`` the monolithic reduction's
    boundary DOFs (model indices).  ``material`` : one Material, or one per part (an assembly's
    components: a Material or GivenMatrices); ``names`` : one per part (default "part k/N")."""

    n = int(labels.max()) + 1
    materials = list(material) if isinstance(material, (list, tuple)) else [material] * n
    names = names or [f"part {p + 1}/{n}" for p in range(n)]
    cells = [mesh.cells[labels == p] for p in range(n)]
    owned = [part_dofs(im, c) for c in cells]
    G = coarse_dofs(owned, boundary)
    parts = []
    for c, dofs, mat, name in zip(cells, owned, materials, names):
        fe = part_fe(mesh, c, mat, im.T[:, dofs])
        parts.append(PartModel(name, dofs, np.flatnonzero(np.isin(dofs, G)), np.ptp(fe.points, axis=0), fe))
    return parts, G

