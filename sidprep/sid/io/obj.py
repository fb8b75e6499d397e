"""Wavefront OBJ surfaces (body frame K): ``write_obj`` / ``read_obj``, the geometry of a SID body or
of a rigid body in a scene.

OBJ has no version of its own; the writer states the length unit in its header comment."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sidprep.errors import InputError, ascii_line
from sidprep.sid.io.atomic import atomic_path


def write_obj(path, points, triangles, *, length_unit: str = "m", comment: str = "") -> Path:
    """Write a triangle surface as Wavefront OBJ, atomically.

    Parameters
    ----------
    points : (ns, 3) float
        Vertex positions in the body frame K, in ``length_unit``.
    triangles : (nf, 3) int
        0-based vertex indices, counter-clockwise seen from outside (outward normals).
    """
    points = np.asarray(points, dtype=float)
    triangles = np.asarray(triangles, dtype=np.int64)
    if points.ndim != 2 or points.shape[1] != 3 or triangles.ndim != 2 or triangles.shape[1] != 3:
        raise InputError(f"{path}: OBJ export needs points (n, 3) and triangles (m, 3), got "
                         f"{points.shape} and {triangles.shape}; pass a triangulated surface")
    if triangles.size and (triangles.min() < 0 or triangles.max() >= len(points)):
        raise InputError(f"{path}: triangle indices outside 0..{len(points) - 1}; fix the surface")
    header = [f"# sidprep surface, body frame K, units: {length_unit}",
              f"# {len(points)} vertices, {len(triangles)} triangles"]
    if comment:
        header.append(f"# {ascii_line(comment)}")
    lines = header + [f"v {x:.12g} {y:.12g} {z:.12g}" for x, y, z in points]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in triangles]
    with atomic_path(path) as tmp:
        tmp.write_text("\n".join(lines) + "\n", encoding="ascii")
    return Path(path)


def read_obj(path) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (n, 3) and triangles (nf, 3) int64 of a Wavefront OBJ file (polygons fanned)."""
    # trimesh costs 1.8 s to import (measured, python -X importtime): only the commands that read
    # an OBJ pay it, not every reader of SID files
    import trimesh  # deferred: 1.8 s import, OBJ only

    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such OBJ file; check the path")
    try:
        mesh = trimesh.load(str(path), force="mesh", process=False)
    except (OSError, ValueError, IndexError, KeyError, TypeError) as exc:   # a face on a vertex the file lacks: IndexError
        raise InputError(f"{path}: cannot read the OBJ surface ({type(exc).__name__}: {exc}); give a triangulated "
                         "Wavefront OBJ file whose faces name its own vertices") from None
    points, faces = np.asarray(mesh.vertices, float), np.asarray(mesh.faces, np.int64)
    if not len(faces):
        raise InputError(f"{path}: the OBJ file has no faces; give a triangulated surface")
    if faces.min() < 0 or faces.max() >= len(points) or not np.isfinite(points).all():
        raise InputError(f"{path}: faces name vertices outside 1..{len(points)} or vertices are not finite; "
                         "give a triangulated Wavefront OBJ file whose faces name its own vertices")
    return points, faces
