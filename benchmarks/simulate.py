#!/usr/bin/env python3
"""CPU seconds per simulated second of the flexible pendulum, sidprep vs Exudyn, at matched accuracy.

The SAME reduced body goes into both solvers: the bar mesh (tet10) is assembled by sidprep
(consistent mass, steel), clamped on its node set ``fixed_end`` and reduced to its lowest
``nq`` clamped eigenmodes Phi (= Craig-Bampton fixed-interface modes of an RBE2 interface at the
hinge, with the reference frame attached to it).  The mesh is shifted so that the hinge (centre
of the face x = 0) is the frame origin.  sidprep gets the SID computed from (mesh, Ms, Phi);
Exudyn 1.13.6 gets (mesh nodes, M, K, Phi) through ``FEMinterface`` ->
``ObjectFFRFreducedOrderInterface`` (its C++ ObjectFFRFreducedOrder), with a GenericJoint
(revolute about y) between the ground and the frame's rigid-body node ("exudyn") or the
hinge-face mesh nodes ("exu-face").  sidprep runs twice: as a user gets it ("sidprep": the solver
detects the planar scene and integrates its in-plane coordinates and modes only) and with
``planar=False`` ("sidp-3d": all coordinates and modes, like Exudyn).

Scene: hinge axis y, gravity -z, released horizontally from rest, 1 s.  Both solvers run
generalised-alpha with rho_inf = 0.9 at fixed steps h (Exudyn with its modified Newton).  Error of a run = max over the output
times (every 40 ms, on every run's step grid) of |angle(t) - angle_ref(t)|, angle = the frame's rotation about y, and
angle_ref = the same solver at h_ref (its own converged answer; the two references are compared
too).  The tip error (mesh node nearest the centre of the free end) is listed as well; it levels
off at the few-micrometre vibration of the modes above ~1 kHz that steps >= 0.25 ms cannot resolve.  "Matched accuracy" = each solver's CPU time interpolated (log-log) at the same
error.  CPU = process time of the time integration only (no set-up, no post-processing), median of
``--repeat`` runs.

    python benchmarks/simulate.py                      # bundled bar, 10 and 16 modes
    python benchmarks/simulate.py --mesh fine.msh      # another bar mesh with node set fixed_end
    python benchmarks/simulate.py --quick              # fewer step sizes (smoke run)
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
GRAVITY = np.array([0.0, 0.0, -9.81])
T_END = 1.0
OUTPUT_DT = 0.04             # s; every step size below divides it, so samples fall on the grid
RHO_INF = 0.9
STEPS = (8e-3, 4e-3, 2e-3, 1e-3, 5e-4)
H_REF = 5e-5


@dataclass(frozen=True)
class Body:
    """The reduced bar: node positions (n, 3) with the hinge at the origin, M, K (3n, 3n),
    Phi (3n, nq) M-normalised, omega2 (nq,) rad^2/s^2, tip node index, hinge (fixed_end) nodes."""

    points: np.ndarray
    Ms: object
    M: object
    K: object
    Phi: np.ndarray
    omega2: np.ndarray
    tip: int
    hinge_nodes: np.ndarray


def reduced_bar(mesh_path: Path, nq: int) -> Body:
    """Assemble, clamp ``fixed_end``, lowest ``nq`` eigenmodes (sidprep's FE side)."""
    from sidprep.fe.assemble import block_pattern, mass_matrix, scalar_mass_matrix, stiffness_matrix
    from sidprep.fe.linalg import clamp_dofs, eigen_modes, node_dofs
    from sidprep.fe.material import material_from_options
    from sidprep.fe.mesh import read_mesh

    mesh = read_mesh(mesh_path)
    steel = material_from_options(name="steel")
    pattern = block_pattern(mesh.cells, mesh.n_nodes)
    K = stiffness_matrix(mesh, steel, pattern)
    Ms = scalar_mass_matrix(mesh, steel.rho, pattern)
    M = mass_matrix(mesh, steel, pattern=pattern)
    fixed = mesh.node_sets["fixed_end"]
    free = clamp_dofs(mesh.n_dof, node_dofs(fixed))
    modes = eigen_modes(free.restrict(K), free.restrict(M), count=nq)
    Phi = free.expand(modes.vectors[:, modes.n_rigid:])
    omega2 = modes.eigenvalues[modes.n_rigid:]
    points = mesh.points - mesh.points[fixed].mean(axis=0)
    end = mesh.node_sets["free_end"]
    centre = points[end].mean(axis=0)
    tip = int(end[np.argmin(np.linalg.norm(points[end] - centre, axis=1))])
    return Body(points, Ms, M, K, Phi, omega2, tip, np.asarray(fixed))


def sidprep_sid(body: Body):
    from sidprep.sid.model import sid_invariants

    phi = body.Phi.reshape(-1, 3, body.Phi.shape[1])
    nodes = [(1, np.zeros(3), np.zeros((3, phi.shape[2]))), (2, body.points[body.tip], phi[body.tip])]
    return sid_invariants(body.points, body.Ms, body.Phi, nodes, Ke=np.diag(body.omega2))


def pendulum_angle(rotation: np.ndarray) -> np.ndarray:
    """Rotation angle about +y (rad, unwrapped) of frame rotation matrices (nt, 3, 3)."""
    return np.unwrap(np.arctan2(rotation[:, 0, 2], rotation[:, 0, 0]))


def run_sidprep(sid, h: float, planar=None) -> tuple[np.ndarray, np.ndarray, float]:
    """Pendulum angle (nt,), tip positions (nt, 3) at the output times, integration CPU seconds.

    planar : None (the solver detects the planar scene and integrates the in-plane coordinates
    and modes only) or False (all 3D coordinates and modes, like Exudyn).
    """
    from sidprep.solver import FlexibleBody, Revolute, System
    from sidprep.solver.run import simulate

    axis_y = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]).T   # z -> y
    system = System(gravity=GRAVITY, planar=planar)
    bar = system.add(FlexibleBody(sid, name="bar"))
    hinge = bar.node_marker(0, name="hinge")
    hinge.rotation = axis_y
    bar.node_marker(1, name="tip")
    system.add(Revolute(system.ground.marker(rotation=axis_y, name="pivot"), hinge, name="revolute"))
    result = simulate(system, T_END, h=h, rho_inf=RHO_INF, output_dt=OUTPUT_DT)
    assert np.allclose(result.t, np.arange(0.0, T_END + 1e-9, OUTPUT_DT)), "output times off the grid"
    return (pendulum_angle(result.bodies["bar"].rotation), result.markers["tip"],
            float(result.stats.cpu_integration))


