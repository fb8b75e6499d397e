"""Paths through or on a meshed body, along which loads move (Hartweg and Heckmann 2012).

A path is a smooth curve in the body frame K (the mesh coordinates) given by

* points it passes through, ``NAME:x0,y0,z0:x1,y1,z1[:x2,y2,z2 ...][:n]``, or
* a node set of the mesh ordered along a direction, ``NAME:nodes=SET:dir=x[:n]`` (``dir`` x, y, z,
  -x, ... or a vector ``dx,dy,dz``; e.g. the nodes of one edge of the body),

sampled at n points (default ``DEFAULT_PATH_POINTS``) of uniform arc length s.

The curve through the k points is the cubic spline in their chord length, not-a-knot ends
(scipy's ``CubicSpline``): two points give the straight segment, three a parabola, more a C2
curve; points on a straight line give that line, uniformly run through.  Not a polyline: the
solver differentiates the path in s (its tangent, and Phi' in the convective terms of moving
masses), and a corner would make the tangent jump and the path's curvature infinite; give a
corner as two paths.  The arc length of the spline is integrated by Gauss-Legendre quadrature
and inverted by Newton steps, so the samples are equally spaced in s to round-off.

At each sample the full-resolution mode shapes are interpolated with the element's own shape
functions (P1 / P2 on straight-sided tetrahedra, barycentric coordinates L):

    phi(x) = sum_i N_i(L(x)) Phi_i,       psi(x) = 1/2 curl phi(x)

(corner nodes N = L_a (2 L_a - 1), mid-edge nodes N = 4 L_a L_b for tet10; N = L_a for tet4),
psi the small rotation of the material at x.  Points on a curved surface lie slightly outside the
straight-sided (faceted) elements; a point outside every element but within
``SURFACE_TOL_FRACTION`` of the nearest element's longest edge takes the mode shapes of that
element at its barycentric coordinates clamped to the element (its stored position stays the given
one); a point farther out is an InputError.  The result is a ``sidprep.sid.model.BodyPath`` stored in the
SID (``SID.paths``, HDF5 ``/paths``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sidprep.errors import InputError
from sidprep.fe.topology import TET10_EDGES
from sidprep.sid.model import BodyPath


#: samples of a path unless the spec gives their number
DEFAULT_PATH_POINTS = 201
#: most samples of a path (each holds 6 nq mode-shape values; 1e8 samples ran past 4 GB)
MAX_PATH_POINTS = 100_000
#: a point belongs to an element when its barycentric coordinates are >= -this
INSIDE_TOL = 1e-9
#: a point outside every element is accepted (as on the body's surface) when it lies within this
#: fraction of the nearest element's longest edge: a facet of edge h sits h^2 / (8 R) inside a
#: surface of radius R, so this accepts every surface curved no tighter than R = 1.25 h
SURFACE_TOL_FRACTION = 0.1
#: Gauss-Legendre points on each of ARC_SUBDIVISIONS pieces of every spline interval (the arc
#: length of a cubic to round-off)
ARC_GAUSS_POINTS, ARC_SUBDIVISIONS = 8, 16
#: Newton steps inverting s(t) from the linear guess within a piece (quadratic convergence)
ARC_NEWTON_STEPS = 4
#: node positions along ``dir`` closer than this fraction of the set's span are the same position
NODE_ORDER_TOL = 1e-9
#: the spec forms, for error messages
PATH_FORMS = "NAME:x0,y0,z0:x1,y1,z1[:x2,y2,z2 ...][:n] or NAME:nodes=SET:dir=x[:n]"
#: ``dir`` names
AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}


@dataclass(frozen=True)
class PathSpec:
    """A parsed ``--path``: ``name``; ``n`` samples; either ``points`` (k, 3) the points the curve
    passes through (m), or ``nodes`` a node-set name with ``direction`` (3,) a unit vector."""

    name: str
    n: int = DEFAULT_PATH_POINTS
    points: np.ndarray | None = None
    nodes: str | None = None
    direction: np.ndarray | None = None


@dataclass(frozen=True)
class PathSamples:
    """A path's samples located in the mesh: ``s`` (n,) arc length, m; ``points`` (n, 3), m;
    ``element`` (n,) the element holding each; ``L`` (n, 4) its barycentric coordinates there."""

    name: str
    s: np.ndarray
    points: np.ndarray
    element: np.ndarray
    L: np.ndarray


def parse_path(spec: str, length_to_m: float = 1.0) -> PathSpec:
    """The PathSpec of a ``--path`` string (module doc), coordinates times ``length_to_m`` (m);
    a one-line InputError naming the forms otherwise."""
    name, *fields = str(spec).split(":")
    try:
        n = int(fields.pop()) if fields and fields[-1].strip().lstrip("+-").isdigit() else DEFAULT_PATH_POINTS
        if not name or not 2 <= n <= MAX_PATH_POINTS:
            raise ValueError(f"needs a name and 2 <= n <= {MAX_PATH_POINTS} samples")
        keyed = dict(f.split("=", 1) for f in fields if "=" in f)
        if keyed:
            return node_path_spec(name, n, keyed, len(fields))
        points = np.array([[float(v) for v in f.split(",")] for f in fields]) * length_to_m
        if len(points) < 2 or points.shape[1:] != (3,):
            raise ValueError("needs two or more points of 3 coordinates")
        if not np.isfinite(points).all():
            raise ValueError("coordinates must be finite numbers")
        if (np.linalg.norm(np.diff(points, axis=0), axis=1) == 0.0).any():
            raise ValueError("two consecutive points are the same")
    except ValueError as exc:
        raise InputError(f"path {spec!r}: {exc}; write {PATH_FORMS}, e.g. axis:0,0.025,0.04:1,0.025,0.04") from None
    return PathSpec(name, n, points=points)


def node_path_spec(name: str, n: int, keyed: dict, n_fields: int) -> PathSpec:
    """PathSpec of the fields ``nodes=SET`` and ``dir=...`` (ValueError when others are mixed in)."""
    if set(keyed) != {"nodes", "dir"} or n_fields != 2:
        raise ValueError("a node path needs exactly nodes=SET and dir=x|y|z|-x|...|dx,dy,dz")
    direction = parse_direction(keyed["dir"])
    return PathSpec(name, n, nodes=keyed["nodes"], direction=direction / np.linalg.norm(direction))


def parse_direction(text: str) -> np.ndarray:
    """(3,) vector of ``x``, ``y``, ``z``, ``-x``, ... or ``dx,dy,dz``; ValueError otherwise."""
    key = text.strip().lower()
    axis = key[1:] if key.startswith("-") else key
    if axis in AXES:
        return (-1.0 if axis != key else 1.0) * np.array(AXES[axis])
    try:
        direction = np.array([float(v) for v in key.split(",")])
    except ValueError:
        direction = np.zeros(0)
    if direction.shape != (3,) or not np.linalg.norm(direction) > 0:
        raise ValueError(f"dir={text} is not a direction (x, y, z, -x, ... or dx,dy,dz)")
    return direction


def ordered_node_points(mesh, spec: PathSpec) -> np.ndarray:
    """(k, 3) positions of the node set ``spec.nodes``, ordered along ``spec.direction``."""
    if spec.nodes not in mesh.node_sets:
        raise InputError(f"path {spec.name!r}: no node set {spec.nodes!r} in {mesh.source or 'the mesh'}; valid: "
                         f"{', '.join(sorted(mesh.node_sets)) or '(none)'}")
    nodes = np.asarray(mesh.node_sets[spec.nodes], dtype=np.int64)
    along = mesh.points[nodes] @ spec.direction
    if len(nodes) < 2:
        raise InputError(f"path {spec.name!r}: node set {spec.nodes!r} has {len(nodes)} node(s); a path needs two "
                         "or more (e.g. the nodes of one edge)")
    order = np.argsort(along, kind="stable")
    gaps = np.diff(along[order])
    k = int(np.argmin(gaps))
    if gaps[k] <= NODE_ORDER_TOL * np.ptp(along):
        a, b = mesh.node_ids[nodes[order[k:k + 2]]]
        raise InputError(f"path {spec.name!r}: nodes {a} and {b} of node set {spec.nodes!r} lie at the same position "
                         "along dir; give a node set along a line (e.g. the nodes of one edge) and its direction")
    return mesh.points[nodes[order]]


def through_points(mesh, spec: PathSpec) -> np.ndarray:
    """(k, 3) the points the path's curve passes through, in order, m."""
    return spec.points if spec.points is not None else ordered_node_points(mesh, spec)


