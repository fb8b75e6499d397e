"""Mesh readers, one module per source: ``gmsh`` (.msh files and geometry meshed through the gmsh
API), ``meshio`` (every other volume format meshio reads) and ``abaqus`` (the Abaqus / CalculiX
deck text meshio does not resolve: ``*INCLUDE`` and the file's node and element numbers).

A reader returns a ``RawMesh``; ``sidprep.fe.validation`` checks and repairs it and
``sidprep.fe.mesh.read_mesh``, the one entry point, makes the ``FEMesh`` of it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class RawMesh:
    """Tetrahedra as a reader found them, before the checks: canonical node order
    (``sidprep.fe.topology``), any orientation.

    Attributes
    ----------
    points : (n_nodes, 3) float64
        Node coordinates in the file's length unit.
    node_ids : (n_nodes,) int64
        The file's node numbers.
    cells : (n_cells, 4) or (n_cells, 10) int64
        Connectivity as 0-based rows of ``points``.
    cell_ids : (n_cells,) int64
        The file's element numbers.
    node_sets, cell_sets : dict name -> (k,) int64
        Node indices (rows of ``points``) and cell indices (rows of ``cells``) of the named groups.
    """

    points: np.ndarray
    node_ids: np.ndarray
    cells: np.ndarray
    cell_ids: np.ndarray
    node_sets: dict
    cell_sets: dict
