"""A reduction job: mesh + material + interfaces -> an in-memory SID with its checks (what FEMBS does).

Steps (each a phase of ``sidprep.progress.Phases``; no printing here, no files):

1. read the mesh, assemble K, M, Ms (sidprep.fe.assemble);
2. couple every interface patch to a 6-DOF master (RBE2 / RBE3, sidprep.reduction.interfaces);
3. first reduction: Craig-Bampton on the master DOFs (sidprep.reduction.craig_bampton), fixed-interface modes up
   to max(2, cutoff_factor) x fmax, or max(CB_MIN_MODES, 3 x modes) of them;
4. second step (sidprep.reduction.modes): eigenmodes of interest + frequency-response modes, cut-off,
   orthonormalisation; reference frame free (default) or attached to an interface master;
5. optional geometric stiffening (sidprep.reduction.stiffening);
6. SID invariants (sidprep.sid.model) and the FE-comparison checks (sidprep.reduction.fe_checks).

Defaults (sidprep.jobs.options): steel; interfaces = every node set of the mesh that can carry 6 DOF, as
RBE2; frame ``free`` (free-free elastic modes, mean axes to first order, what a SIMPACK user gets
from FEMBS for a body connected at several points); 8 eigenmodes + FRMs at every interface master
DOF, cut-off 5x; 2 % modal damping.  Files: sidprep.jobs.output.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np

from sidprep.errors import InputError
from sidprep.fe.assemble import block_pattern, scalar_mass_matrix, stiffness_matrix, vector_mass
from sidprep.fe.linalg import single_threaded_blas
from sidprep.fe.material import material_from_options, unit_system
from sidprep.fe.mesh import FEMesh, read_mesh
from sidprep.fe.topology import connected_parts
from sidprep.fe.plausibility import unit_warnings
from sidprep.jobs.options import (CB_MIN_MODES, DEFAULT_CUTOFF_FACTOR, DEFAULT_DAMPING, DEFAULT_MATERIAL,
    DEFAULT_MODES, ReduceOptions, check_reduce_options, material_given)
from sidprep.progress import Phases, peak_memory_mb
from sidprep.reduction.craig_bampton import craig_bampton
from sidprep.reduction.fe_checks import STATIC_CHECK_TOL, fe_checks, structured_checks
from sidprep.reduction.interfaces import (KINDS, SELECTIONS, SELECTORS, Interface, check_patch, interface_model,
    linear_surface_triangles, make_interface, rigid_modes_model, select_patch, tied_interface_model)
from sidprep.reduction.modes import modal_basis, modal_damping, mode_labels
from sidprep.reduction.paths import fe_path, located_paths
from sidprep.reduction.stiffening import stiffening_parts, support_dofs
from sidprep.reduction.stress import stress_check, stress_modes, structured_stress_check
from sidprep.sid.check import checks_as_dicts
from sidprep.sid.model import SurfaceModes, sid_invariants


@dataclass(frozen=True)
class Reduction:
    """The result of steps 2-4.

    im : InterfaceModel; K_model, M_model : sparse model matrices; cb : ReducedModel;
    basis : ModalBasis; Phi_model (n_model, nq); Phi_fe (3n, nq); held : frame master model DOFs
    or None (free frame); rigid : (n_model, 6) rigid motions in model DOFs; supports : the 6
    statically determinate support DOFs of static solves (sid-spec 6.4).
    """

    im: object
    K_model: object
    M_model: object
    cb: object
    basis: object
    Phi_model: np.ndarray
    Phi_fe: np.ndarray
    held: np.ndarray | None
    rigid: np.ndarray
    supports: np.ndarray

    def static_solve(self, P: np.ndarray) -> np.ndarray:
        """Exact full-model K_model u = P with u = 0 on the supports; (n_model, nc)."""
        return self.cb.static_solve(P, self.supports)


@dataclass(frozen=True)
class ReductionResult:
    """What ``reduce`` returns.

    sid : sidprep.sid.model.SID (SI units; metadata holds options, material, notes and the checks);
    checks : dict of the FE-comparison checks (sidprep.reduction.fe_checks); notes : advice lines;
    n_dof : FE DOF count; timings_s : wall seconds per phase; peak_memory_mb : process peak RSS (MiB).
    """

    sid: object
    checks: dict
    notes: tuple[str, ...]
    n_dof: int
    timings_s: dict
    peak_memory_mb: float

    @property
    def passed(self) -> bool:
        return bool(self.checks.get("passed", False))


# ---------------------------------------------------------------------------------------------
# interfaces
# ---------------------------------------------------------------------------------------------

def parse_interface(spec: str) -> tuple[str, str]:
    """"NAME[:rbe2|rbe3]" -> (name, kind)."""

    name, _, kind = spec.partition(":")
    kind = (kind or "rbe2").lower()
    if not name or kind not in KINDS:
        raise InputError(f"interface {spec!r}: expected NAME[:rbe2|rbe3]; valid kinds: {', '.join(KINDS)}")
    return name, kind


#: keys of an interface table in a job file, besides the selection's own (type, point, normal, ...)
INTERFACE_KEYS = ("name", "kind", "master_point", "node_set")


#: interface-table entries that are lengths (converted with the unit system's length factor)
LENGTH_KEYS = ("master_point", "point", "center", "radius", "tol")


def interface_from_spec(mesh, spec, length_to_m: float = 1.0, rows=None):
    """An Interface from "NAME[:rbe2|rbe3]" (a node set) or a job-file table {name, kind,
    master_point, node_set | type = plane|cylinder|sphere + its parameters and tol}; lengths of
    the table are in the job's unit system (``length_to_m`` converts them to the mesh's metres);
    ``rows``: the node rows a patch may hold (sidprep.reduction.interfaces.make_interface)."""

    if isinstance(spec, str):
        name, kind = parse_interface(spec)
        return make_interface(mesh, name, kind=kind, rows=rows)
    spec = {k: (np.asarray(v, dtype=float) * length_to_m if k in LENGTH_KEYS else v) for k, v in dict(spec).items()}
    valid = set(INTERFACE_KEYS) | {"type"} | {k for _, keys in SELECTORS.values() for k in keys}
    unknown = sorted(set(spec) - valid)
    if unknown or "name" not in spec:
        raise InputError(f"interface {spec}: needs name and a node_set or type ({', '.join(SELECTIONS)}); "
                         f"unknown key(s) {', '.join(unknown) or '-'}; valid: {', '.join(sorted(valid))}")
    selection = {k: v for k, v in spec.items() if k not in INTERFACE_KEYS} or spec.get("node_set")
    return make_interface(mesh, spec["name"], selection=selection, kind=spec.get("kind", "rbe2"),
                          master_point=spec.get("master_point"), rows=rows)


def imported_interfaces(imported, specs, o: ReduceOptions, length_to_m: float):
    """(Interfaces, options) of a reduction from imported matrices (sidprep.fe.matrices.onto_model):
    a spec naming a rigid body is its reference and rotation nodes (the FE code's own 6-DOF master);
    a clamped export gets an interface on its supports (an RBE2 on clamped solid nodes, or a rigid
    body's two nodes), which carries the frame (the options' frame set to it, first in the list
    unless a spec names it); default interfaces that hold dependent nodes are left out; interfaces on
    6-DOF nodes (beams, shells) use their rotations (sidprep.reduction.grid_interfaces)."""
    from sidprep.reduction.grid_interfaces import six_dof_interface, with_rotations  # deferred: imported K, M only

    mesh = imported.mesh
    dependent = set() if mesh.ties is None else set(mesh.ties.slaves.tolist())
    clamp = None
    if len(imported.clamped):
        if o.frame not in ("free", imported.clamp_name):
            raise InputError(f"frame = {o.frame!r}: the matrices are clamped at {len(imported.clamped)} nodes "
                             f"({imported.clamp_name}); the frame of a clamped export is its support: omit --frame "
                             f"or give --frame {imported.clamp_name}")
        x = mesh.points[imported.clamped]
        if imported.clamp_kind == "rbe2":
            check_patch(imported.clamp_name, x, np.ones(len(x)))
        clamp = Interface(imported.clamp_name, imported.clamped, x.mean(axis=0), imported.clamp_kind)
        o = replace(o, frame=imported.clamp_name)
    names = [parse_interface(s)[0].upper() if isinstance(s, str) else None for s in specs]
    out = [clamp] if clamp is not None and imported.clamp_name.upper() not in names else []
    for spec, name in zip(specs, names):
        if clamp is not None and name == imported.clamp_name.upper():
            out.append(clamp)                              # the supports carry the frame
        elif name is not None and name in imported.rigid_bodies:
            ref, rot = imported.rigid_bodies[name]
            out.append(Interface(parse_interface(spec)[0], np.array([ref, rot]), mesh.points[ref].copy(), "node"))
        elif o.interfaces or name is None or not dependent.intersection(
                mesh.node_sets.get(parse_interface(spec)[0], np.zeros(0, np.int64)).tolist()):
            out.append(six_dof_interface(mesh, spec, imported.rotation_of, imported.unconnected) or with_rotations(
                interface_from_spec(mesh, spec, length_to_m, imported.rotation_of > -2), imported.rotation_of))
    return out, o


def default_interfaces(mesh) -> list[str]:
    """Node sets that look like interfaces: patches able to carry 6 DOF, as RBE2 ("NAME:rbe2")."""

    out = []
    for name, nodes in mesh.node_sets.items():
        try:
            check_patch(name, mesh.points[nodes], np.ones(len(nodes)))
        except InputError:
            continue
        if len(nodes) < 0.5 * mesh.n_nodes:
            out.append(f"{name}:rbe2")
    return out


def reduce_body(mesh, K_fe, M_fe, interfaces, *, frame="free", n_modes=None, fmax=None,
                frm=True, cutoff_factor=DEFAULT_CUTOFF_FACTOR, load_nodes=(), phases=None, reducer=None) -> Reduction:
    """Steps 2-4 of the module docstring for an assembled FE model.

    interfaces : list of sidprep.reduction.interfaces.Interface; frame : "free" or an interface name;
    load_nodes : FE node indices that get 3 unit FRM forces each, besides every master DOF.
    K_fe and M_fe are only projected: a caller that keeps no reference to them lets them be freed
    before the factorisation (peak memory).  ``reducer`` : the Craig-Bampton step done otherwise,
    (im, K_model, M_model, boundary, n_modes=, fmax=) -> ReducedModel (in parts: sidprep.jobs.parts).
    """

    ph = phases or Phases(verbose=False)
    if n_modes is None and fmax is None:
        n_modes = DEFAULT_MODES
    names = [i.name for i in interfaces]
    if frame != "free" and frame not in names:
        raise InputError(f"frame = {frame!r}: no such interface; valid: free, {', '.join(names) or '(no interfaces)'}")
    with ph("interfaces", f"{len(interfaces)} master node(s)"):
        im = tied_interface_model(interface_model(mesh.n_nodes, interfaces, mesh.points), mesh.ties)
        K_model, M_model = im.project(K_fe), im.project(M_fe)
        del K_fe, M_fe                            # freed here unless the caller keeps them (peak memory)
        rigid = rigid_modes_model(im, mesh.points, mesh.rotational)
    boundary = im.master_dofs.ravel() if len(interfaces) else support_dofs(rigid, np.arange(im.n_model))
    with ph("craig-bampton", f"{len(boundary)} boundary DOF"):
        count = {"fmax": max(2.0, cutoff_factor) * fmax} if fmax is not None \
            else {"n_modes": max(CB_MIN_MODES, 3 * n_modes)}
        if reducer is None:
            cb = craig_bampton(K_model, M_model, boundary, extent=np.ptp(mesh.points, axis=0), **count)
        else:
            cb = reducer(im, K_model, M_model, boundary, **count)
    held = None if frame == "free" else im.master_dofs[names.index(frame)]
    held_r = () if held is None else np.flatnonzero(np.isin(boundary, held))
    with ph("modes", "eigen + frequency-response modes"):
        z_rigid = np.zeros((cb.K.shape[0], 6))
        z_rigid[:len(boundary)] = rigid[boundary]
        basis = modal_basis(cb.K, cb.M, rigid=z_rigid if held is None else None, held=held_r,
                            loads=frm_loads(im, cb, load_nodes), n_modes=n_modes, fmax=fmax,
                            frm=frm, cutoff_factor=cutoff_factor)
        Phi_model = cb.basis @ basis.Z
        Phi_fe = np.asarray(im.T @ Phi_model)
    return Reduction(im, K_model, M_model, cb, basis, Phi_model, Phi_fe, held, rigid,
                     support_dofs(rigid, boundary, held))


def frm_loads(im, cb, load_nodes=()) -> np.ndarray:
    """FRM unit loads in Craig-Bampton coordinates: every master DOF, then x, y, z forces on each
    load node (projected: basis^T T^T e); (nr, 6 n_if + 3 n_nodes)."""
    nr = cb.K.shape[0]
    P = np.zeros((nr, im.master_dofs.size))
    P[np.flatnonzero(np.isin(cb.boundary_dofs, im.master_dofs.ravel())), np.arange(im.master_dofs.size)] = 1.0
    nodes = np.asarray(load_nodes, dtype=np.int64)
    if len(nodes):
        dofs = (3 * nodes[:, None] + np.arange(3)).ravel()
        P = np.hstack([P, cb.basis.T @ np.asarray(im.T[dofs].T.todense())])
    return P


# ---------------------------------------------------------------------------------------------
# SID and files
# ---------------------------------------------------------------------------------------------

def surface_modes(mesh, Phi_fe):
    """SurfaceModes of the outer surface (tet10 faces split into 4 linear triangles)."""

    tri = linear_surface_triangles(mesh)
    nodes, tri = np.unique(tri, return_inverse=True)
    nq = Phi_fe.shape[1]
    shapes = Phi_fe.reshape(mesh.n_nodes, 3, nq)[nodes]
    return SurfaceModes(mesh.points[nodes], tri.reshape(-1, 3).astype(np.int64), shapes, mesh.node_ids[nodes])


def build_sid(red: Reduction, mesh, Ms, *, damping=DEFAULT_DAMPING, stiffening=None, metadata=None):
    """The SID of the reduced body: one node per interface master, surface modes attached."""


    f = red.basis.frequencies_hz
    first_id = int(mesh.node_ids.max()) + 1 if len(mesh.node_ids) else 1
    nodes = [(first_id + i, itf.master_point, red.Phi_model[m[:3]], red.Phi_model[m[3:]], itf.name)
             for i, (itf, m) in enumerate(zip(red.im.interfaces, red.im.master_dofs))]
    labels = mode_labels(f, first=7 if red.held is None else 1, kinds=red.basis.kinds)
    sid = sid_invariants(mesh.points, Ms, red.Phi_fe, nodes, labels=labels, frequencies_hz=f,
                         mode_kinds=red.basis.kinds, Ke=np.diag((2 * np.pi * f) ** 2),
                         De=modal_damping(f, damping), stiffening=stiffening, metadata=metadata or {})
    return replace(sid, surface=surface_modes(mesh, red.Phi_fe))


def check_mode_count(o: ReduceOptions, n_dof: int, n_interfaces: int) -> None:
    """Reject ``modes`` the model cannot give before the solve: the Craig-Bampton step asks for
    max(CB_MIN_MODES, 3 modes) fixed-interface modes of the interior DOFs."""
    if o.modes is None:
        return
    interior = n_dof - 6 * max(n_interfaces, 1)
    most = max(interior // 3, 0)
    if 3 * o.modes > interior:
        raise InputError(f"modes = {o.modes}: the model has {n_dof} DOF, enough for at most {most} modes; "
                         "use fewer modes or a finer mesh")


def check_parts_held(mesh, interfaces, source) -> None:
    """A mesh of several disconnected parts reduces only if every part carries an interface (otherwise
    its interior stiffness is singular in any frame); the advice names the parts' sizes."""

    n_parts, labels = connected_parts(mesh)
    if n_parts < 2:
        return
    held = set(labels[np.concatenate([i.nodes for i in interfaces])].tolist()) if interfaces else set()
    loose = [p for p in range(n_parts) if p not in held]
    if loose:
        sizes = np.bincount(labels, minlength=n_parts)
        raise InputError(f"{source}: the mesh has {n_parts} disconnected parts and {len(loose)} of them "
                         f"(with {', '.join(str(int(sizes[p])) for p in loose[:5])} nodes) carry no interface; "
                         "join the parts in the mesh (shared nodes) or add an interface on each part")


def reduce(mesh, options: ReduceOptions = ReduceOptions(), *, phases=None, scheduler=None,
           workers: int | None = None) -> ReductionResult:
    """Reduce an FE model to a flexible body: ``mesh`` (an FEMesh or a path) -> SID and checks.

    Runs with one BLAS thread (sidprep.fe.linalg.single_threaded_blas); no printing, no files.
    ``phases`` : sidprep.progress.Phases for progress lines and timings (default silent).  With
    ``options.parts``, the parts run on the Dask cluster ``scheduler`` (an address or a
    dask.distributed Client) or on a local pool of ``workers`` processes (sidprep.jobs.parts).
    """

    check_reduce_options(options)
    with single_threaded_blas():
        return _reduce(mesh, options, phases, (scheduler, workers))


def load_mesh(mesh, o, ph):
    """(FEMesh in metres, source name) from an FEMesh or a path, in the unit system of ``o``."""

    units = unit_system(o.units)
    if isinstance(mesh, FEMesh):
        return mesh, str(mesh.source)
    # a deck of any solid elements when K, M are imported (ReduceOptions.matrices; ModalOptions has none)
    if getattr(o, "matrices", None):
        from sidprep.fe.matrices.deck import read_model  # deferred: the deck readers (meshio), imported K, M only

        read = read_model
    else:
        read = read_mesh
    with ph("mesh", str(mesh)):
        m = read(mesh, size=o.size, order=o.order).in_metres(units.length_to_m, units.name)
    return m, str(mesh)


def model_material(o):
    """(Material in SI, notes): the given material, or the default with a note saying so."""

    if material_given(o):
        return material_from_options(E=o.E, nu=o.nu, rho=o.rho, name=o.material, units=o.units), []
    m = material_from_options(name=DEFAULT_MATERIAL)
    return m, [f"material: none given, {m.name} used (E = {m.E / 1e9:g} GPa, nu = {m.nu:g}, "
               f"rho = {m.rho:g} kg/m^3); set material or E, nu, rho"]


@dataclass(frozen=True)
class FEModel:
    """An assembled FE model ready to reduce (what ``reduce_fe_model`` needs).

    mesh : FEMesh (m); source : its name; assembled : {"K", "M"} FE matrices (N/m, kg), popped by
    ``reduce_fe_model`` so they are freed once projected; Ms : scalar mass matrix (kg); material : the
    Material of the stresses, the geometric stiffening and the unit plausibility warnings;
    material_metadata : what the SID metadata says of the material(s); imported : the
    sidprep.fe.matrices model when K, M come from another FE code, else None; notes : list of
    advice lines (appended to); interfaces : Interface list; paths : located load paths.
    """

    mesh: FEMesh
    source: str
    assembled: dict
    Ms: object
    material: object
    material_metadata: object
    imported: object
    notes: list
    interfaces: list
    paths: list


def _reduce(mesh_in, o: ReduceOptions, phases, cluster=(None, None)) -> ReductionResult:

    ph = phases or Phases(verbose=False)
    units = unit_system(o.units)
    material, material_notes = model_material(o)
    mesh, source = load_mesh(mesh_in, o, ph)
    notes = list(mesh.notes) + material_notes
    paths = located_paths(mesh, o.paths, units.length_to_m)
    specs = o.interfaces or default_interfaces(mesh)
    imported = None
    if o.matrices:                                        # K, M of another FE code (sidprep.fe.matrices)
        from sidprep.fe.matrices.deck_sections import deck_stress  # deferred: imported K, M only
        from sidprep.fe.matrices.onto_model import imported_model  # deferred: 0.1 s import with the decks' readers

        with ph("import", str(o.matrices)):
            imported = imported_model(mesh, o.matrices, units, len(specs))
            material = deck_stress(mesh, units) if o.stress else material   # the deck's elements and materials
        mesh = imported.mesh                              # with rotation nodes and the deck's constraints
        interfaces, o = imported_interfaces(imported, specs, o, units.length_to_m)
        assembled, Ms = {"K": imported.K, "M": imported.M}, imported.Ms
        imported = replace(imported, K=None)              # K freed once projected (peak memory); M kept for the checks
        notes = list(mesh.notes) + list(imported.notes) + [f"stiffness and mass: {o.matrices} ({imported.fmt}); "
                                    + ("stresses from the deck's elements and materials" if o.stress else "material not used")]
    else:
        interfaces = [interface_from_spec(mesh, s, units.length_to_m) for s in specs]
    check_mode_count(o, mesh.n_dof, len(interfaces))
    if not o.matrices:
        check_parts_held(mesh, interfaces, source)
        with ph("assemble", f"{mesh.n_dof} DOF"):
            pattern = block_pattern(mesh.cells, mesh.n_nodes)
            assembled = {"K": stiffness_matrix(mesh, material, pattern)}
            Ms = scalar_mass_matrix(mesh, material.rho, pattern)
            assembled["M"] = vector_mass(Ms)
            del pattern
    reducer = None
    if o.parts:
        from sidprep.jobs.parts import PartsSettings, parts_reducer  # deferred: --parts only (pool, pymetis)

        reducer = parts_reducer(mesh, material, PartsSettings(o.parts, *cluster), notes)
    metadata = {"name": f"none: K and M from {o.matrices}"} if o.matrices else material.as_dict()
    model = FEModel(mesh, source, assembled, Ms, material, metadata, imported, notes, interfaces, paths)
    return reduce_fe_model(model, o, ph, reducer)


def reduce_fe_model(model: FEModel, o: ReduceOptions, ph, reducer=None) -> ReductionResult:
    """Steps 2-6 of the module docstring for an assembled FE model (``reduce`` and assemblies,
    sidprep.jobs.assembly); ``reducer`` : the Craig-Bampton step in parts (reduce_body)."""

    mesh, material, imported, notes = model.mesh, model.material, model.imported, model.notes
    load_nodes = np.unique(np.concatenate([np.zeros(0, np.int64)] + [select_patch(mesh, n) for n in o.frm_nodes]))
    # K_fe and M_fe are handed over (popped), so that reduce_body frees them once projected, before
    # the factorisation (peak memory); M_fe is rebuilt from Ms afterwards
    red = reduce_body(mesh, model.assembled.pop("K"), model.assembled.pop("M"), model.interfaces, frame=o.frame,
                      n_modes=o.modes, fmax=o.fmax, frm=o.frm, cutoff_factor=o.cutoff_factor, load_nodes=load_nodes,
                      phases=ph, reducer=reducer)
    M_fe = imported.M if imported is not None else vector_mass(model.Ms)
    eigen_hz = [f for f, kind in zip(red.basis.frequencies_hz, red.basis.kinds) if kind == "eigen" and f > 0]
    notes += unit_warnings(mesh.points, material, float(M_fe.sum() / 3.0),
                           None if imported is not None else min(eigen_hz, default=None))
    stiff = None
    if o.stiffening:
        with ph("stiffening", "unit load cases"):
            stiff = stiffening_parts(mesh, material, M_fe, red.im, red.static_solve, red.Phi_fe)
    metadata = {"source": model.source, "mesh_sha256": mesh.sha256, "notes": notes,
                "material": model.material_metadata,
                "options": {"mesh": model.source, **asdict(o)},
                "interfaces": [{"name": i.name, "kind": i.kind, "nodes": int(len(i.nodes)),
                                "master_point_m": i.master_point.tolist()} for i in model.interfaces],
                "frame": o.frame, "frm_omega_hz": red.basis.frm_omega_hz, "cutoff_hz": red.basis.cutoff_hz,
                "rejected_frm_hz": red.basis.rejected_frm_hz.tolist(),
                "fixed_interface_modes": int(len(red.cb.fixed_interface_hz))}
    sid = build_sid(red, mesh, model.Ms, damping=o.damping, stiffening=stiff, metadata=metadata)
    if model.paths:
        sid = replace(sid, paths={p.name: fe_path(mesh, red.Phi_fe, p) for p in model.paths})
    if o.stress:
        with ph("stress", f"modal stresses at the {o.stress} nodes"):
            sid = replace(sid, stress=stress_modes(mesh, material, red.Phi_fe, o.stress))
    with ph("checks", "reduced vs full FE model"):
        checks = fe_checks(red, mesh, M_fe, sid, full_frequencies=o.check_frequencies)
        if sid.stress is not None:
            checks.update(stress_check(red, mesh, material, sid.stress))
        if imported is not None:
            from sidprep.fe.matrices.onto_model import imported_checks  # deferred: imported K, M only

            checks.update(imported_checks(imported, red.basis))
    notes += rotation_warning(checks, red.basis, o.cutoff_factor)
    sid = replace(sid, metadata={**sid.metadata, "notes": notes, "checks": checks_as_dicts(
        {**structured_checks(checks), **structured_stress_check(checks)})})
    return ReductionResult(sid, checks, tuple(notes), int(mesh.n_dof), dict(ph.timings_s), peak_memory_mb())


def rotation_warning(checks: dict, basis, cutoff_factor: float) -> list[str]:
    """A warning when the reduced body misses the 1 % promise for rotations under unit moments
    (FEMBS promises it for deflections): name the cut-off factor that keeps the dropped
    frequency-response modes (the moment FRMs are usually the ones above the cut-off)."""

    error = checks["static_rotation_max_rel_error"]
    if error <= STATIC_CHECK_TOL:
        return []
    fix = "keep the frequency-response modes (--frm) or raise --modes"
    rejected = np.asarray(basis.rejected_frm_hz)
    if rejected.size and np.isfinite(basis.cutoff_hz) and basis.cutoff_hz > 0:
        needed = float(np.ceil(cutoff_factor * rejected.max() / basis.cutoff_hz * 1.01))
        fix = (f"{rejected.size} frequency-response modes up to {rejected.max():.4g} Hz fell above the cut-off "
               f"{basis.cutoff_hz:.4g} Hz; keep them with --cutoff-factor {needed:g}")
    return [f"WARNING: rotation under unit moments at the interface masters is off by {100 * error:.2f} % "
            f"(> {100 * STATIC_CHECK_TOL:g} %): {fix}"]
