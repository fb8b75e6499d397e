"""Modal stresses of a tet4/tet10 body: the stress of every coordinate of the reduced basis at the
nodes of the mesh (``sidprep reduce --stress``), and their check against the full model.

For each element, the displacement gradient of a field u is evaluated at the element's own nodes
from the shape-function gradients of sidprep.fe.assemble (H = sum_b u_b (x) grad N_b), the strain
eps = (H + H^T) / 2 and the isotropic Hooke stress sigma = lambda tr(eps) I + 2 mu eps; the values
of all elements sharing a node are averaged (unweighted, the usual nodal averaging of CalculiX and
Nastran; one material per mesh, so there are no material borders to respect).  A model whose K and
M were imported gets the stresses of its deck's own elements and materials instead
(sidprep.fe.element_stress.DeckStress, passed where a Material is otherwise).  Components in
sidprep.sid.stress.STRESS_ORDER, Pa per unit modal coordinate.
"""

from __future__ import annotations

import numpy as np

from sidprep.fe.assemble import shape_functions, shape_gradients
from sidprep.fe.element_stress import DeckStress, add_to_nodes, hooke
from sidprep.fe.topology import TET10_EDGES
from sidprep.reduction.fe_checks import relieved_static_solve
from sidprep.reduction.interfaces import linear_surface_triangles
from sidprep.sid.check import Check
from sidprep.sid.stress import StressModes

#: where modal stresses are kept: the outer surface's nodes (default) or every node
SCOPES = ("surface", "all")
#: elements per batch (temporaries ~ CHUNK * 10 * 9 * nc * 8 bytes)
CHUNK = 1024
#: the reduced body's stress under unit master forces vs the full model's, relative to the largest
#: stress of the load case, off the interface patches (a warning).  This measures the basis, not
#: the recovery (exact for shapes in the basis): the FRMs are responses at Omega > 0 and a free
#: body's unit force carries inertia-relief body loads, neither exactly in the span.  Measured with
#: the defaults: piston rod 5.3 % (axial force, near the small eye), bundled bar with two free RBE2
#: ends 8.6 %, the same bar clamped at one end 2.9 %
STRESS_CHECK_TOL = 0.10
METHOD = ("element strain at the element's nodes from the shape-function gradients, isotropic Hooke, "
          "unweighted average over the elements sharing a node")


def element_node_coordinates(order: int) -> np.ndarray:
    """Reference coordinates (3, nn) of a tet4 (nn = 4) or tet10 (nn = 10) element's nodes."""
    vertices = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    if order == 1:
        return vertices.T
    mids = np.array([0.5 * (vertices[i] + vertices[j]) for i, j in TET10_EDGES])
    return np.vstack([vertices, mids]).T


def element_nodal_stress(X: np.ndarray, Ue: np.ndarray, order: int, lame: tuple[float, float],
                         first: int) -> np.ndarray:
    """Stress at the element's own nodes for displacement fields of the element.

    X : (ne, nn, 3) node coordinates, m; Ue : (ne, nn, 3, nc) nodal displacements, m;
    lame : (lambda, mu), Pa; first : index of the first element (error messages).
    Returns (ne, nn, 6, nc) in STRESS_ORDER, Pa.
    """
    _, dN = shape_functions(order, element_node_coordinates(order))
    G, _ = shape_gradients(X, dN, np.ones(dN.shape[0]), first)        # (ne, p, b, j) = dN_b/dx_j at node p
    H = np.einsum("ebik,epbj->epijk", Ue, G, optimize=True)            # du_i/dx_j at node p, field k
    return hooke(H, *lame)


