"""Animation export: a compact ParaView series (``.pvd``): one ``.vtu`` file per shown time, at
most ``MAX_VTU_FILES`` of them (every k-th output sample; a 10 s run at 100 samples/s wrote 1001
files / 71 MB before, now 100 files).

Each VTU holds the surfaces of all bodies at that time: a flexible body's deformed surface
x = r_O + A (c + S q) from ``SID.surface`` (points c, shapes S (ns, 3, nq)), with the point field
``displacement`` = A S q (elastic part, inertial components, m) and, when its SID has modal
stresses, ``von_mises`` (Pa, sidprep.sid.stress; 0 on bodies without); a rigid body's OBJ surface
x = r_O + A p (displacement 0).  A flexible body without surface modes (e.g. read from an ASCII
SID_FEM file) is shown by its SID node points, as vertex cells.  The cell field ``body`` numbers
the bodies in scene order.  Open the ``.pvd`` in ParaView and press play.
"""

from __future__ import annotations

import os
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from sidprep.errors import InputError
from sidprep.sid.io.atomic import atomic_path
from sidprep.sid.surface import Surface, surface_motion, surface_von_mises


#: the series holds at most this many time steps (files): every k-th output sample
MAX_VTU_FILES = 100


def frame_mesh(result, surfaces: dict[str, Surface], i: int):
    """meshio.Mesh of all bodies at output index ``i``."""
    import meshio  # deferred: 0.07 CPU-s of import, needed only to write meshes

    points, disp, cells, body_ids, vm = [], [], [], [], []
    offset = 0
    for k, (name, surf) in enumerate(surfaces.items()):
        b = result.bodies[name]
        x, u = surface_motion(surf, b.position[i:i + 1], b.rotation[i:i + 1], b.q[i:i + 1])
        points.append(x[0])
        disp.append(u[0])
        vm.append(np.zeros(len(x[0])) if surf.stress is None else surface_von_mises(surf, b.q[i:i + 1])[0])
        if len(surf.triangles):
            cells.append(("triangle", surf.triangles + offset))
        else:
            cells.append(("vertex", np.arange(len(x), dtype=np.int64)[:, None] + offset))
        body_ids.append(np.full(len(cells[-1][1]), k, dtype=np.int32))
        offset += len(x)
    point_data = {"displacement": np.vstack(disp)}
    if any(s.stress is not None for s in surfaces.values()):
        point_data["von_mises"] = np.concatenate(vm)
    return meshio.Mesh(np.vstack(points), cells, point_data=point_data, cell_data={"body": body_ids})


def write_animation(result, surfaces: dict[str, Surface], pvd_path: str | os.PathLike,
                    max_files: int = MAX_VTU_FILES) -> Path:
    """Write ``<stem>.pvd`` and ``<stem>_vtu/<stem>_NNNNN.vtu`` (every k-th output time, at most
    ``max_files`` files, the last time always included); returns the .pvd path."""
    import meshio  # deferred: 0.07 CPU-s of import, needed only to write meshes

    pvd_path = Path(pvd_path)
    if not surfaces:
        raise InputError(f"{pvd_path}: no body has a surface to animate; give rigid bodies an `obj` "
                         "or flexible bodies a SID file with surface modes")
    folder = pvd_path.with_name(pvd_path.stem + "_vtu")
    folder.mkdir(parents=True, exist_ok=True)
    entries = []
    nt = len(result.t)
    shown = np.unique(np.r_[np.arange(0, nt, max(1, int(np.ceil(nt / max(1, max_files - 1))))), nt - 1])
    for i in shown:
        t = result.t[i]
        vtu = folder / f"{pvd_path.stem}_{i:05d}.vtu"
        with atomic_path(vtu) as tmp:
            meshio.write(tmp, frame_mesh(result, surfaces, i), file_format="vtu")
        rel = vtu.relative_to(pvd_path.parent).as_posix()
        entries.append(f'    <DataSet timestep="{float(t)!r}" group="" part="0" file={quoteattr(rel)}/>')
    text = "\n".join(['<?xml version="1.0"?>',
                      '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
                      "  <Collection>", *entries, "  </Collection>", "</VTKFile>", ""])
    with atomic_path(pvd_path) as tmp:
        Path(tmp).write_text(text)
    return pvd_path
