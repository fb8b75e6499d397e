"""A reduction job: mesh + material + interfaces -> SID files (what FEMBS does for SIMPACK).

Steps (each a phase with progress and timing):

1. read the mesh, assemble K, M, Ms (sidprep.assemble);
2. couple every interface patch to a 6-DOF master (RBE2 / RBE3, sidprep.interfaces);
3. first reduction: Craig-Bampton on the master DOFs (sidprep.reduce), fixed-interface modes up
   to max(2, cutoff_factor) x fmax, or max(CB_MIN_MODES, 3 x --modes) of them;
4. second step (sidprep.modes): eigenmodes of interest + frequency-response modes, cut-off,
   orthonormalisation; reference frame free (default) or attached to an interface master;
5. optional geometric stiffening (sidprep.stiffening);
6. SID invariants (sidprep.sid), FE-comparison checks, files (.sid.h5, .SID_FEM, .obj).

Defaults (``sidprep reduce MESH`` alone): steel; interfaces = every node set of the mesh that can
carry 6 DOF, as RBE2 (for the piston rod: big_end and small_end); frame ``free`` - the body
frame stays at the FE origin, the modes are free-free elastic modes (mean axes to first order),
which is what a SIMPACK user gets from FEMBS for a body connected by joints at several points;
8 eigenmodes + FRMs at every interface master DOF, cut-off 5x; 2 % modal damping; all three files.
"""

from __future__ import annotations

import json
import sys
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from sidprep.errors import InputError
from sidprep.fe_checks import fe_checks, format_checks, structured_checks

#: default number of elastic eigenmodes of interest (8: with 6 the piston rod's axial FRMs fall
#: above the 5x cut-off and its static deflection misses the FEMBS 1 % promise: 5.8 % vs 0.5 %)
DEFAULT_MODES = 8
#: default modal damping ratio (typical of bolted steel parts)
DEFAULT_DAMPING = 0.02
#: fewest fixed-interface modes of the Craig-Bampton step when --modes is given
CB_MIN_MODES = 20
FRAMES_HINT = "free or the name of an interface"


@dataclass(frozen=True)
class ReduceOptions:
    """Everything a reduction job needs (CLI options or a TOML job file, same names)."""

    mesh: str
    size: float | None = None
    order: int = 2
    E: float | None = None
    nu: float | None = None
    rho: float | None = None
    material: str | None = None
    units: str = "si"
    interfaces: tuple = ()
    frm_nodes: tuple[str, ...] = ()
    frame: str = "free"
    modes: int | None = None
    fmax: float | None = None
    frm: bool = True
    cutoff_factor: float = 5.0
    damping: float | tuple | dict = DEFAULT_DAMPING
    stiffening: bool = False
    check_frequencies: bool = True
    output: str | None = None
    sid_fem: bool = True
    obj: bool = True
    json: bool = False
    verbose: bool = True


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


# ---------------------------------------------------------------------------------------------
# options
# ---------------------------------------------------------------------------------------------

def parse_interface(spec: str) -> tuple[str, str]:
    """"NAME[:rbe2|rbe3]" -> (name, kind)."""
    from sidprep.interfaces import KINDS

    name, _, kind = spec.partition(":")
    kind = (kind or "rbe2").lower()
    if not name or kind not in KINDS:
        raise InputError(f"--interface {spec}: expected NAME[:rbe2|rbe3]; valid kinds: {', '.join(KINDS)}")
    return name, kind


#: keys of an interface table in a job file, besides the selection's own (type, point, normal, ...)
INTERFACE_KEYS = ("name", "kind", "master_point", "node_set")


#: interface-table entries that are lengths (converted with the unit system's length factor)
LENGTH_KEYS = ("master_point", "point", "center", "radius", "tol")


