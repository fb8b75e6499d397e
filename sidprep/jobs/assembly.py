"""An assembly of components reduced to one flexible body (``sidprep reduce ASSEMBLY.toml``).

The job file (sidprep.jobs.jobfile.read_assembly) lists components - each a mesh with its material -
and how they are joined: shared node sets or tied surfaces (sidprep.fe.joined).  The reduction is
the one of a model in parts (sidprep.jobs.parts, docs/scale.md) with the components as the parts:

1. every component's mesh read and the components joined into one FE model (shared nodes merged,
   tied nodes constrained; joins, tolerances and a floating component checked before any solve);
2. every component's stiffness and mass assembled with its own material;
3. every component a Craig-Bampton task on the executor of ``sidprep batch`` (local pool or Dask)
   with its joint DOFs and interface masters as boundary; the reduced components assembled, the
   second Craig-Bampton on the interface masters, every node recovered from its component;
4. the user's interfaces, frame, eigenmodes of interest, frequency-response modes, checks against
   the full joined model and the SID, as a monolithic ``sidprep reduce`` (sidprep.jobs.reduce).
"""

from __future__ import annotations

from dataclasses import replace

from sidprep.errors import InputError
from sidprep.fe.assemble import scalar_mass_matrix, stiffness_matrix, vector_mass
from sidprep.fe.joined import joined_mesh
from sidprep.fe.linalg import single_threaded_blas
from sidprep.fe.material import unit_system
from sidprep.jobs.options import check_reduce_options, material_given
from sidprep.jobs.parts import PartsSettings, parts_reducer
from sidprep.jobs.reduce import (FEModel, ReductionResult, check_mode_count, check_parts_held, default_interfaces,
    interface_from_spec, load_mesh, model_material, reduce_model)
from sidprep.progress import Phases
from sidprep.reduction.paths import located_paths


def component_material(component, o):
    """(Material in SI, notes) of a component: its own material keys, else the job's."""
    if material_given(component):
        return model_material(replace(o, material=component.material, E=component.E, nu=component.nu,
                                      rho=component.rho))
    return model_material(o)


def check_one_material(job, materials) -> None:
    """Stresses and geometric stiffening use one material: refused for components of several."""
    if (job.options.stress or job.options.stiffening) and len(set(materials)) > 1:
        raise InputError(f"{job.mesh}: stress / stiffening of an assembly of several materials is not supported yet; "
                         "drop stress and stiffening, or give every component the same material")


def reduce_assembly(job, *, phases=None, scheduler=None, workers: int | None = None) -> ReductionResult:
    """Reduce the assembly of ``job`` (a sidprep.jobs.jobfile.Job with components and joins) to one
    flexible body: the module docstring's steps; the components run on the Dask cluster
    ``scheduler`` (address or Client) or a local pool of ``workers`` processes."""

    o = job.options
    check_reduce_options(o)
    ph = phases or Phases(verbose=False)
    names = [c.name for c in job.components]
    pairs = [component_material(c, o) for c in job.components]
    materials = [m for m, _ in pairs]
    check_one_material(job, materials)
    notes = [f"{c.name}: {n}" for c, (_, ns) in zip(job.components, pairs) for n in ns]
    units = unit_system(o.units)
    with single_threaded_blas():
        meshes = [load_mesh(c.mesh, replace(o, size=c.size if c.size is not None else o.size), ph)[0]
                  for c in job.components]
        with ph("join", f"{len(job.joins)} join(s) of {len(names)} components"):
            mesh, labels = joined_mesh(meshes, names, list(job.joins), job.mesh, units.length_to_m)
        del meshes
        notes = list(mesh.notes) + notes
        paths = located_paths(mesh, o.paths, units.length_to_m)
        joint_sets = {ref for j in job.joins for ref in j.sets}
        interfaces = [interface_from_spec(mesh, s, units.length_to_m) for s in
                      (o.interfaces or [d for d in default_interfaces(mesh) if d.split(":")[0] not in joint_sets])]
        check_mode_count(o, mesh.n_dof, len(interfaces))
        check_parts_held(mesh, interfaces, job.mesh)
        with ph("assemble", f"{mesh.n_dof} DOF, {len(names)} components"):
            assembled, Ms = {"K": 0, "M": 0}, 0
            for p, material in enumerate(materials):
                sub = replace(mesh, cells=mesh.cells[labels == p])
                assembled["K"] = assembled["K"] + stiffness_matrix(sub, material)
                Ms = Ms + scalar_mass_matrix(sub, material.rho)
            assembled["M"] = vector_mass(Ms)
        reducer = parts_reducer(mesh, materials, PartsSettings(len(names), scheduler, workers), notes,
                                components=(labels, names))
        metadata = [{"component": c.name, **m.as_dict()} for c, m in zip(job.components, materials)]
        model = FEModel(mesh, str(job.mesh), assembled, Ms.tocsr(), materials[0], metadata, None, notes,
                        interfaces, paths)
        return reduce_model(model, o, ph, reducer)
