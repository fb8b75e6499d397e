#!/usr/bin/env python3
"""What accuracy costs in time: FE discretisation, reduction, time integration (run on demand).

    python benchmarks/accuracy_cost.py [--part fe reduce solve] [--repeat 3] [--quick]

Prints markdown tables and writes PNG plots (matplotlib Agg) into ``docs/img/``; the measured
tables and their reading are in ``docs/accuracy-cost.md``.

a. ``fe``: the validation bar (1.0 x 0.05 x 0.08 m steel, E = 210 GPa, nu = 0.3, rho = 7850),
   clamped on x = 0, meshed by gmsh at several element sizes, tet4 and tet10.  Error of the first
   10 frequencies against CalculiX C3D10 at h = 0.007 m (262k DOF,
   ``../shared/validation/results/cantilever.csv``); its change from h = 0.01 m (at most 4.3e-4,
   torsion modes; 1.3e-4 for f1) bounds what the table can resolve.  Wall time = mesh + assembly + eigen solve.
b. ``reduce``: the bundled piston rod (``data/meshes/piston_rod.msh``, default RBE2 interfaces,
   free frame): number of eigenmodes, FRMs on/off, cut-off factor.  Errors against the full
   FE model (same interface model): static deflection at the masters under unit loads
   (sidprep.reduction.fe_checks.master_compliance_full) and the first elastic frequencies.  Time =
   ``reduce_body`` (Craig-Bampton + modal basis), body size nq.
c. ``solve``: the 10-mode flexible pendulum of ``benchmarks/solver_speed.py`` (bundled bar,
   hinge and tip SID nodes, 1 s): fixed step sizes, step-size control tolerances, rho_inf and
   effects on/off, errors of hinge angle and tip deflection against a tight reference
   (h = 2.5e-5 s, Newton tolerance 1e-12, all effects of the row's set), CPU s per simulated s.

Every time is the median of ``--repeat`` runs; the load average of the shared machine is printed.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))
IMG = ROOT / "docs" / "img"
VALIDATION = ROOT.parent / "shared" / "validation" / "results"

N_FREQ = 10
#: element sizes (m) per element order; the largest levels are ~100k DOF (2 shared cores)
FE_SIZES = {1: (0.02, 0.0125, 0.008, 0.0055), 2: (0.05, 0.03, 0.02, 0.014, 0.01)}
FE_SIZES_QUICK = {1: (0.02, 0.0125), 2: (0.05, 0.03)}
STEEL = dict(E=210e9, nu=0.3, rho=7850.0)
PISTON_ROD = ROOT / "data" / "meshes" / "piston_rod.msh"
N_FULL = 20            # full-model elastic modes of the reduction reference


def load_average() -> str:
    return "load average %.1f %.1f %.1f" % os.getloadavg()


def finish(fig, axes, xlabels, ylabels, target, title, name) -> None:
    """Label the log-scale panels, draw the accuracy target (dotted), save docs/img/<name>."""
    for ax, xlabel, ylabel in zip(axes, xlabels, ylabels):
        ax.axhline(target, color="grey", ls=":", lw=1)
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(IMG / name, dpi=110)


def median_time(fn, repeat: int):
    """(result of the last call, median wall time s) of ``repeat`` calls of fn()."""
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return out, float(np.median(times))


# ---------------------------------------------------------------------------------------------
# a. FE discretisation
# ---------------------------------------------------------------------------------------------

def calculix_reference(level: str = "bar_h0.007") -> np.ndarray:
    """First N_FREQ cantilever frequencies (Hz) of CalculiX C3D10 on the given validation mesh."""
    import csv

    with open(VALIDATION / "cantilever.csv") as f:
        row = next(r for r in csv.DictReader(f) if r["mesh"] == level and r["tool"] == "calculix")
    return np.array([float(row[f"f{i}_Hz"]) for i in range(1, N_FREQ + 1)])


def timoshenko_reference() -> np.ndarray:
    """Timoshenko / 1D values of the same 6 cantilever modes (validation analytical_bar.csv)."""
    import csv

    with open(VALIDATION / "cantilever_compare.csv") as f:
        rows = [r for r in csv.DictReader(f) if r["mesh"] == "bar_h0.007"]
    return np.array([float(r["ref_Timoshenko_or_1D_Hz"]) for r in rows[:N_FREQ]])


def cantilever_frequencies(h: float, order: int, folder: Path) -> tuple[np.ndarray, int]:
    """Mesh, assemble and solve the clamped bar: (first N_FREQ frequencies Hz, DOF)."""
    from reduce import BAR_GEO

    from sidprep.fe.assemble import mass_matrix, stiffness_matrix
    from sidprep.fe.linalg import clamp_dofs, eigen_modes, node_dofs
    from sidprep.fe.material import Material
    from sidprep.fe.mesh import read_mesh

    geo = folder / "bar.geo"
    geo.write_text(BAR_GEO.format(h=h))
    mesh = read_mesh(geo, order=order)
    material = Material(name="steel", **STEEL)
    K, M = stiffness_matrix(mesh, material), mass_matrix(mesh, material)
    clamp = clamp_dofs(mesh.n_dof, node_dofs(np.flatnonzero(mesh.points[:, 0] < 1e-9)))
    ev = eigen_modes(clamp.restrict(K), clamp.restrict(M), count=N_FREQ)
    return ev.frequencies_hz[ev.n_rigid:], mesh.n_dof


def fe_study(repeat: int, quick: bool) -> list[dict]:
    ref, timo = calculix_reference(), timoshenko_reference()
    ref_err = np.abs(calculix_reference("bar_h0.01") / ref - 1)
    print(f"\n## a. FE discretisation: clamped bar, first {N_FREQ} frequencies ({load_average()})")
    print("reference CalculiX C3D10 h = 0.007 m: " + ", ".join(f"{f:.3f}" for f in ref)
          + f" Hz (its change from h = 0.01: max {ref_err.max():.1e}); Timoshenko / 1D: "
          + ", ".join(f"{f:.2f}" for f in timo))
    print(f"| element | h [m] | DOF | max rel. error f1-f{N_FREQ} | f1-f6 | f1 | max rel. diff. to Timoshenko | "
          "wall s (median) |")
    print("|---|---|---|---|---|---|---|---|")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for order, sizes in (FE_SIZES_QUICK if quick else FE_SIZES).items():
            for h in sizes:
                (f, dof), wall = median_time(lambda: cantilever_frequencies(h, order, Path(tmp)),
                                             1 if h == sizes[-1] else repeat)
                err = np.abs(f / ref - 1)
                row = dict(element=f"tet{4 if order == 1 else 10}", h=h, dof=dof, err=err.max(), err6=err[:6].max(), err1=err[0],
                           timo=np.abs(f / timo - 1).max(), wall=wall)
                rows.append(row)
                print(f"| {row['element']} | {h:g} | {dof} | {row['err']:.2e} | {row['err6']:.2e} | {row['err1']:.2e} | "
                      f"{row['timo']:.2e} | {wall:.2f} |", flush=True)
    return rows


def plot_fe(rows: list[dict]) -> None:
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for element, marker in (("tet4", "s-"), ("tet10", "o-")):
        r = [x for x in rows if x["element"] == element]
        for ax, key in zip(axes, ("dof", "wall")):
            ax.loglog([x[key] for x in r], [x["err"] for x in r], marker, label=element)
    finish(fig, axes, ("DOF", "wall time [s] (mesh + assembly + eigen)"), (f"max rel. error f1-f{N_FREQ}",) * 2, 1e-3,
           "Clamped steel bar 1.0 x 0.05 x 0.08 m vs CalculiX C3D10 at 262k DOF", "accuracy_fe.png")
    plt.close(fig)


# ---------------------------------------------------------------------------------------------
# b. reduction
# ---------------------------------------------------------------------------------------------

def reduction_variants(quick: bool) -> list[tuple[str, dict]]:
    if quick:
        return [("modes 6, FRM, cut-off 5", dict(n_modes=6)), ("modes 6, no FRM", dict(n_modes=6, frm=False))]
    rows = [(f"modes {n}, FRM, cut-off 5", dict(n_modes=n)) for n in (2, 4, 6, 8, 12, 16)]
    rows += [(f"modes {n}, no FRM", dict(n_modes=n, frm=False)) for n in (6, 8, 12, 16, 24, 32)]
    rows += [(f"modes 6, FRM, cut-off {c:g}", dict(n_modes=6, cutoff_factor=c)) for c in (2, 3, 10, 20)]
    return rows


def reduced_compliance(red, loads: np.ndarray) -> np.ndarray:
    """Static deflection of the basis at the load DOFs: Phi diag(1/omega^2) Phi^T (free body:
    mean-axis deflection, sid-spec 4.8); (nl,) diagonal."""
    Pm = red.Phi_model[loads]
    return np.einsum("ij,j,ij->i", Pm, 1.0 / (2 * np.pi * red.basis.frequencies_hz) ** 2, Pm)


def reduce_study(repeat: int, quick: bool) -> list[dict]:
    from sidprep.fe.assemble import mass_matrix, stiffness_matrix
    from sidprep.fe.linalg import eigen_modes
    from sidprep.fe.material import builtin_material
    from sidprep.fe.mesh import read_mesh
    from sidprep.reduction.fe_checks import master_compliance_full
    from sidprep.jobs.reduce import default_interfaces, interface_from_spec, reduce_body

    mesh = read_mesh(PISTON_ROD)
    material = builtin_material("steel")
    K, M = stiffness_matrix(mesh, material), mass_matrix(mesh, material)
    interfaces = [interface_from_spec(mesh, s) for s in default_interfaces(mesh)]
    first = reduce_body(mesh, K, M, interfaces, n_modes=6)
    loads, C_full = master_compliance_full(first)
    c_full = np.diag(C_full)
    force = np.isin(loads, first.im.master_dofs[:, :3])
    ev = eigen_modes(first.K_model, first.M_model, count=N_FULL)
    f_full = ev.frequencies_hz[ev.n_rigid:]
    print(f"\n## b. Reduction: piston rod, {mesh.n_dof} DOF, interfaces {', '.join(i.name for i in interfaces)} "
          f"(RBE2), free frame ({load_average()})")
    print("full model elastic frequencies: " + ", ".join(f"{f:.0f}" for f in f_full[:10]) + " Hz")
    print("| basis | nq | eigen + FRM | static deflection error (max, unit forces) | rotation error (unit moments) | "
          "max freq. error of kept eigenmodes | freq. error f7-f10 (full modes beyond the kept ones) | reduce_body s |")
    print("|---|---|---|---|---|---|---|---|")
    rows = []
    for label, kw in reduction_variants(quick):
        red, wall = median_time(lambda: reduce_body(mesh, K, M, interfaces, **kw), repeat)
        err = np.abs(reduced_compliance(red, loads) / c_full - 1)
        f_red = np.sort(red.basis.frequencies_hz)
        n_eig = sum(k == "eigen" for k in red.basis.kinds)
        n_cmp = min(len(f_red), 10)
        ferr = np.abs(f_red[:n_cmp] / f_full[:n_cmp] - 1)
        beyond = ferr[n_eig:] if n_cmp > n_eig else np.zeros(0)
        row = dict(label=label, nq=red.Phi_fe.shape[1], n_eig=n_eig, static=err[force].max(),
                   rotation=err[~force].max(), freq=ferr[:n_eig].max(),
                   beyond=beyond.max() if len(beyond) else float("nan"), wall=wall, frm=kw.get("frm", True))
        rows.append(row)
        print(f"| {label} | {row['nq']} | {n_eig} + {row['nq'] - n_eig} | {row['static']:.2e} | {row['rotation']:.2e} | "
              f"{row['freq']:.1e} | {row['beyond']:.1e} | {wall:.2f} |", flush=True)
    return rows


def plot_reduce(rows: list[dict]) -> None:
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    groups = (("eigenmodes + FRM (cut-off 5)", lambda r: r["frm"] and "cut-off 5" in r["label"], "o-"),
              ("eigenmodes only", lambda r: not r["frm"], "s-"),
              ("6 eigenmodes + FRM, cut-off 2-20", lambda r: r["frm"] and "modes 6" in r["label"], "^"))
    for name, pick, marker in groups:
        r = sorted((x for x in rows if pick(x)), key=lambda x: x["nq"])
        axes[0].semilogy([x["nq"] for x in r], [x["static"] for x in r], marker, label=name)
        axes[1].semilogy([x["wall"] for x in r], [x["static"] for x in r], marker[0], label=name)   # noisy: no line
    finish(fig, axes, ("body size nq", "reduce_body wall time [s]"), ("static deflection error at the masters",) * 2, 1e-2,
           "Piston rod: reduced basis vs full FE model (FEMBS promise 1 % dotted)", "accuracy_reduce.png")
    plt.close(fig)


# ---------------------------------------------------------------------------------------------
# c. time integration
# ---------------------------------------------------------------------------------------------

#: divisors of the output interval: with a fixed step the samples fall on the step ending at or
#: after each requested time, so other steps would be compared at shifted times
SOLVE_STEPS = (1e-4, 2.5e-4, 1e-3, 2.5e-3, 5e-3, 1e-2)
SOLVE_RTOLS = (1e-4, 1e-5, 1e-6, 1e-7)
EFFECT_SETS = {
    "auto": "auto",
    "constant mass (no inertia_change)": ["gravity", "coupling", "coriolis", "centrifugal", "damping"],
    "all": "all",
}


def pendulum_run(sid, h, *, rtol=None, newton_tol=1e-8, effects="auto", rho_inf=0.9):
    """(times (nt,) s, hinge angle (nt,) rad, tip deflection Phi_tip q (nt, 3) m, CPU s per
    simulated s, stats)."""
    from solver_speed import OUTPUT_DT, T_END, pendulum

    res = simulate(pendulum(sid, planar=False), T_END, h=h, rtol=rtol, newton_tol=newton_tol, output_dt=OUTPUT_DT,
                                               static_start=True, effects=effects, rho_inf=rho_inf)
    deflection = res.bodies["bar"].q @ sid.nodes[1].phi.M0.T
    return res.t, res.joints["hinge"].coordinate, deflection, res.stats["cpu_integration"] / T_END, res.stats


def solve_specs(quick: bool) -> list[tuple[str, str, dict]]:
    steps = (1e-3, 1e-2) if quick else SOLVE_STEPS
    specs = [("step", f"h = {h:g}", dict(h=h)) for h in steps]
    specs += [("rtol", f"rtol = {r:g}", dict(h=1e-3, rtol=r)) for r in ((1e-5,) if quick else SOLVE_RTOLS)]
    specs += [("rho_inf", f"rho_inf = {r:g}, h = 1e-3", dict(h=1e-3, rho_inf=r)) for r in (0.5, 0.0)]
    specs += [("effects", f"effects {name}, h = 1e-3", dict(h=1e-3, effects=eff)) for name, eff in EFFECT_SETS.items()]
    return specs


def solve_study(repeat: int, quick: bool) -> list[dict]:
    from solver_speed import H_REF, reduced_bar

    from sidprep.sid.io import read_sid

    with tempfile.TemporaryDirectory() as tmp:
        sid = read_sid(reduced_bar(Path(tmp)))
    pendulum_run(sid, 1e-3)                               # numba cache load
    refs = {}

    def reference(effects):
        key = str(effects)
        if key not in refs:
            refs[key] = pendulum_run(sid, H_REF, newton_tol=1e-12, effects=effects)[:3]
        return refs[key]

    auto_ref = reference("auto")
    scale = np.max(np.linalg.norm(auto_ref[2], axis=1))
    print(f"\n## c. Time integration: 10-mode flexible pendulum, 1 s, 3D coordinates ({load_average()})")
    print(f"reference h = {H_REF:g} s, Newton tol 1e-12, same effects; max tip deflection {scale:.3e} m")
    print("| study | run | steps | angle error [deg] | tip error [rel] | diff. to auto reference: angle [deg] / tip [rel] | "
          "CPU s / sim s (median) |")
    print("|---|---|---|---|---|---|---|")
    rows = []
    for study, label, kw in solve_specs(quick):
        out = [pendulum_run(sid, **kw) for _ in range(repeat)]
        t, angle, defl, _, stats = out[0]
        ref = reference(kw.get("effects", "auto"))
        if t.shape != ref[0].shape or not np.allclose(t, ref[0], rtol=0, atol=1e-9):
            print(f"| {study} | {label} | output times differ from the reference |")
            continue
        row = dict(study=study, label=label, steps=stats["steps"],
                   angle=float(np.degrees(np.abs(angle - ref[1]).max())),
                   tip=float(np.linalg.norm(defl - ref[2], axis=1).max() / scale),
                   d_angle=float(np.degrees(np.abs(ref[1] - auto_ref[1]).max())),
                   d_tip=float(np.linalg.norm(ref[2] - auto_ref[2], axis=1).max() / scale),
                   cpu=float(np.median([o[3] for o in out])))
        rows.append(row)
        print(f"| {study} | {label} | {row['steps']} | {row['angle']:.2e} | {row['tip']:.2e} | "
              f"{row['d_angle']:.1e} / {row['d_tip']:.1e} | {row['cpu']:.4f} |", flush=True)
    return rows


def plot_solve(rows: list[dict]) -> None:
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for study, marker, name in (("step", "o-", "fixed step"), ("rtol", "s-", "step-size control")):
        r = sorted((x for x in rows if x["study"] == study), key=lambda x: x["cpu"])
        for ax, key in zip(axes, ("angle", "tip")):
            ax.loglog([x["cpu"] for x in r], [x[key] for x in r], marker, label=name)
    finish(fig, axes, ("CPU s per simulated s",) * 2, ("hinge angle error [deg]", "tip deflection error [rel]"), 1e-3,
           "10-mode flexible pendulum, generalised-alpha, vs h = 2.5e-5 s", "accuracy_solve.png")
    plt.close(fig)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--part", nargs="*", choices=("fe", "reduce", "solve"), default=["fe", "reduce", "solve"])
    p.add_argument("--repeat", type=int, default=3, help="runs per configuration (median time)")
    p.add_argument("--quick", action="store_true", help="two configurations per part, one run each")
    args = p.parse_args(argv)
    import matplotlib

    matplotlib.use("Agg")
    IMG.mkdir(parents=True, exist_ok=True)
    repeat = 1 if args.quick else args.repeat
    if "fe" in args.part:
        plot_fe(fe_study(repeat, args.quick))
    if "reduce" in args.part:
        plot_reduce(reduce_study(repeat, args.quick))
    if "solve" in args.part:
        plot_solve(solve_study(repeat, args.quick))
    print(f"\nplots in {IMG.relative_to(ROOT)}; {load_average()}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