def interface_from_spec(mesh, spec, length_to_m: float = 1.0):
    """An Interface from "NAME[:rbe2|rbe3]" (a node set) or a job-file table {name, kind,
    master_point, node_set | type = plane|cylinder|sphere + its parameters and tol}; lengths of
    the table are in the job's unit system (``length_to_m`` converts them to the mesh's metres)."""
    from sidprep.interfaces import SELECTIONS, SELECTORS, make_interface

    if isinstance(spec, str):
        name, kind = parse_interface(spec)
        return make_interface(mesh, name, kind=kind)
    spec = {k: (np.asarray(v, dtype=float) * length_to_m if k in LENGTH_KEYS else v) for k, v in dict(spec).items()}
    valid = set(INTERFACE_KEYS) | {"type"} | {k for _, keys in SELECTORS.values() for k in keys}
    unknown = sorted(set(spec) - valid)
    if unknown or "name" not in spec:
        raise InputError(f"interface {spec}: needs name and a node_set or type ({', '.join(SELECTIONS)}); "
                         f"unknown key(s) {', '.join(unknown) or '-'}; valid: {', '.join(sorted(valid))}")
    selection = {k: v for k, v in spec.items() if k not in INTERFACE_KEYS} or spec.get("node_set")
    return make_interface(mesh, spec["name"], selection=selection, kind=spec.get("kind", "rbe2"),
                          master_point=spec.get("master_point"))


def options_from_job(path) -> ReduceOptions:
    """Read a TOML job file holding the ReduceOptions fields (paths relative to the file)."""
    try:
        import tomllib
    except ImportError:  # Python 3.10
        import tomli as tomllib
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise InputError(f"{path}: cannot read the job file ({exc}); fix the TOML syntax") from None
    valid = set(ReduceOptions.__dataclass_fields__)
    unknown = sorted(set(data) - valid)
    if unknown:
        raise InputError(f"{path}: unknown key(s) {', '.join(unknown)}; valid: {', '.join(sorted(valid))}")
    if "mesh" not in data:
        raise InputError(f"{path}: the job file needs mesh = \"FILE\"")
    data["mesh"] = str((path.parent / data["mesh"]).resolve()) if not Path(data["mesh"]).is_absolute() else data["mesh"]
    if isinstance(data.get("damping"), list):
        data["damping"] = tuple(data["damping"])
    data["interfaces"] = tuple(data.get("interfaces", ()))
    data["frm_nodes"] = tuple(data.get("frm_nodes", ()))
    return ReduceOptions(**data)


def check_options(o: ReduceOptions) -> None:
    """One-line InputErrors for inconsistent options."""
    if o.modes is not None and o.fmax is not None:
        raise InputError("--modes and --fmax: give one of them, not both")
    if o.modes is not None and o.modes < 1:
        raise InputError(f"--modes {o.modes}: must be >= 1")
    if o.fmax is not None and not o.fmax > 0:
        raise InputError(f"--fmax {o.fmax}: must be > 0 Hz")
    if not o.cutoff_factor >= 1:
        raise InputError(f"--cutoff-factor {o.cutoff_factor}: must be >= 1 (FEMBS default 5)")
    if isinstance(o.damping, dict):                    # the form, before the expensive work
        from sidprep.modes import modal_damping
        modal_damping(np.ones(1), o.damping)


# ---------------------------------------------------------------------------------------------
# the reduction
# ---------------------------------------------------------------------------------------------

