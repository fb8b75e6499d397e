"""An assembly of components reduced to one flexible body (``sidprep reduce ASSEMBLY.toml``).

The job file (sidprep.jobs.jobfile.read_assembly) lists components - each a mesh with its material,
or a tetrahedral deck with the K and M its FE code wrote (``matrices``, sidprep.fe.matrices) - and how they are joined: shared node sets or tied surfaces (sidprep.fe.joined).  The reduction is
the one of a model in parts (sidprep.jobs.parts, docs/scale.md) with the components as the parts:

1. every component's mesh read and the components joined into one FE model (shared nodes merged,
   tied nodes constrained; joins, tolerances and a floating component checked before any solve);
2. every component's stiffness and mass assembled with its own material, or imported;
3. every component a Craig-Bampton task on the executor of ``sidprep batch`` (local pool or Dask)
   with its joint DOFs and interface masters as boundary; the reduced components assembled, the
   second Craig-Bampton on the interface masters, every node recovered from its component;
4. the user's interfaces, frame, eigenmodes of interest, frequency-response modes, checks against
   the full joined model and the SID, as a monolithic ``sidprep reduce`` (sidprep.jobs.reduce).
"""

from __future__ import annotations

from dataclasses import replace

from sidprep.errors import InputError
from sidprep.fe.assemble import scalar_mass_matrix, vector_mass
from sidprep.fe.joined import embedded, joined_mesh
from sidprep.fe.linalg import single_threaded_blas
from sidprep.fe.material import unit_system
from sidprep.fe.ties import untied_triangles
from sidprep.fe.matrices.onto_model import imported_model
from sidprep.jobs.jobfile import NOT_IN_ASSEMBLIES
from sidprep.jobs.options import check_reduce_options, material_given
from sidprep.jobs.parts import PartsSettings, parts_reducer
from sidprep.jobs.reduce import (FEModel, ReductionResult, check_mode_count, check_parts_held, default_interfaces,
    interface_from_spec, load_mesh, model_material, reduce_fe_model)
from sidprep.progress import Phases
from sidprep.reduction.interfaces import linear_surface_triangles
from sidprep.reduction.partition import GivenMatrices, part_fe_matrices
from sidprep.reduction.paths import located_paths


def component_material(component, o):
    """(Material in SI, notes) of a component: its own material keys, else the job's."""
    if material_given(component):
        return model_material(replace(o, material=component.material, E=component.E, nu=component.nu,
                                      rho=component.rho))
    return model_material(o)


def read_component(component, o, units, ph):
    """(FEMesh in metres, ImportedModel or None) of a component: its mesh, and with ``matrices`` the
    FE code's K and M on it (sidprep.fe.matrices; tetrahedral decks of translational DOFs only)."""
    opts = replace(o, size=component.size if component.size is not None else o.size, matrices=component.matrices)
    mesh = load_mesh(component.mesh, opts, ph)[0]
    if component.matrices is None:
        return mesh, None
    if mesh.surface is not None:
        raise InputError(f"component {component.name}: {component.mesh} has hexahedra, wedges or pyramids; an "
                         "assembly joins tetrahedral models only (C3D4 / C3D10 decks): reduce that model on its own")
    with ph("import", str(component.matrices)):
        imported = imported_model(mesh, component.matrices, unit_system(o.units))
    if imported.mesh.n_nodes != mesh.n_nodes:
        raise InputError(f"component {component.name}: {component.matrices} has rotational DOFs (beams, shells); an "
                         "assembly joins solid models of translational DOFs only: reduce that model on its own")
    return mesh, imported


def check_one_material(job, materials) -> None:
    """Stresses and geometric stiffening use one material: refused for components of several or
    with imported matrices."""
    if (job.options.stress or job.options.stiffening) and \
            (len(set(materials)) > 1 or any(c.matrices for c in job.components)):
        raise InputError(f"{job.mesh}: stress / stiffening of an assembly of several materials or imported matrices "
                         "is not supported yet; drop stress and stiffening, or give every component the same material")