def run_exudyn(body: Body, h: float, on_nodes: bool = False) -> tuple[np.ndarray, np.ndarray, float]:
    """The same pendulum in Exudyn (ObjectFFRFreducedOrder + GenericJoint); angle, tip, CPU s.

    The joint acts on the frame's rigid-body node, or with ``on_nodes`` on a
    MarkerSuperElementRigid over the hinge face nodes (as in Exudyn's FFRF examples; the same
    motion here since the clamped modes vanish there).
    """
    import exudyn as exu
    from exudyn.FEM import FEMinterface, ObjectFFRFreducedOrderInterface
    from exudyn.itemInterface import (GenericJoint, MarkerBodyRigid, MarkerNodeRigid,
                                      MarkerSuperElementPosition, MarkerSuperElementRigid, ObjectGround,
                                      SensorMarker, SensorNode)

    fem = FEMinterface()
    fem.nodes = {"Position": body.points}
    fem.massMatrix, fem.stiffnessMatrix = body.M.tocsr(), body.K.tocsr()
    fem.modeBasis = {"matrix": body.Phi, "type": "NormalModes"}
    fem.eigenValues = body.omega2
    cms = ObjectFFRFreducedOrderInterface(fem)
    sc = exu.SystemContainer()
    mbs = sc.AddSystem()
    obj = cms.AddObjectFFRFreducedOrder(mbs, positionRef=[0, 0, 0], gravity=list(GRAVITY))
    ground = mbs.AddObject(ObjectGround())
    m_ground = mbs.AddMarker(MarkerBodyRigid(bodyNumber=ground, localPosition=[0, 0, 0]))
    if on_nodes:
        nodes = body.hinge_nodes
        m_frame = mbs.AddMarker(MarkerSuperElementRigid(bodyNumber=obj["oFFRFreducedOrder"], meshNodeNumbers=nodes,
                                                        weightingFactors=np.full(len(nodes), 1.0 / len(nodes))))
    else:
        m_frame = mbs.AddMarker(MarkerNodeRigid(nodeNumber=obj["nRigidBody"]))
    mbs.AddObject(GenericJoint(markerNumbers=[m_ground, m_frame], constrainedAxes=[1, 1, 1, 1, 0, 1]))
    m_tip = mbs.AddMarker(MarkerSuperElementPosition(bodyNumber=obj["oFFRFreducedOrder"],
                                                     meshNodeNumbers=[body.tip], weightingFactors=[1.0]))
    sensor = mbs.AddSensor(SensorMarker(markerNumber=m_tip, outputVariableType=exu.OutputVariableType.Position,
                                        storeInternal=True, writeToFile=False))
    frame = mbs.AddSensor(SensorNode(nodeNumber=obj["nRigidBody"], storeInternal=True, writeToFile=False,
                                     outputVariableType=exu.OutputVariableType.RotationMatrix))
    mbs.Assemble()
    s = exu.SimulationSettings()
    s.timeIntegration.numberOfSteps = int(round(T_END / h))
    s.timeIntegration.endTime = T_END
    s.timeIntegration.generalizedAlpha.spectralRadius = RHO_INF
    s.timeIntegration.newton.useModifiedNewton = True      # Exudyn's faster setting (2-3x here)
    s.timeIntegration.verboseMode = 0
    s.show.statistics = False
    s.solution.file.write = False
    s.solution.sensors.writePeriod = OUTPUT_DT
    cpu0 = time.process_time()
    mbs.SolveDynamic(s)
    cpu = time.process_time() - cpu0
    t_out = np.arange(0.0, T_END + 1e-9, OUTPUT_DT)

    def sampled(sensor_index):
        data = mbs.GetSensorStoredData(sensor_index)
        rows = [int(np.argmin(np.abs(data[:, 0] - t))) for t in t_out]
        assert np.allclose(data[rows, 0], t_out), "Exudyn sensor times off the grid"
        return data[rows, 1:]

    rotation = sampled(frame).reshape(-1, 3, 3)              # row-major 3x3 per sample
    return pendulum_angle(rotation), sampled(sensor), cpu