def default_interfaces(mesh) -> list[str]:
    """Node sets that look like interfaces: patches able to carry 6 DOF, as RBE2 ("NAME:rbe2")."""
    from sidprep.interfaces import check_patch

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
                frm=True, cutoff_factor=5.0, load_nodes=(), phases=None) -> Reduction:
    """Steps 2-4 of the module docstring for an assembled FE model.

    interfaces : list of sidprep.interfaces.Interface; frame : "free" or an interface name;
    load_nodes : FE node indices that get 3 unit FRM forces each, besides every master DOF.
    """
    from sidprep.interfaces import interface_model, rigid_modes_model
    from sidprep.modes import modal_basis
    from sidprep.progress import Phases
    from sidprep.reduce import craig_bampton
    from sidprep.stiffening import support_dofs

    ph = phases or Phases(verbose=False)
    if n_modes is None and fmax is None:
        n_modes = DEFAULT_MODES
    names = [i.name for i in interfaces]
    if frame != "free" and frame not in names:
        raise InputError(f"--frame {frame}: no such interface; valid: free, {', '.join(names) or '(no interfaces)'}")
    with ph("interfaces", f"{len(interfaces)} master node(s)"):
        im = interface_model(mesh.n_nodes, interfaces, mesh.points)
        K_model, M_model = im.project(K_fe), im.project(M_fe)
        rigid = rigid_modes_model(im, mesh.points)
    boundary = im.master_dofs.ravel() if len(interfaces) else support_dofs(rigid, np.arange(im.n_model))
    with ph("craig-bampton", f"{len(boundary)} boundary DOF"):
        if fmax is not None:
            cb = craig_bampton(K_model, M_model, boundary, fmax=max(2.0, cutoff_factor) * fmax)
        else:
            cb = craig_bampton(K_model, M_model, boundary, n_modes=max(CB_MIN_MODES, 3 * n_modes))
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
    from sidprep.interfaces import linear_surface_triangles
    from sidprep.sid import SurfaceModes

    tri = linear_surface_triangles(mesh)
    nodes, tri = np.unique(tri, return_inverse=True)
    nq = Phi_fe.shape[1]
    shapes = Phi_fe.reshape(mesh.n_nodes, 3, nq)[nodes]
    return SurfaceModes(mesh.points[nodes], tri.reshape(-1, 3).astype(np.int64), shapes, mesh.node_ids[nodes])


def build_sid(red: Reduction, mesh, Ms, *, damping=DEFAULT_DAMPING, stiffening=None, metadata=None):
    """The SID of the reduced body: one node per interface master, surface modes attached."""
    from dataclasses import replace as dc_replace

    from sidprep.modes import modal_damping, mode_labels
    from sidprep.sid import sid_invariants

    f = red.basis.frequencies_hz
    first_id = int(mesh.node_ids.max()) + 1 if len(mesh.node_ids) else 1
    nodes = [(first_id + i, itf.master_point, red.Phi_model[m[:3]], red.Phi_model[m[3:]], itf.name)
             for i, (itf, m) in enumerate(zip(red.im.interfaces, red.im.master_dofs))]
    labels = mode_labels(f, first=7 if red.held is None else 1)
    sid = sid_invariants(mesh.points, Ms, red.Phi_fe, nodes, labels=labels, frequencies_hz=f,
                         mode_kinds=red.basis.kinds, Ke=np.diag((2 * np.pi * f) ** 2),
                         De=modal_damping(f, damping), stiffening=stiffening, metadata=metadata or {})
    return dc_replace(sid, surface=surface_modes(mesh, red.Phi_fe))


def output_paths(o: ReduceOptions) -> dict[str, Path]:
    """{"hdf5": ..., "sid_fem": ..., "obj": ...} for the enabled outputs (default: ./<mesh stem>.*)."""
    h5 = Path(o.output) if o.output else Path(Path(o.mesh).stem + ".sid.h5")
    stem = h5.name[:-len(".sid.h5")] if h5.name.endswith(".sid.h5") else h5.stem
    out = {"hdf5": h5}
    if o.sid_fem:
        out["sid_fem"] = h5.with_name(stem + ".SID_FEM")
    if o.obj:
        out["obj"] = h5.with_name(stem + ".obj")
    return out


def reduce_job(options: ReduceOptions) -> dict:
    """Run a reduction job and write its files; returns a JSON-ready summary (paths, checks, timings).

    Runs with one BLAS thread (sidprep.linalg.single_threaded_blas)."""
    from sidprep.linalg import single_threaded_blas

    with single_threaded_blas():
        return _reduce_job(options)


