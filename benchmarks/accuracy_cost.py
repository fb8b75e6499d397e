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
import json
import os
import sys
import tempfile
import time
from dataclasses import dataclass, replace
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

    from sidprep.solver.run import simulate

    res = simulate(pendulum(sid, planar=False), T_END, h=h, rtol=rtol, newton_tol=newton_tol, output_dt=OUTPUT_DT,
                                               static_start=True, effects=effects, rho_inf=rho_inf)
    deflection = res.bodies["bar"].q @ sid.nodes[1].phi.M0.T
    return res.t, res.joints["hinge"].coordinate, deflection, res.stats.cpu_integration / T_END, res.stats


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
    pendulum_run(sid, 1e-3)                               # warm-up
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
        row = dict(study=study, label=label, steps=stats.steps,
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


# ---------------------------------------------------------------------------------------------
# d. integration methods on the examples
# ---------------------------------------------------------------------------------------------

#: a modal coordinate is compared when its peak is at least this share of its body's largest
MODE_SHARE = 0.1
#: Newton tolerance of the generalised-alpha reference runs (position correction / system length)
REFERENCE_NEWTON_TOL = 1e-11
GA_FIXED, GA_RTOL, RK4, RK45, DOP853 = ("genalpha, fixed h", "genalpha, rtol", "rk4, fixed h", "rk45, rtol",
                                        "dop853, rtol")
METHOD_STYLE = {GA_FIXED: "o-", GA_RTOL: "s--", RK4: "^-", RK45: "v--", DOP853: "D--"}


@dataclass(frozen=True)
class MethodCase:
    """One scene of the method study: its file (``prepare`` makes the folder), the simulated
    time (s), the joints whose coordinates and the flexible bodies whose modal coordinates
    (those with a peak >= MODE_SHARE of the body's largest) are compared, the settings of the
    reference run, of a looser run of the same method (their difference bounds the reference's
    error) and of an independent run of the other family, and the ladder of settings per method."""

    name: str
    scene: str
    t_end: float
    joints: tuple
    bodies: tuple
    reference: dict
    looser: dict
    independent: dict
    ladders: dict
    prepare: object = None


def method_cases(quick: bool) -> list[MethodCase]:
    """The three scenes and their ladders (h in s)."""
    def ladders(steps, h0, rtols, rk4, rk45, dop853):
        out = {GA_FIXED: [dict(h=h) for h in steps], GA_RTOL: [dict(h=h0, rtol=r) for r in rtols],
               RK4: [dict(method="rk4", h=h) for h in rk4], RK45: [dict(method="rk45", h=h0, rtol=r) for r in rk45],
               DOP853: [dict(method="dop853", h=h0, rtol=r) for r in dop853]}
        return {k: v[:2 if k == GA_FIXED else 1] if quick else v for k, v in out.items()}

    def ga(h):
        return dict(h=h, newton_tol=REFERENCE_NEWTON_TOL)

    def dop(rtol, h0):
        return dict(method="dop853", rtol=rtol, atol=1e-14, h=h0)

    from engine import prepared_folder

    return [
        MethodCase("flexible pendulum", "flexible_pendulum/scene.toml", 1.0, ("hinge",), ("bar",),
                   dop(1e-11, 1e-4), dop(1e-10, 1e-4), ga(1.25e-5),
                   ladders((1e-2, 5e-3, 2e-3, 1e-3, 5e-4, 2e-4, 1e-4, 5e-5, 2.5e-5), 1e-3, (1e-4, 1e-5, 1e-6, 1e-7, 1e-8),
                           (1.5e-4, 1e-4, 5e-5), (1e-3, 1e-6), (1e-3, 1e-7))),
        MethodCase("seed slider crank", "beam_slider_crank/scene.toml", 10.0, ("slider_joint",), ("crank", "conrod"),
                   ga(3.125e-5), ga(6.25e-5), dop(1e-9, 1e-3),
                   ladders((1e-2, 5e-3, 2e-3, 1e-3, 5e-4, 2.5e-4), 2e-3, (1e-5, 1e-6, 1e-7, 1e-8), (2e-3, 1e-3),
                           (1e-4, 1e-6), (1e-4, 1e-6, 1e-8))),
        MethodCase("engine, flexible rod (0.1 s)", "engine/scene.toml", 0.1, ("crank_joint", "piston_joint"),
                   ("rod",), dop(1e-10, 1e-5), dop(1e-9, 1e-5), ga(1.25e-5),
                   ladders((1e-3, 5e-4, 2e-4, 1e-4, 5e-5, 2.5e-5, 1.25e-5), 2e-4, (1e-5, 1e-6, 1e-7, 1e-8), (4e-5, 2e-5),
                           (1e-6,), (1e-6, 1e-8)),
                   prepare=lambda tmp: prepared_folder(tmp) / "scene.toml"),
    ]


def compared_signals(result, case: MethodCase, modes: dict) -> list[np.ndarray]:
    """The joint coordinates and the chosen modal coordinates (modes: body -> indices) of a run."""
    return ([result.joints[j].coordinate for j in case.joints]
            + [result.bodies[b].q[:, k] for b in case.bodies for k in modes[b]])


def relative_error(result, reference, case: MethodCase, modes: dict, joints_only: bool = False) -> float:
    """max over the compared signals (or the joint coordinates only) of
    max_t |x - x_ref| / max_t |x_ref| at the output times."""
    if result.t.shape != reference.t.shape or np.max(np.abs(result.t - reference.t)) > 1e-9:
        raise ValueError(f"{case.name}: output times differ from the reference's")
    pairs = list(zip(compared_signals(result, case, modes), compared_signals(reference, case, modes)))
    return max(float(np.max(np.abs(x - r)) / np.max(np.abs(r))) for x, r in pairs[:len(case.joints) if joints_only else None])


def timed_runs(run, kw: dict, repeat: int):
    """(last Result or the failure message, median integration CPU s, median whole-run CPU s)
    of ``repeat`` runs (process time; whole run = set-up + integration + post-processing)."""
    from sidprep.errors import SimulationFailed

    integ, total, result = [], [], None
    for _ in range(repeat):
        t0 = time.process_time()
        try:
            result = run(**kw)
        except SimulationFailed as exc:
            return str(exc).splitlines()[0][:90], np.nan, np.nan
        total.append(time.process_time() - t0)
        integ.append(result.stats.cpu_integration)
        if not all(np.all(np.isfinite(b.q)) and np.all(np.isfinite(b.position)) for b in result.bodies.values()):
            return "diverged (non-finite state, no error raised)", np.nan, np.nan
    return result, float(np.median(integ)), float(np.median(total))


def fixed_step_cpu(rows: list[dict], error: float, key: str = "error") -> tuple[float, bool]:
    """CPU of the fixed-step generalised-alpha curve of the same scene at ``error`` (``key``: all
    signals or "joints"): its Pareto front (the runs more accurate than every cheaper one),
    interpolated log-log; beyond its ends the end segment's slope, flagged True."""
    front = []
    for cpu, err in sorted((r["integ"], r[key]) for r in rows if r["method"] == GA_FIXED and np.isfinite(r[key])):
        if not front or err < front[-1][1]:
            front.append((cpu, err))
    c, e = np.log([p[0] for p in front])[::-1], np.log([p[1] for p in front])[::-1]
    x = np.log(error)
    if len(front) > 1 and e[0] <= x <= e[-1]:
        return float(np.exp(np.interp(x, e, c))), False
    if len(front) == 1:
        return float(np.exp(c[0])), True
    i = (0, 1) if x < e[0] else (-2, -1)
    slope = (c[i[1]] - c[i[0]]) / (e[i[1]] - e[i[0]])
    return float(np.exp(c[i[0]] + slope * (x - e[i[0]]))), True


def print_method_rows(rows: list[dict]) -> None:
    """The markdown table of one scene's rows; the last columns compare each run's integration
    CPU with the fixed-step generalised-alpha curve at the same error (< 1: the run is cheaper)."""
    print("| method | setting | steps | rejected | mean h [s] | error | joints only | integration CPU s | "
          "whole-run CPU s | CPU / fixed genalpha at equal error | the same, joints only |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for row in rows:
        if "failed" in row:
            print(f"| {row['method']} | {row['setting']} | - | - | - | {row['failed']} | - | - | - | - | - |")
            continue
        ratios = []
        for key in ("error", "joints"):
            if row["method"] == GA_FIXED:
                ratios.append("1")
                continue
            cpu, extrapolated = fixed_step_cpu(rows, row[key], key)
            ratios.append(f"{row['integ'] / cpu:.2g}" + (" (extrap.)" if extrapolated else ""))
        print(f"| {row['method']} | {row['setting']} | {row['steps']} | {row['rejected']} | {row['mean_h']:.2g} | "
              f"{row['error']:.2e} | {row['joints']:.2e} | {row['integ']:.3f} | {row['total']:.3f} | "
              f"{ratios[0]} | {ratios[1]} |", flush=True)


def step_history(result) -> str:
    """min / 10 % / median / 90 % / max of the accepted steps of a run sampled at every step, s."""
    h = np.diff(result.t)[:-1]          # the last step is cut to land on t_end
    return " / ".join(f"{v:.2g}" for v in np.percentile(h, (0, 10, 50, 90, 100)))


def method_study(repeat: int, quick: bool, names=None) -> list[dict]:
    from sidprep.solver.run import simulate
    from sidprep.solver.scene import load_scene, simulate as run_scene

    os.environ.setdefault("OMP_NUM_THREADS", "1")
    rows = []
    for case in method_cases(quick):
        if names and not any(n in case.name for n in names):
            continue
        with tempfile.TemporaryDirectory() as tmp:
            path = case.prepare(Path(tmp)) if case.prepare else ROOT / "examples" / case.scene
            scene = load_scene(path)

            def run(t_end=None, **kw):
                return run_scene(scene, t_end=t_end or case.t_end, **kw)

            def every_step(**kw):            # the scene's settings with a sample after every step
                return simulate(scene.system, case.t_end, replace(scene.settings, **kw, output_dt=None))

            rows += method_table(case, run, every_step, repeat)
    return rows


def method_reference(case: MethodCase, run):
    """(reference Result, compared modes, printed line on its error and independent check)."""
    ref = run(**case.reference)
    modes = {b: np.flatnonzero(np.abs(ref.bodies[b].q).max(0) >= MODE_SHARE * np.abs(ref.bodies[b].q).max())
             for b in case.bodies}
    looser, independent = run(**case.looser), run(**case.independent)

    def describe(kw):
        return ", ".join(f"{k} = {v:g}" if not isinstance(v, str) else v for k, v in kw.items())

    line = (f"reference {describe(case.reference)} ({ref.stats.cpu_integration:.1f} CPU-s); the same method at "
            f"{describe(case.looser)} differs from it by {relative_error(looser, ref, case, modes):.1e} (joints "
            f"{relative_error(looser, ref, case, modes, True):.1e}); independent {describe(case.independent)}: "
            f"{relative_error(independent, ref, case, modes):.1e} (joints "
            f"{relative_error(independent, ref, case, modes, True):.1e})")
    return ref, modes, line


def method_table(case: MethodCase, run, every_step, repeat: int) -> list[dict]:
    """Every ladder of the case against its reference: table rows (printed) and step histories."""
    ref, modes, line = method_reference(case, run)
    signals = list(case.joints) + [f"{b}.q{k + 1}" for b in case.bodies for k in modes[b]]
    print(f"\n### {case.name}, {case.t_end:g} s ({load_average()})\n")
    print(f"compared: {', '.join(signals)}; {line}\n")
    rows = []
    for method, ladder in case.ladders.items():
        run(**ladder[0], t_end=min(case.t_end, 50 * ladder[0]["h"]))     # kernels loaded before timing
        for kw in ladder:
            result, integ, total = timed_runs(run, kw, repeat)
            setting = ", ".join(f"{k} = {v:g}" for k, v in kw.items() if k != "method")
            row = dict(scene=case.name, method=method, setting=setting, error=np.nan, integ=integ, total=total)
            if isinstance(result, str):
                row["failed"] = result
            else:
                st = result.stats
                row.update(error=relative_error(result, ref, case, modes),
                           joints=relative_error(result, ref, case, modes, True), steps=st["steps"],
                           rejected=st.get("rejected", 0), mean_h=case.t_end / st["steps"],
                           newton=st.get("newton_iterations", 0), rhs=st.get("rhs_evaluations", 0))
            rows.append(row)
    print_method_rows(rows)
    print("\nstep sizes of the error-controlled runs (every step sampled): min / 10 % / median / 90 % / max [s]\n")
    print("| method | setting | steps | rejected | h [s] |")
    print("|---|---|---|---|---|")
    for method in (GA_RTOL, RK45, DOP853):
        kw = case.ladders[method][len(case.ladders[method]) // 2]
        try:
            result = every_step(**kw)
        except Exception as exc:          # a failed run is a finding, not a crash of the benchmark
            print(f"| {method} | {kw} | failed: {str(exc)[:80]} |")
            continue
        print(f"| {method} | rtol = {kw['rtol']:g} | {result.stats.steps} | {result.stats.rejected} | "
              f"{step_history(result)} |", flush=True)
    return rows


def plot_methods(rows: list[dict]) -> None:
    """Error against integration CPU, one panel per scene (top: all compared signals, bottom:
    the joint coordinates), one line per method: docs/img/accuracy_methods.png."""
    import matplotlib.pyplot as plt

    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    fig, axes = plt.subplots(2, len(scenes), figsize=(4.6 * len(scenes), 7.6), squeeze=False)
    for col, scene in enumerate(scenes):
        for method, style in METHOD_STYLE.items():
            r = sorted((x for x in rows if x["scene"] == scene and x["method"] == method and np.isfinite(x["error"])),
                       key=lambda x: x["integ"])
            for ax, key in zip(axes[:, col], ("error", "joints")):
                if r:
                    ax.loglog([x["integ"] for x in r], [x[key] for x in r], style, label=method)
        for ax, what in zip(axes[:, col], ("joint and modal coordinates", "joint coordinates")):
            ax.set_title(f"{scene}: {what}", fontsize=9)
            ax.set_xlabel("integration CPU [s]")
            ax.set_ylabel("max error / peak of the signal")
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(IMG / "accuracy_methods.png", dpi=100)
    plt.close(fig)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--part", nargs="*", choices=("fe", "reduce", "solve", "methods"),
                   default=["fe", "reduce", "solve", "methods"])
    p.add_argument("--scene", nargs="*", help="methods part: only the scenes whose name contains one of these")
    p.add_argument("--rows", nargs="*", type=Path, default=[],
                   help="methods part: write its rows to the first JSON file; the plot shows the rows of all given files")
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
    if "methods" in args.part:
        rows = method_study(repeat, args.quick, args.scene)
        if args.rows and rows:
            args.rows[0].write_text(json.dumps(rows))
        if args.rows:
            rows = [r for f in args.rows if f.exists() for r in json.loads(f.read_text())]
        plot_methods(rows)
    print(f"\nplots in {IMG.relative_to(ROOT)}; {load_average()}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