def cpu_at_error(errors, cpus, target: float) -> float:
    """CPU seconds interpolated log-log at ``target`` error (NaN outside the measured range)."""
    e, c = np.log(np.asarray(errors)), np.log(np.asarray(cpus))
    order = np.argsort(e)
    lt = np.log(target)
    if not e[order][0] <= lt <= e[order][-1]:
        return float("nan")
    return float(np.exp(np.interp(lt, e[order], c[order])))


def sweep(name: str, run, steps, ref, repeat: int):
    """Rows (solver, h, angle error rad, tip error m, median CPU s per simulated s) against
    ref = (angle, tip); every run is repeated ``repeat`` times (the machine is shared)."""
    rows = []
    for h in steps:
        runs = [run(h) for _ in range(repeat)]
        angle, tip, _ = runs[0]
        cpu = float(np.median([r[2] for r in runs]))
        err = float(np.max(np.abs(angle - ref[0])))
        tip_err = float(np.max(np.linalg.norm(tip - ref[1], axis=1)))
        rows.append((name, h, err, tip_err, cpu / T_END))
        print(f"  {name:8s} h = {h:8.1e} s  angle error {err:9.3e} rad  tip error {tip_err:9.3e} m  "
              f"CPU {cpu / T_END:8.3f} s per simulated s", flush=True)
    return rows


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--mesh", type=Path, default=ROOT / "data/meshes/bar.msh")
    p.add_argument("--modes", type=int, nargs="+", default=[10, 16])
    p.add_argument("--quick", action="store_true", help="three step sizes, h_ref = 2.5e-4 s, one run each")
    p.add_argument("--no-exudyn", action="store_true")
    p.add_argument("--repeat", type=int, default=3, help="runs per step size; the median CPU is reported")
    p.add_argument("--steps", type=float, nargs="+", help="step sizes, s (default: %s)" % (STEPS,))
    args = p.parse_args(argv)
    steps = args.steps or (STEPS[1:4] if args.quick else STEPS)
    h_ref = 2.5e-4 if args.quick else H_REF
    if args.quick:
        args.repeat = 1
    try:
        import exudyn
        exu_version = exudyn.__version__
    except ImportError:
        exu_version = None
    use_exudyn = exu_version is not None and not args.no_exudyn
    table = []
    for nq in args.modes:
        body = reduced_bar(args.mesh, nq)
        sid = sidprep_sid(body)
        print(f"{args.mesh.name}: {body.M.shape[0]} DOF, {nq} clamped modes "
              f"{np.sqrt(body.omega2[0]) / 2 / np.pi:.1f} .. {np.sqrt(body.omega2[-1]) / 2 / np.pi:.1f} Hz", flush=True)
        ref = run_sidprep(sid, h_ref)[:2]
        rows = sweep("sidprep", lambda h: run_sidprep(sid, h), steps, ref, args.repeat)
        rows += sweep("sidp-3d", lambda h: run_sidprep(sid, h, planar=False), steps, ref, args.repeat)
        if use_exudyn:
            ref_exu = run_exudyn(body, h_ref)[:2]
            print(f"  references (h = {h_ref:g} s) differ by {np.max(np.abs(ref[0] - ref_exu[0])):.3e} rad in "
                  f"angle, {np.max(np.linalg.norm(ref[1] - ref_exu[1], axis=1)):.3e} m at the tip", flush=True)
            rows += sweep("exudyn", lambda h: run_exudyn(body, h), steps, ref_exu, args.repeat)
            rows += sweep("exu-face", lambda h: run_exudyn(body, h, on_nodes=True), steps, ref_exu, args.repeat)
        table.append((nq, body.M.shape[0], rows))
    print()
    print("| modes | DOF | solver | h [s] | angle error [rad] | tip error [m] | CPU s per simulated s |")
    print("|---|---|---|---|---|---|---|")
    for nq, ndof, rows in table:
        for name, h, err, tip_err, cpu in rows:
            print(f"| {nq} | {ndof} | {name} | {h:g} | {err:.2e} | {tip_err:.2e} | {cpu:.3f} |")
    if use_exudyn:
        print()
        print(f"Matched accuracy (Exudyn {exu_version}): at the angle error of each sidprep run, Exudyn's CPU "
              "interpolated log-log between its runs")
        print("| modes | DOF | sidprep run | h [s] | angle error [rad] | sidprep CPU/sim s | Exudyn (frame node) "
              "| ratio | Exudyn (face nodes) | ratio |")
        print("|---|---|---|---|---|---|---|---|---|---|")
        for nq, ndof, rows in table:
            variants = [[(e, c) for n, _, e, _, c in rows if n == v] for v in ("exudyn", "exu-face")]
            for name, h, err, _, cpu in rows:
                if name.startswith("sid"):
                    other = [cpu_at_error(*zip(*v), err) for v in variants]
                    print(f"| {nq} | {ndof} | {name} | {h:g} | {err:.2e} | {cpu:.3f} | "
                          + " | ".join(f"{o:.3f} | {cpu / o:.2f}" for o in other) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