def _reduce_job(options: ReduceOptions) -> dict:
    from sidprep.assemble import mass_matrix, scalar_mass_matrix, stiffness_matrix
    from sidprep.interfaces import select_patch
    from sidprep.io.obj import write_obj
    from sidprep.io.sid_fem import write_sid_fem
    from sidprep.io.sid_hdf5 import write_sid_hdf5
    from sidprep.material import material_from_options, unit_system
    from sidprep.mesh import read_mesh
    from sidprep.progress import Phases, peak_memory_mb
    from sidprep.stiffening import stiffening_parts

    o = options
    check_options(o)
    ph = Phases(verbose=o.verbose)
    units = unit_system(o.units)
    material_name = o.material if (o.material or o.E is not None or o.nu is not None or o.rho is not None) else "steel"
    material = material_from_options(E=o.E, nu=o.nu, rho=o.rho, name=material_name, units=o.units)
    with ph("mesh", o.mesh):
        mesh = read_mesh(o.mesh, size=o.size, order=o.order).in_metres(units.length_to_m, units.name)
    notes = list(mesh.notes)
    if material_name == "steel" and not o.material:
        notes.append("material: none given, steel used (E = 210 GPa, nu = 0.3, rho = 7850 kg/m^3); "
                     "set --material or --E --nu --rho")
    if o.verbose:
        for note in notes:
            print(f"note: {note}", file=sys.stderr)
    interfaces = [interface_from_spec(mesh, s, units.length_to_m) for s in (o.interfaces or default_interfaces(mesh))]
    with ph("assemble", f"{mesh.n_dof} DOF"):
        K_fe = stiffness_matrix(mesh, material)
        M_fe = mass_matrix(mesh, material)
        Ms = scalar_mass_matrix(mesh, material.rho)
    load_nodes = np.unique(np.concatenate([np.zeros(0, np.int64)] + [select_patch(mesh, n) for n in o.frm_nodes]))
    red = reduce_body(mesh, K_fe, M_fe, interfaces, frame=o.frame, n_modes=o.modes, fmax=o.fmax,
                      frm=o.frm, cutoff_factor=o.cutoff_factor, load_nodes=load_nodes, phases=ph)
    stiff = None
    if o.stiffening:
        with ph("stiffening", "unit load cases"):
            stiff = stiffening_parts(mesh, material, M_fe, red.im, red.static_solve, red.Phi_fe)
    metadata = {"source": str(o.mesh), "mesh_sha256": mesh.sha256, "material": material.as_dict(), "notes": notes,
                "options": {k: v for k, v in asdict(o).items() if k != "verbose"},
                "interfaces": [{"name": i.name, "kind": i.kind, "nodes": int(len(i.nodes)),
                                "master_point_m": i.master_point.tolist()} for i in interfaces],
                "frame": o.frame, "frm_omega_hz": red.basis.frm_omega_hz, "cutoff_hz": red.basis.cutoff_hz,
                "rejected_frm_hz": red.basis.rejected_frm_hz.tolist(),
                "fixed_interface_modes": int(len(red.cb.fixed_interface_hz))}
    sid = build_sid(red, mesh, Ms, damping=o.damping, stiffening=stiff, metadata=metadata)
    with ph("checks", "reduced vs full FE model"):
        checks = fe_checks(red, mesh, M_fe, sid, full_frequencies=o.check_frequencies)
    sid = replace(sid, metadata={**sid.metadata, "checks": structured_checks(checks)})
    paths = output_paths(o)
    with ph("write", ", ".join(str(p) for p in paths.values())):
        write_sid_hdf5(sid, paths["hdf5"])
        if "sid_fem" in paths:
            write_sid_fem(sid, paths["sid_fem"], comment=f"sidprep reduce {Path(o.mesh).name}")
        if "obj" in paths:
            write_obj(paths["obj"], sid.surface.points, sid.surface.triangles)
    summary = {"files": {k: str(v) for k, v in paths.items()}, "dof": mesh.n_dof, "nq": sid.nq, "labels": list(sid.labels),
               "kinds": list(sid.mode_kinds), "notes": notes, "checks": checks, "timings_s": ph.timings_s,
               "peak_memory_mb": peak_memory_mb()}
    if o.verbose:
        print(format_checks(checks), file=sys.stderr)
    return summary


def summary_json(summary: dict) -> str:
    return json.dumps(summary, indent=2, default=float)
