"""Interface patches coupled to 6-DOF master nodes (RBE2 rigid spiders, RBE3 averaging elements).

An interface is a patch of FE nodes (a named node set or a geometric selection) and one master
node with 3 translations and 3 rotations, placed at the patch centroid or at a given point.

* RBE2 (rigid): every patch node follows the master rigidly, u_i = u_m + theta_m x r_i,
  r_i = x_i - x_m.  The patch DOFs are eliminated.
* RBE3 (distributing, sid-spec 4.6 option 2): the master motion is the weighted least-squares
  rigid fit of the patch motion, weights = tributary area of the patch's boundary faces.  The
  patch keeps its flexibility.  As Nastran's "UM" choice, six well-conditioned patch DOFs are
  made dependent and replaced by the six master DOFs: the map (other DOFs, master) -> all FE DOFs
  is square and invertible, so K_model = T^T K T is as SPD as K (CHOLMOD-able) and adds no
  stiffness at all.

Both are realised by one sparse transformation u_FE = T u_model; the model DOFs are the retained
FE DOFs (original order) followed by 6 DOFs per interface master [ux uy uz rx ry rz].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from sidprep.errors import InputError
from sidprep.fe.topology import TET10_EDGES, boundary_faces


KINDS = ("rbe2", "rbe3")
#: a patch whose weighted second moment of lever arms has a condition number above this is
#: treated as collinear (cannot carry rotations)
COLLINEAR_COND = 1e8


@dataclass(frozen=True)
class Interface:
    """One interface: patch nodes coupled to a 6-DOF master.

    name : str; nodes : (k,) int64 node indices of the patch; master_point : (3,) position of
    the master in the mesh frame (m); kind : "rbe2" or "rbe3", or "node": the master is an FE node
    pair that already has 6 DOFs (nodes = [translation node, rotation node], e.g. a rigid body's
    reference and rotation nodes of an imported model); weights : (k,) RBE3 weights (tributary
    areas, m^2), uniform when None; rotations : (r,) rotation nodes of an imported model (their 3
    DOFs are a 6-DOF node's rotations) that an RBE2 ties to the master's rotation (Nastran RBE2 with
    components 123456), none when None.
    """

    name: str
    nodes: np.ndarray
    master_point: np.ndarray
    kind: str = "rbe2"
    weights: np.ndarray | None = None
    rotations: np.ndarray | None = None


@dataclass(frozen=True)
class InterfaceModel:
    """The transformation u_FE = T u_model and where the masters are.

    T : (3n, n_model) csr; master_dofs : (n_if, 6) model DOF indices of each master;
    retained : FE DOF of each of the first len(retained) model DOFs;
    interfaces : the Interface objects, in master order.
    """

    T: sp.csr_matrix
    master_dofs: np.ndarray
    retained: np.ndarray
    interfaces: tuple[Interface, ...]

    @property
    def n_model(self) -> int:
        return self.T.shape[1]

    def project(self, A: sp.spmatrix) -> sp.csr_matrix:
        """T^T A T, the FE matrix A in model DOFs."""
        return (self.T.T @ (A @ self.T)).tocsr()


# ---------------------------------------------------------------------------------------------
# node selection
# ---------------------------------------------------------------------------------------------

def nodes_on_plane(points, point, normal, tol):
    """Indices of nodes within ``tol`` of the plane through ``point`` with ``normal``."""
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    return np.flatnonzero(np.abs((points - np.asarray(point, float)) @ n) <= tol)


def nodes_on_cylinder(points, point, axis, radius, tol):
    """Indices of nodes within ``tol`` of the cylinder surface (axis through ``point``)."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    d = points - np.asarray(point, float)
    r = np.linalg.norm(d - np.outer(d @ a, a), axis=1)
    return np.flatnonzero(np.abs(r - radius) <= tol)


def nodes_on_sphere(points, center, radius, tol):
    """Indices of nodes within ``tol`` of the sphere surface."""
    r = np.linalg.norm(points - np.asarray(center, float), axis=1)
    return np.flatnonzero(np.abs(r - radius) <= tol)


#: geometric selections: type -> (function, its parameters after ``points``)
SELECTORS = {"plane": (nodes_on_plane, ("point", "normal", "tol")),
             "cylinder": (nodes_on_cylinder, ("point", "axis", "radius", "tol")),
             "sphere": (nodes_on_sphere, ("center", "radius", "tol"))}
SELECTIONS = tuple(SELECTORS)


def select_patch(mesh, selection) -> np.ndarray:
    """Node indices of a patch: a node-set name, or a dict {"type": plane|cylinder|sphere, ...}."""
    if isinstance(selection, str):
        if selection not in mesh.node_sets:
            raise InputError(f"interface '{selection}': no such node set in {mesh.source or 'the mesh'}; "
                             f"valid: {', '.join(sorted(mesh.node_sets)) or '(none)'} or a plane/cylinder/sphere selection")
        return np.asarray(mesh.node_sets[selection], dtype=np.int64)
    kind = selection.get("type")
    if kind not in SELECTORS:
        raise InputError(f"interface selection type {kind!r} is unknown; valid: {', '.join(SELECTIONS)}")
    func, keys = SELECTORS[kind]
    missing = [k for k in keys if k not in selection]
    if missing:
        raise InputError(f"interface selection '{kind}' needs {', '.join(keys)}; missing {', '.join(missing)}")
    return func(mesh.points, *(selection[k] for k in keys))


def tributary_areas(mesh, nodes: np.ndarray) -> np.ndarray:
    """Boundary-face area attributed to each patch node, (k,) m^2 (zero for interior nodes).

    Every boundary triangle whose corners all lie in the patch gives a third of its area to each
    corner (tet4); for tet10 each face is split into its 4 sub-triangles through the mid-edge
    nodes first (corners get A/12, mid-edge nodes A/4).
    """
    faces = linear_surface_triangles(mesh)
    in_patch = np.zeros(mesh.n_nodes, bool)
    in_patch[nodes] = True
    faces = faces[in_patch[faces].all(axis=1)]
    x = mesh.points
    area = 0.5 * np.linalg.norm(np.cross(x[faces[:, 1]] - x[faces[:, 0]], x[faces[:, 2]] - x[faces[:, 0]]), axis=1)
    node_area = np.bincount(faces.ravel(), weights=np.repeat(area / 3.0, 3), minlength=mesh.n_nodes)
    return node_area[nodes]


def linear_surface_triangles(mesh) -> np.ndarray:
    """Outer-surface triangles, outward: the corner triangles (tet4), or each 6-node face split
    into its 4 sub-triangles through the mid-edge nodes (tet10), or the model's own ``surface``
    (imported decks of other elements); (nf or 4nf, 3) int64."""

    if mesh.surface is not None:
        return mesh.surface
    faces = boundary_faces(mesh)
    if mesh.order == 1:
        return faces
    n = mesh.n_nodes
    cells = mesh.cells
    ends = np.array(TET10_EDGES)
    a, b = cells[:, ends[:, 0]].ravel(), cells[:, ends[:, 1]].ravel()
    keys = np.minimum(a, b) * n + np.maximum(a, b)
    order = np.argsort(keys)
    keys, mids = keys[order], cells[:, 4:].ravel()[order]

    def mid(i, j):
        k = np.minimum(i, j) * n + np.maximum(i, j)
        return mids[np.searchsorted(keys, k)]

    v0, v1, v2 = faces.T
    m01, m12, m02 = mid(v0, v1), mid(v1, v2), mid(v0, v2)
    return np.concatenate([np.stack(t, axis=1) for t in
                           ((v0, m01, m02), (m01, v1, m12), (m02, m12, v2), (m01, m12, m02))])


def make_interface(mesh, name: str, selection=None, kind: str = "rbe2", master_point=None, rows=None) -> Interface:
    """Build an Interface from a node set (default: the set called ``name``) or a geometric selection.

    The master sits at ``master_point`` or, by default, at the area-weighted centroid of the patch.
    ``rows`` (n,) bool: the node rows a patch may hold (an imported model's own nodes, not its
    rotation or auxiliary nodes at the same places); None: all.
    Raises InputError when the patch cannot carry 6 DOF (< 3 nodes, collinear).
    """
    kind = kind.lower()
    if kind not in KINDS:
        raise InputError(f"interface '{name}': kind {kind!r} is unknown; valid: {', '.join(KINDS)}")
    nodes = np.unique(select_patch(mesh, name if selection is None else selection))
    nodes = nodes if rows is None else nodes[rows[nodes]]
    area = tributary_areas(mesh, nodes) if len(nodes) else np.zeros(0)
    weights = area if area.sum() > 0 else np.ones(len(nodes))
    check_patch(name, mesh.points[nodes], weights)
    centroid = weights @ mesh.points[nodes] / weights.sum()
    point = centroid if master_point is None else np.asarray(master_point, float).reshape(3)
    return Interface(name, nodes, point, kind, weights)


def check_patch(name: str, x: np.ndarray, weights: np.ndarray) -> None:
    """InputError unless the weighted patch (k, 3) has >= 3 nodes that are not collinear."""
    used = weights > 0
    if used.sum() < 3:
        raise InputError(f"interface '{name}': the patch has {int(used.sum())} node(s); it needs at least 3 "
                         "non-collinear nodes to carry 6 DOF — select a larger patch")
    A = lever_arm_moment(x[used], weights[used])
    if np.linalg.cond(A) > COLLINEAR_COND:
        raise InputError(f"interface '{name}': the patch nodes are collinear and cannot carry rotations about "
                         "that line — select a patch that spans an area")


def lever_arm_moment(x: np.ndarray, w: np.ndarray) -> np.ndarray:
    """A = sum_i w_i rho~_i^T rho~_i, rho_i = x_i - weighted mean (sid-spec 4.6 option 2); (3, 3)."""
    rho = x - w @ x / w.sum()
    return np.eye(3) * np.einsum("i,ij,ij->", w, rho, rho) - np.einsum("i,ij,ik->jk", w, rho, rho)


def rigid_rows(r: np.ndarray) -> np.ndarray:
    """(k, 3, 6): u_i = [I, -skew(r_i)] [u_m; theta_m] = u_m + theta_m x r_i for lever arms r (k, 3)."""
    k = len(r)
    R = np.zeros((k, 3, 6))
    R[:, [0, 1, 2], [0, 1, 2]] = 1.0
    # -skew(r) theta = theta x r
    R[:, 0, 4], R[:, 0, 5] = r[:, 2], -r[:, 1]
    R[:, 1, 3], R[:, 1, 5] = -r[:, 2], r[:, 0]
    R[:, 2, 3], R[:, 2, 4] = r[:, 1], -r[:, 0]
    return R


def rbe3_averaging(x: np.ndarray, w: np.ndarray, master_point: np.ndarray) -> np.ndarray:
    """W (6, 3k): master [u; theta] = W u_patch, the weighted least-squares rigid fit (sid-spec 4.6-2).

    u_bar = sum w_i u_i / sum w_i; theta = A^-1 sum w_i rho_i x u_i; master translation
    u_bar + theta x (x_m - x_bar).
    """
    xbar = w @ x / w.sum()
    rho = x - xbar
    Ainv = np.linalg.inv(lever_arm_moment(x, w))
    k = len(x)
    # theta = Ainv sum_i w_i skew(rho_i) u_i
    skews = -rigid_rows(rho)[:, :, 3:]          # skew(rho_i), (k, 3, 3)
    Wr = np.einsum("ab,i,ibc->aic", Ainv, w, skews).reshape(3, 3 * k)
    Wt = np.kron(w / w.sum(), np.eye(3)).reshape(3, 3 * k)
    d = master_point - xbar
    Wt = Wt + rigid_rows(d[None])[0][:, 3:] @ Wr       # + theta x d = -skew(d) theta
    return np.vstack([Wt, Wr])


def best_columns(A: np.ndarray, k: int) -> np.ndarray:
    """Indices of k columns of A (m, n) whose sub-matrix is best conditioned (pivoted QR)."""
    _, piv = sla.qr(A, mode="r", pivoting=True)
    return np.sort(piv[:k])


def interface_model(n_nodes: int, interfaces, points: np.ndarray) -> InterfaceModel:
    """The sparse transformation u_FE = T u_model for a list of interfaces (module docstring)."""
    interfaces = tuple(interfaces)
    n_dof = 3 * n_nodes
    owner = np.full(n_nodes, -1)
    for i, itf in enumerate(interfaces):
        held = np.r_[itf.nodes, _rotations(itf)]
        clash = owner[held] >= 0
        if clash.any():
            other = interfaces[owner[held][clash][0]].name
            raise InputError(f"interfaces '{other}' and '{itf.name}' share {int(clash.sum())} node(s); "
                             "patches must not overlap — shrink one of the selections")
        owner[held] = i
    dependent = np.zeros(n_dof, bool)
    deps, averaging = [], []                           # per interface: dependent FE DOFs, RBE3 W
    for itf in interfaces:
        dofs = (3 * itf.nodes[:, None] + np.arange(3)).ravel()
        W = None if itf.kind in ("rbe2", "node") else rbe3_averaging(points[itf.nodes], _weights(itf), itf.master_point)
        d = dofs if W is None else dofs[best_columns(W, 6)]
        dependent[d] = True
        dependent[(3 * _rotations(itf)[:, None] + np.arange(3)).ravel()] = True
        deps.append(d), averaging.append(W)
    retained = np.flatnonzero(~dependent)
    col = np.full(n_dof, -1)
    col[retained] = np.arange(len(retained))
    master_dofs = len(retained) + np.arange(6 * len(interfaces)).reshape(-1, 6)
    rows, cols, vals = [retained], [col[retained]], [np.ones(len(retained))]
    for itf, d, W, m in zip(interfaces, deps, averaging, master_dofs):
        if itf.kind == "node":                             # the FE code's own 6-DOF node: its DOFs are the master
            rows.append(d), cols.append(m), vals.append(np.ones(6))
        elif W is None:
            R = rigid_rows(points[itf.nodes] - itf.master_point).reshape(-1, 6)
            rows.append(np.repeat(d, 6)), cols.append(np.tile(m, len(d))), vals.append(R.ravel())
            r = (3 * _rotations(itf)[:, None] + np.arange(3)).ravel()      # theta_r = theta_master
            rows.append(r), cols.append(np.tile(m[3:], len(r) // 3)), vals.append(np.ones(len(r)))
        else:
            dofs = (3 * itf.nodes[:, None] + np.arange(3)).ravel()
            is_dep = np.isin(dofs, d)
            Wd_inv = np.linalg.inv(W[:, is_dep])                 # u_d = Wd^-1 (u_m - W_o u_o)
            C = np.hstack([Wd_inv, -Wd_inv @ W[:, ~is_dep]])
            c = np.concatenate([m, col[dofs[~is_dep]]])
            rows.append(np.repeat(dofs[is_dep], len(c))), cols.append(np.tile(c, 6)), vals.append(C.ravel())
    T = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(n_dof, len(retained) + 6 * len(interfaces)))
    return InterfaceModel(T, master_dofs, retained, interfaces)


def _rotations(itf: Interface) -> np.ndarray:
    return np.zeros(0, np.int64) if itf.rotations is None else np.asarray(itf.rotations, np.int64)


def _weights(itf: Interface) -> np.ndarray:
    return np.ones(len(itf.nodes)) if itf.weights is None else itf.weights


def rigid_modes_model(im: InterfaceModel, points: np.ndarray, rotational: np.ndarray | None = None) -> np.ndarray:
    """(n_model, 6) rigid-body motions [t; theta] about the origin in model DOFs.

    FE DOFs: u = t + theta x x, the rotation theta on the rows ``rotational`` (n_nodes,) bool (a
    6-DOF node's rotations, FEMesh.rotational); master DOFs: translation t + theta x x_m, rotation theta.
    """
    rows = rigid_rows(points)
    if rotational is not None:
        rows[rotational] = 0.0
        rows[rotational, :, 3:] = np.eye(3)
    R = np.zeros((im.n_model, 6))
    R[:len(im.retained)] = rows.reshape(-1, 6)[im.retained]
    for itf, m in zip(im.interfaces, im.master_dofs):
        R[m[:3]] = rigid_rows(itf.master_point[None])[0]
        R[m[3:], 3:] = np.eye(3)
    return R


def tied_interface_model(im: InterfaceModel, ties) -> InterfaceModel:
    """The interface model with the tied nodes' constraints imposed (sidprep.fe.ties.Ties, or the
    constraint equations of an import, sidprep.fe.matrices.constraints.Constraints):
    u_FE = S T u_model (``ties.dof_map``), the dependent DOFs' own columns dropped.  A tied node
    may be neither in an interface patch nor the master of another tie (one-line InputError)."""

    if ties is None:
        return im
    for itf in im.interfaces:
        clash = np.intersect1d(itf.nodes, ties.slaves)
        if len(clash):
            raise InputError(f"interface '{itf.name}' holds {len(clash)} tied node(s) (node indices from "
                             f"{int(clash[0])}); put the interface on the master side of the tie")
    if np.isin(ties.masters, ties.slaves).any():
        raise InputError("ties: a tied node is also a master node of another tie; tie each surface to an "
                         "untied one (chains of ties are not resolved)")
    n_nodes = im.T.shape[0] // 3
    keep = ~np.isin(im.retained, ties.dependent_dofs())
    cols = np.r_[np.flatnonzero(keep), np.arange(len(im.retained), im.T.shape[1])]
    T = (ties.dof_map(n_nodes) @ im.T)[:, cols].tocsr()
    return InterfaceModel(T, im.master_dofs - int((~keep).sum()), im.retained[keep], im.interfaces)
