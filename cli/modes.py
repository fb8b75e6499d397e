"""``sidprep modes MESH``: natural frequencies and modes of a tetrahedral FE model (free or clamped)."""

from __future__ import annotations

from cli.options import add_model_arguments


#: a part whose clamped nodes span a plane (rank 2 about their centroid) has no rigid-body mode
PLANAR_RANK = 2


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "modes", help="natural frequencies of a tetrahedral FE model (free-free or clamped node sets)",
        description="Assembles K and the consistent M (tet4 / tet10) and solves K phi = omega^2 M phi by "
                    "shift-invert Lanczos (CHOLMOD) or AMG-LOBPCG. Rigid-body modes are detected and listed "
                    "separately; --count counts ELASTIC modes. Without --material / --E --nu --rho the "
                    "material is steel (E = 210 GPa, nu = 0.3, rho = 7850 kg/m^3), as in 'sidprep reduce', "
                    "and a note says so.")
    p.add_argument("mesh", metavar="MESH", help="mesh (.msh .inp .bdf .vtu ...) or geometry (.geo .step .brep)")
    add_model_arguments(p, units_default="si")
    n = p.add_mutually_exclusive_group()
    n.add_argument("--count", type=int, help="number of elastic modes (default 10)")
    n.add_argument("--fmax", type=float, metavar="HZ", help="all modes up to this frequency")
    p.add_argument("--clamp", action="append", default=[], metavar="GROUP",
                   help="fix all DOFs of the nodes of this node set (repeat for several)")
    p.add_argument("--backend", default="auto", choices=("auto", "cholmod", "superlu", "lobpcg"),
                   help="eigen solver: shift-invert Lanczos with CHOLMOD / SuperLU, or AMG-LOBPCG (large models)")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout instead of the table")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress lines on stderr")
    p.set_defaults(func=run)


def clamped_nodes(mesh, groups: list[str]):
    """Sorted node indices of the node sets ``groups``; InputError naming the available sets."""
    import numpy as np

    from sidprep.errors import InputError

    for g in groups:
        if g not in mesh.node_sets:
            available = ", ".join(sorted(mesh.node_sets)) or "none"
            raise InputError(f"--clamp {g}: {mesh.source or 'mesh'} has no node set '{g}'; available: {available}")
    if not groups:
        return np.zeros(0, dtype=np.int64)
    return np.unique(np.concatenate([mesh.node_sets[g] for g in groups]))


def rigid_mode_bound(mesh, clamped) -> int:
    """Upper bound of the rigid-body mode count: 6 per free part, 0 for a part clamped at nodes that
    span a plane, 3 otherwise (a point or a line of clamped nodes leaves rotations free)."""
    import numpy as np

    from sidprep.mesh import connected_parts

    n_parts, labels = connected_parts(mesh)
    bound = 0
    for part in range(n_parts):
        x = mesh.points[clamped[labels[clamped] == part]]
        if len(x) == 0:
            bound += 6
        elif np.linalg.matrix_rank(x - x.mean(axis=0), tol=1e-9 * np.ptp(mesh.points)) < PLANAR_RANK:
            bound += 3
    return bound


def run(args) -> int:
    import json

    from sidprep.assemble import stiffness_and_mass
    from sidprep.linalg import clamp_dofs, eigen_modes, fast_blas, node_dofs, rigid_body_modes
    from sidprep.material import material_from_options, unit_system
    from sidprep.mesh import read_mesh
    from sidprep.progress import Phases, peak_memory_mb

    notes = []
    units = unit_system(args.units)
    if args.material is None and all(v is None for v in (args.E, args.nu, args.rho)):
        material = material_from_options(name="steel")
        notes.append("no material given: steel (E = 210 GPa, nu = 0.3, rho = 7850 kg/m^3)")
    else:
        material = material_from_options(E=args.E, nu=args.nu, rho=args.rho, name=args.material, units=args.units)
    count = args.count if args.count is not None or args.fmax is not None else 10
    ph = Phases(verbose=not args.quiet)
    with ph("mesh", args.mesh):
        mesh = read_mesh(args.mesh, size=args.size, order=args.order or 2)
        mesh = mesh.in_metres(units.length_to_m, units.name)
    notes.extend(mesh.notes)
    clamped = clamped_nodes(mesh, args.clamp)
    with ph("assemble", f"{mesh.n_dof} DOF, tet{4 if mesh.order == 1 else 10}"):
        K, M = stiffness_and_mass(mesh, material)
    mass_kg = float(M.sum() / 3.0)
    restriction = clamp_dofs(mesh.n_dof, node_dofs(clamped))
    if len(clamped):
        K, M = restriction.restrict(K), restriction.restrict(M)
    near_null = rigid_body_modes(mesh.points)[restriction.free] if args.backend == "lobpcg" else None
    res = eigen_modes(K, M, count=count, fmax=args.fmax, backend=args.backend,
                      n_rigid_max=rigid_mode_bound(mesh, clamped), near_null=near_null, phases=ph)
    f = res.frequencies_hz
    nr = res.n_rigid
    summary = {
        "mesh": {"file": str(args.mesh), "sha256": mesh.sha256, "nodes": mesh.n_nodes,
                 "elements": int(mesh.cells.shape[0]), "element": "tet4" if mesh.order == 1 else "tet10"},
        "n_dof": mesh.n_dof, "n_free_dof": int(K.shape[0]), "clamped": list(args.clamp),
        "units": {"input": units.name, "output": "SI (m, kg, s, Hz)"}, "material": material.as_dict(),
        "mass_kg": mass_kg, "rigid_modes": nr,
        "rigid_frequencies_hz": f[:nr].tolist(), "rigid_residuals": res.residuals[:nr].tolist(),
        "frequencies_hz": f[nr:].tolist(), "residuals": res.residuals[nr:].tolist(),
        "backend": res.backend, "blas": fast_blas() if res.backend == "cholmod" else None,
        "sigma_rad2_s2": res.sigma,
        "timings_s": {k: round(v, 3) for k, v in ph.timings_s.items()},
        "peak_memory_mb": round(peak_memory_mb(), 1), "notes": notes,
    }
    if args.json:
        print(json.dumps(summary))
        return 0
    print(f"{args.mesh}: {mesh.n_dof} DOF ({K.shape[0]} free), mass {mass_kg:.6g} kg, material {material.name}, "
          f"{nr} rigid-body mode(s)")
    print(f"{'mode':>5} {'f [Hz]':>14} {'kind':>8} {'residual':>10}")
    for i, (fi, ri) in enumerate(zip(f, res.residuals), start=1):
        print(f"{i:5d} {fi:14.6f} {'rigid' if i <= nr else 'elastic':>8} {ri:10.1e}")
    for note in notes:
        print(f"note: {note}")
    return 0