def smooth_curve(points: np.ndarray):
    """The cubic spline c(t) through ``points`` (k, 3), t their cumulative chord length (module doc)."""
    from scipy.interpolate import CubicSpline  # deferred: scipy.interpolate costs 0.37 s of every reduce, paths only

    t = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
    return CubicSpline(t, points, bc_type="not-a-knot")


def arc_length(curve, t0: np.ndarray, t1: np.ndarray) -> np.ndarray:
    """Arc length of ``curve`` from t0 to t1 (arrays of one shape), Gauss-Legendre quadrature."""
    xg, wg = np.polynomial.legendre.leggauss(ARC_GAUSS_POINTS)
    half = 0.5 * (np.asarray(t1) - np.asarray(t0))
    t = (0.5 * (np.asarray(t0) + np.asarray(t1)))[..., None] + half[..., None] * xg
    return half * (np.linalg.norm(curve(t, 1), axis=-1) @ wg)


def uniform_arc_length_samples(points: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(s (n,), x (n, 3)): n points of the smooth curve through ``points`` (k, 3) at equal steps
    of arc length s from 0 to the curve's length, m."""
    curve = smooth_curve(points)
    knots = curve.x
    table = np.concatenate([np.linspace(a, b, ARC_SUBDIVISIONS, endpoint=False) for a, b in zip(knots[:-1], knots[1:])]
                           + [knots[-1:]])
    S = np.concatenate([[0.0], np.cumsum(arc_length(curve, table[:-1], table[1:]))])
    s = np.linspace(0.0, S[-1], n)
    piece = np.clip(np.searchsorted(S, s, side="right") - 1, 0, len(table) - 2)
    lo, hi = table[piece], table[piece + 1]
    t = lo + (s - S[piece]) / (S[piece + 1] - S[piece]) * (hi - lo)
    for _ in range(ARC_NEWTON_STEPS):
        speed = np.linalg.norm(curve(t, 1), axis=-1)
        t = np.clip(t - (S[piece] + arc_length(curve, lo, t) - s) / speed, lo, hi)
    x = curve(t)
    x[[0, -1]] = points[[0, -1]]
    return s, x


def element_geometry(mesh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(corners (ne, 4, 3), inverse edge matrices (ne, 3, 3), longest edges (ne,)) of the
    straight-sided elements."""
    corners = mesh.points[mesh.cells[:, :4]]
    Tinv = np.linalg.inv((corners[:, 1:] - corners[:, :1]).transpose(0, 2, 1))
    edges = np.linalg.norm(corners[:, [1, 2, 2, 3, 3, 3]] - corners[:, [0, 0, 1, 0, 1, 2]], axis=2)
    return corners, Tinv, edges.max(axis=1)


def barycentric_all(corners: np.ndarray, Tinv: np.ndarray, p: np.ndarray) -> np.ndarray:
    """(ne, 4) barycentric coordinates of the point p (3,) in every element."""
    l123 = np.einsum("eij,ej->ei", Tinv, p - corners[:, 0])
    return np.concatenate([1.0 - l123.sum(axis=1, keepdims=True), l123], axis=1)


def clamped_distance(corners: np.ndarray, lam: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(distances (ne,), clamped coordinates (ne, 4)): p's barycentric coordinates ``lam`` with the
    negative ones set to 0 and renormalised (a point of each element), and p's distance to it, m."""
    clamped = np.maximum(lam, 0.0)
    clamped /= clamped.sum(axis=1, keepdims=True)
    return np.linalg.norm(np.einsum("ea,eac->ec", clamped, corners) - p, axis=1), clamped


def locate(mesh, x: np.ndarray, name: str = "path") -> tuple[np.ndarray, np.ndarray]:
    """(element (n,), L (n, 4)) holding each point x (n, 3): the element with the largest smallest
    barycentric coordinate, or for a point on a curved surface (module doc) the nearest element
    and the clamped coordinates; InputError for a point farther outside."""
    corners, Tinv, longest = element_geometry(mesh)
    element, L = np.zeros(len(x), np.int64), np.zeros((len(x), 4))
    for k, p in enumerate(x):
        lam = barycentric_all(corners, Tinv, p)
        inside = np.flatnonzero(lam.min(axis=1) >= -INSIDE_TOL)
        if inside.size:
            element[k] = inside[np.argmax(lam[inside].min(axis=1))]
            L[k] = lam[element[k]]
            continue
        distance, clamped = clamped_distance(corners, lam, p)
        element[k] = np.argmin(distance)
        if distance[element[k]] > SURFACE_TOL_FRACTION * longest[element[k]]:
            raise InputError(f"path {name!r}: the point ({p[0]:.6g}, {p[1]:.6g}, {p[2]:.6g}) m lies "
                             f"{distance[element[k]]:.3g} m outside the mesh (more than {SURFACE_TOL_FRACTION:g} of "
                             "the nearest element's edge); give points inside the body or on its surface")
        L[k] = clamped[element[k]]
    return element, L


def path_samples(mesh, spec: PathSpec) -> PathSamples:
    """The samples of ``spec`` on ``mesh`` (module doc), located in its elements; InputErrors for
    unknown node sets and points outside, before any FE work."""
    s, x = uniform_arc_length_samples(through_points(mesh, spec), spec.n)
    element, L = locate(mesh, x, spec.name)
    return PathSamples(spec.name, s, x, element, L)


def located_paths(mesh, specs, length_to_m: float = 1.0) -> list[PathSamples]:
    """PathSamples of the ``--path`` strings ``specs`` (coordinates times ``length_to_m``, m);
    InputErrors for bad specs, a name given twice, unknown node sets and points outside."""
    parsed = [parse_path(spec, length_to_m) for spec in specs]
    names = [p.name for p in parsed]
    twice = sorted({name for name in names if names.count(name) > 1})
    if twice:
        raise InputError(f"path {twice[0]!r} is given twice; give each path its own name")
    return [path_samples(mesh, p) for p in parsed]


def shape_functions(L: np.ndarray, order: int, gradL: np.ndarray):
    """Values N (nn,) and gradients dN (nn, 3) of the element's nodal shape functions at the
    barycentric coordinates L (4,), with gradL (4, 3) the gradients of L."""
    if order == 1:
        return L.copy(), gradL.copy()
    N, dN = np.zeros(10), np.zeros((10, 3))
    for a in range(4):
        N[a], dN[a] = L[a] * (2 * L[a] - 1), (4 * L[a] - 1) * gradL[a]
    for k, (a, b) in enumerate(TET10_EDGES):
        N[4 + k], dN[4 + k] = 4 * L[a] * L[b], 4 * (L[a] * gradL[b] + L[b] * gradL[a])
    return N, dN


def fe_path(mesh, Phi_fe: np.ndarray, samples: PathSamples) -> BodyPath:
    """The BodyPath of ``samples`` with the full mode shapes Phi_fe (3 n_nodes, nq) interpolated
    at them (module doc): phi, psi (n, 3, nq)."""
    nq = Phi_fe.shape[1]
    shapes = Phi_fe.reshape(mesh.n_nodes, 3, nq)
    n = len(samples.s)
    phi, psi = np.zeros((n, 3, nq)), np.zeros((n, 3, nq))
    for k, (e, L) in enumerate(zip(samples.element, samples.L)):
        nodes = mesh.cells[e]
        corners = mesh.points[nodes[:4]]
        g123 = np.linalg.inv((corners[1:] - corners[:1]).T)            # rows: grad L1..L3
        N, dN = shape_functions(L, mesh.order, np.vstack([-g123.sum(axis=0), g123]))
        u = shapes[nodes]                                              # (nn, 3, nq)
        phi[k] = np.einsum("i,icq->cq", N, u)
        grad = np.einsum("icq,id->cdq", u, dN)                         # d u_c / d x_d
        psi[k] = 0.5 * np.stack([grad[2, 1] - grad[1, 2], grad[0, 2] - grad[2, 0], grad[1, 0] - grad[0, 1]])
    return BodyPath(samples.s, samples.points, phi, psi)
