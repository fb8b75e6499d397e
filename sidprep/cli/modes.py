"""``sidprep modes MESH``: natural frequencies and modes of a tetrahedral FE model (free or clamped)."""

from __future__ import annotations

import sys

from sidprep.cli.options import add_count, add_json, add_model_arguments, add_quiet, cli_flags, quiet_native_output


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
    add_count(n)
    n.add_argument("--fmax", type=float, metavar="HZ", help="all modes up to this frequency")
    p.add_argument("--clamp", action="append", default=[], metavar="GROUP",
                   help="fix all DOFs of the nodes of this node set (repeat for several)")
    p.add_argument("--backend", default="auto", choices=("auto", "cholmod", "superlu", "lobpcg", "dense"),
                   help="eigen solver: shift-invert Lanczos with CHOLMOD / SuperLU, or AMG-LOBPCG (large models)")
    add_json(p)
    add_quiet(p)
    p.set_defaults(func=run)


def modal_options(args):
    """ModalOptions from the command line."""
    from sidprep.jobs.options import ModalOptions

    return ModalOptions(size=args.size, order=args.order or 2, E=args.E, nu=args.nu, rho=args.rho,
                        material=args.material, units=args.units,
                        count=None if args.fmax is not None else args.count, fmax=args.fmax,
                        clamp=tuple(args.clamp), backend=args.backend)


def run(args) -> int:
    import json

    from sidprep.jobs.modal import modal_analysis
    from sidprep.errors import WARNING_PREFIX, note_line
    from sidprep.fe.linalg import fast_blas
    from sidprep.progress import Phases, peak_memory_mb

    ph = Phases(verbose=not args.quiet)
    with cli_flags(), quiet_native_output():
        res = modal_analysis(args.mesh, modal_options(args), phases=ph)
    f, nr, mesh = res.frequencies_hz, res.n_rigid, res.mesh
    for note in res.notes:
        if not args.quiet or note.startswith(WARNING_PREFIX):     # -q: the warnings only
            print(note_line(note), file=sys.stderr)
    summary = {
        "mesh": {"file": str(args.mesh), "sha256": mesh.sha256, "nodes": mesh.n_nodes,
                 "elements": int(mesh.cells.shape[0]), "element": "tet4" if mesh.order == 1 else "tet10"},
        "n_dof": res.n_dof, "n_free_dof": res.n_free_dof, "clamped": list(args.clamp),
        "units": {"input": args.units, "output": "SI (m, kg, s, Hz)"}, "material": res.material.as_dict(),
        "mass_kg": res.mass_kg, "rigid_modes": nr,
        "rigid_frequencies_hz": f[:nr].tolist(), "rigid_residuals": res.residuals[:nr].tolist(),
        "frequencies_hz": f[nr:].tolist(), "residuals": res.residuals[nr:].tolist(),
        "backend": res.backend, "blas": fast_blas() if res.backend == "cholmod" else None,
        "sigma_rad2_s2": res.sigma_rad2_s2,
        "timings_s": {k: round(v, 3) for k, v in res.timings_s.items()},
        "peak_memory_mb": round(peak_memory_mb(), 1), "notes": list(res.notes),
    }
    if args.json:
        print(json.dumps(summary))
        return 0
    print(f"{args.mesh}: {res.n_dof} DOF ({res.n_free_dof} free), mass {res.mass_kg:.6g} kg, "
          f"material {res.material.name}, {nr} rigid-body mode(s)")
    print(f"{'mode':>5} {'f [Hz]':>14} {'kind':>8} {'residual':>10}")
    for i, (fi, ri) in enumerate(zip(f, res.residuals), start=1):
        print(f"{i:5d} {fi:14.6f} {'rigid' if i <= nr else 'elastic':>8} {ri:10.1e}")
    return 0
