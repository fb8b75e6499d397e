"""Tetrahedral FE meshes: the data model (readers and checks follow below it).

Node order of a cell (the canonical order used everywhere in sidprep, = VTK / meshio):
tet4: vertices 0..3; tet10: vertices 0..3, then mid-edge nodes of the edges
(0,1), (1,2), (0,2), (0,3), (1,3), (2,3).
DOFs are node-interleaved: DOF 3*i + c is component c (x, y, z) of node i.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Mapping

import numpy as np

#: mid-edge node k (k = 4..9 of a tet10) lies on the edge between these two vertices
TET10_EDGES = ((0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3))


@dataclass(frozen=True)
class FEMesh:
    """A validated tetrahedral mesh.

    Attributes
    ----------
    points : (n_nodes, 3) float64
        Node coordinates, in the length unit of ``length_unit``.
    cells : (n_cells, 4) or (n_cells, 10) int64
        Connectivity in the canonical node order (module docstring), positive volume.
    node_ids : (n_nodes,) int64
        The node numbers of the source file (used as SID node names).
    node_sets : mapping name -> (k,) int64
        Physical groups / node sets, as sorted unique node indices (0-based rows of ``points``).
    cell_sets : mapping name -> (k,) int64
        Volume physical groups / element sets, as cell indices.
    source : str
        The file the mesh was read from.
    sha256 : str
        Hash of that file's bytes (provenance).
    notes : tuple of str
        One-line notes about repairs made while reading (merged duplicates, dropped nodes, ...).
    length_unit : str
        "m" unless scaled otherwise.
    """

    points: np.ndarray
    cells: np.ndarray
    node_ids: np.ndarray
    node_sets: Mapping[str, np.ndarray] = field(default_factory=dict)
    cell_sets: Mapping[str, np.ndarray] = field(default_factory=dict)
    source: str = ""
    sha256: str = ""
    notes: tuple[str, ...] = ()
    length_unit: str = "m"

    @property
    def order(self) -> int:
        """1 for tet4, 2 for tet10."""
        return 1 if self.cells.shape[1] == 4 else 2

    @property
    def n_nodes(self) -> int:
        return self.points.shape[0]

    @property
    def n_dof(self) -> int:
        return 3 * self.points.shape[0]

    def scaled(self, factor: float, length_unit: str = "m") -> "FEMesh":
        """The same mesh with coordinates multiplied by ``factor`` (e.g. 1e-3 for mm -> m)."""
        return replace(self, points=self.points * factor, length_unit=length_unit)