def nodal_stress(mesh, material, U: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """Averaged nodal stress of displacement fields at the chosen nodes.

    mesh : FEMesh (m); material : Material (of the tet4/tet10 mesh) or DeckStress (an imported
    deck's elements and materials); U : (3 n_nodes, nc) fields, DOF 3 i + c, m; nodes : (ns,) node
    indices.  Returns (ns, 6, nc) in STRESS_ORDER, Pa.  Only the elements that touch a chosen node
    are evaluated.
    """
    if isinstance(material, DeckStress):
        return material.nodal_stress(mesh.points, U, nodes)
    nodes = np.asarray(nodes, dtype=np.int64)
    nc = U.shape[1]
    row = np.full(mesh.n_nodes, -1, dtype=np.int64)
    row[nodes] = np.arange(len(nodes))
    elements = np.flatnonzero((row[mesh.cells] >= 0).any(axis=1))
    U3 = np.asarray(U).reshape(mesh.n_nodes, 3, nc)
    total = np.zeros((len(nodes), 6 * nc))
    count = np.zeros(len(nodes))
    for start in range(0, len(elements), CHUNK):
        e = elements[start:start + CHUNK]
        cells = mesh.cells[e]
        s = element_nodal_stress(mesh.points[cells], U3[cells], mesh.order, material.lame, int(e[0]))
        add_to_nodes(total, count, row[cells], s)
    return (total / count[:, None]).reshape(len(nodes), 6, nc)


def surface_nodes(mesh) -> np.ndarray:
    """Indices of the nodes on the outer surface (those of SID.surface), sorted."""

    return np.unique(linear_surface_triangles(mesh))


def stress_nodes(mesh, scope: str, material=None) -> np.ndarray:
    """Node indices of a scope (SCOPES): the outer surface's (of the deck's own element faces for a
    DeckStress ``material``, mid-edge nodes included) or all."""
    if scope != "surface":
        return np.arange(mesh.n_nodes)
    return material.surface_nodes() if isinstance(material, DeckStress) else surface_nodes(mesh)


def stress_modes(mesh, material, Phi_fe: np.ndarray, scope: str = "surface") -> StressModes:
    """The modal stresses of the basis Phi_fe (3 n_nodes, nq) at the surface nodes or all nodes."""
    nodes = stress_nodes(mesh, scope, material)
    modes = nodal_stress(mesh, material, Phi_fe, nodes)
    method = material.method if isinstance(material, DeckStress) else METHOD
    return StressModes(mesh.node_ids[nodes].astype(np.int64), mesh.points[nodes], modes, scope, method)


def stress_check(red, mesh, material, stress: StressModes) -> dict:
    """The modal stresses against the full model's static solution: unit forces at every interface
    master (not held), the full model's relieved deflection (sidprep.reduction.fe_checks) and its
    nodal stress vs sum_k sigma_k q_k with the reduced body's static q = Ke^-1 Phi^T P, at the
    stress nodes off the interface patches (whose stress is that of the rigid coupling, singular
    at the patch border).

    Returns {"stress_static_max_rel_error": largest |sigma_red - sigma_full| over nodes and
    components, relative to the load case's largest |sigma_full|, worst case; "stress_load_cases": n}.
    """

    forces = red.im.master_dofs[:, :3].ravel()
    loads = np.setdiff1d(forces, [] if red.held is None else red.held)
    if not len(loads):
        return {}
    P = np.zeros((red.im.n_model, len(loads)))
    P[loads, np.arange(len(loads))] = 1.0
    U_full = np.asarray(red.im.T @ relieved_static_solve(red, P))
    nodes = stress_nodes(mesh, stress.scope, material)
    away = ~np.isin(nodes, np.concatenate([i.nodes for i in red.im.interfaces]))
    full = nodal_stress(mesh, material, U_full, nodes[away])            # (ns, 6, nl)
    q = (red.Phi_model[loads].T) / ((2 * np.pi * red.basis.frequencies_hz) ** 2)[:, None]
    reduced = np.einsum("sck,kl->scl", stress.modes[away], q)
    err = np.abs(reduced - full).max(axis=(0, 1)) / np.abs(full).max(axis=(0, 1))
    return {"stress_static_max_rel_error": float(err.max()), "stress_load_cases": int(len(loads))}


def structured_stress_check(checks: dict) -> dict:
    """The stress check as a named check {"FE stress": Check} (sidprep.sid.check) for the SID metadata."""
    if "stress_static_max_rel_error" not in checks:
        return {}
    return {"FE stress": Check.measured(
        checks["stress_static_max_rel_error"], STRESS_CHECK_TOL,
        f"modal stresses under {checks['stress_load_cases']} unit master forces vs the full model's static "
        "stress, largest error relative to the load case's largest stress", "warning")}