def component_matrices(mesh, cells, material, imported, nodes):
    """(K (3n, 3n), Ms (n, n), the part's material for sidprep.reduction.partition.part_models) of one
    component on the joined mesh: assembled from its cells with its material, or the FE code's
    matrices placed on its joined nodes ``nodes``."""
    if imported is None:
        K, _ = part_fe_matrices(mesh, cells, material)
        return K, scalar_mass_matrix(replace(mesh, cells=cells), material.rho), material
    K, M = embedded(imported.K, nodes, mesh.n_nodes), embedded(imported.M, nodes, mesh.n_nodes)
    return K, embedded(imported.Ms, nodes, mesh.n_nodes, per_node=1), GivenMatrices(K, M)


def reduce_assembly(job, *, phases=None, scheduler=None, workers: int | None = None) -> ReductionResult:
    """Reduce the assembly of ``job`` (a sidprep.jobs.jobfile.Job with components and joins) to one
    flexible body: the module docstring's steps; the components run on the Dask cluster
    ``scheduler`` (address or Client) or a local pool of ``workers`` processes."""

    o = job.options
    check_reduce_options(o)
    for key, value in (("matrices", o.matrices), ("parts", o.parts)):
        if value:
            raise InputError(f"{job.mesh}: {key} = {value}: does not apply to an assembly; {NOT_IN_ASSEMBLIES[key]}")
    ph = phases or Phases(verbose=False)
    names = [c.name for c in job.components]
    pairs = [component_material(c, o) for c in job.components]
    materials = [m for m, _ in pairs]
    check_one_material(job, materials)
    notes = [f"{c.name}: {n}" for c, (_, ns) in zip(job.components, pairs) for n in ns if not c.matrices]
    units = unit_system(o.units)
    with single_threaded_blas():
        read = [read_component(c, o, units, ph) for c in job.components]
        with ph("join", f"{len(job.joins)} join(s) of {len(names)} components"):
            mesh, labels, nodes = joined_mesh([m for m, _ in read], names, list(job.joins), job.mesh, units.length_to_m)
        if mesh.ties is not None:                         # the tied joints' faces are inside the body
            mesh = replace(mesh, surface=untied_triangles(linear_surface_triangles(mesh), mesh.ties))
        imported = [i for _, i in read]
        del read
        notes = list(mesh.notes) + notes + [f"{c.name}: stiffness and mass: {c.matrices} ({i.fmt}); material not used"
                                            for c, i in zip(job.components, imported) if i is not None]
        paths = located_paths(mesh, o.paths, units.length_to_m)
        joint_sets = {ref for j in job.joins for ref in j.sets}
        interfaces = [interface_from_spec(mesh, s, units.length_to_m) for s in
                      (o.interfaces or [d for d in default_interfaces(mesh) if d.split(":")[0] not in joint_sets])]
        check_mode_count(o, mesh.n_dof, len(interfaces))
        check_parts_held(mesh, interfaces, job.mesh)
        with ph("assemble", f"{mesh.n_dof} DOF, {len(names)} components"):
            per_part = [component_matrices(mesh, mesh.cells[labels == p], materials[p], imported[p], nodes[p])
                        for p in range(len(names))]
            assembled = {"K": sum(k for k, _, _ in per_part)}
            Ms = sum(ms for _, ms, _ in per_part).tocsr()
            assembled["M"] = vector_mass(Ms)
        reducer = parts_reducer(mesh, [part for _, _, part in per_part], PartsSettings(len(names), scheduler, workers),
                                notes, components=(labels, names))
        del per_part
        metadata = [{"component": c.name, **({"name": f"none: K and M from {c.matrices}"} if c.matrices
                                             else m.as_dict())} for c, m in zip(job.components, materials)]
        model = FEModel(mesh, str(job.mesh), assembled, Ms, materials[0], metadata, None, notes, interfaces, paths)
        return reduce_fe_model(model, o, ph, reducer)
