"""Numerical stability on hard cases: each against an independent reference or an invariant.

FE side: nearly incompressible material, mm-t-s units, slender and thin free bodies, extreme moduli,
a body far from the origin, sliver elements.  Solver: a stiff 16-mode body with a step far above
1/f_max, a body spinning near its first critical speed, a 100 s rigid pendulum, the cases of
the hard cases (whirl, energy books, watchdog, broken SIDs, failures that name their numerical cause)
and the hard-case suite on every integrator (genalpha, rk4, rk45, dop853): a spinning flexible
body on a joint, dead centres, a start off the assembled pose, a near-zero mass link, 60 modes up
to 22 kHz at h = 1 ms, a rotor above its first critical speed with and without stiffening.
Long runs of these: benchmarks/stability.py.
"""

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

from sidprep.fe.assemble import mass_matrix, scalar_mass_matrix, stiffness_matrix
from sidprep.fe.linalg import clamp_dofs, eigen_modes, factorize, node_dofs, rigid_body_modes
from sidprep.fe.material import Material, material_from_options
from sidprep.fe.mesh import FEMesh, read_mesh
from sidprep.fe.topology import surface_node_indices
from sidprep.solver.core.steps import lu_factor, lu_solve
from sidprep.solver.integrators.settings import METHODS
from sidprep.solver.run import simulate

ROOT = Path(__file__).resolve().parents[1]
BAR = ROOT / "data" / "meshes" / "bar.msh"
STEEL = Material(E=210e9, nu=0.3, rho=7850.0, name="steel")
BOX_GEO = """SetFactory("OpenCASCADE");
Box(1) = {{0, 0, 0, {L}, {b}, {t}}};
Mesh.MeshSizeMin = {h};
Mesh.MeshSizeMax = {h};
Physical Volume("body") = {{1}};
"""
#: free-free Euler-Bernoulli beam: (beta_n L) of the first three bending modes
BETA_L_FREE = (4.730041, 7.853205, 10.995608)


def box_mesh(tmp_path, L, b, t, h, order=2) -> FEMesh:
    """gmsh box [0, L] x [0, b] x [0, t] (m), element size h."""
    geo = tmp_path / f"box_{L}_{b}_{t}_{h}.geo"
    geo.write_text(BOX_GEO.format(L=L, b=b, t=t, h=h))
    return read_mesh(geo, order=order)


def euler_bernoulli_free_hz(material, L, b, t, n=3, shear=False) -> np.ndarray:
    """Free-free bending frequencies (Hz) of a rectangular b x t beam of length L, both planes,
    ascending: f = (beta L)^2 / (2 pi L^2) sqrt(E I / (rho A)).  ``shear``: times the first-order
    Timoshenko factor 1 - (beta r)^2 (1 + E / (kappa G)) / 2 (shear + rotary inertia, radius of
    gyration r, kappa = 10 (1 + nu) / (12 + 11 nu), Cowper's rectangle)."""
    e_over_kg = (12 + 11 * material.nu) / 5          # E / (kappa G), G = E / (2 (1 + nu))
    f = []
    for bl in BETA_L_FREE[:n]:
        for d in (b, t):
            r = d / np.sqrt(12)
            factor = 1 - 0.5 * (bl / L * r) ** 2 * (1 + e_over_kg) if shear else 1.0
            f.append(bl**2 / (2 * np.pi * L**2) * np.sqrt(material.E / material.rho) * r * factor)
    return np.sort(f)


def free_frequencies(mesh, material, count, **kw):
    K, M = stiffness_matrix(mesh, material), mass_matrix(mesh, material)
    return eigen_modes(K, M, count=count, **kw)


# ---------------------------------------------------------------------------------------------
# FE side
# ---------------------------------------------------------------------------------------------

#: tet10 (2-3 elements across) vs Euler-Bernoulli with the first-order shear / rotary-inertia
#: factor, nu = 0.499, first four bending modes of a 1 x 0.03 x 0.02 m bar: measured 7.7e-4
#: (plain Euler-Bernoulli differs by up to 9.6e-3 on the 2nd bending mode: shear)
INCOMPRESSIBLE_BENDING_RTOL = 2e-3
#: eigen residual |K phi - lambda M phi| / |K phi| at nu = 0.499: measured 5.5e-7 (first mode;
#: the bulk modulus widens the spectrum), 3.9e-9 at nu = 0.3
INCOMPRESSIBLE_RESIDUAL_TOL = 5e-6


def test_nearly_incompressible_bending_frequencies_and_no_spurious_modes(tmp_path):
    """nu = 0.499, tet10, free-free 1.0 x 0.03 x 0.02 m bar: the bending frequencies follow beam
    theory (volumetric locking would stiffen them) and no extra (spurious) mode appears below
    the 6th bending mode."""
    L, b, t = 1.0, 0.03, 0.02
    mesh = box_mesh(tmp_path, L, b, t, h=0.01)
    rubberlike = Material(E=210e9, nu=0.499, rho=7850.0, name="nu 0.499")
    eb = euler_bernoulli_free_hz(rubberlike, L, b, t, shear=True)
    ev = free_frequencies(mesh, rubberlike, count=7)
    f = ev.frequencies_hz[ev.n_rigid:]
    assert ev.n_rigid == 6
    np.testing.assert_allclose(f[:4], eb[:4], rtol=INCOMPRESSIBLE_BENDING_RTOL)
    # torsion (~1.3 kHz) and axial (2.6 kHz) lie above: exactly 5 modes below the 3rd y-bending (862 Hz)
    assert np.sum(f < 0.97 * eb[5]) == 5
    assert np.max(ev.residuals) < INCOMPRESSIBLE_RESIDUAL_TOL


#: frequencies of the same body in SI and in mm-t-s numbers (measured 1.5e-13)
UNITS_RTOL = 1e-10


def test_millimetre_mesh_with_mm_t_s_units_gives_the_si_frequencies():
    """The bundled bar in mm with E in MPa and rho in t/mm^3 assembled as raw numbers (K in
    N/mm, M in t: the same (rad/s)^2), and through material_from_options(units='mm-t-s') +
    FEMesh.scaled (the pipeline path): same free-free frequencies as SI."""
    mesh = read_mesh(BAR)
    ref = free_frequencies(mesh, STEEL, count=8)
    raw_mm = Material(E=210e3, nu=0.3, rho=7.85e-9, name="steel mm-t-s")
    mm = free_frequencies(mesh.scaled(1e3, "mm"), raw_mm, count=8)
    converted = material_from_options(E=210e3, nu=0.3, rho=7.85e-9, units="mm-t-s")
    back = free_frequencies(mesh.scaled(1e3, "mm").scaled(1e-3), converted, count=8)
    for ev in (mm, back):
        assert ev.n_rigid == 6
        np.testing.assert_allclose(ev.frequencies_hz[6:], ref.frequencies_hz[6:], rtol=UNITS_RTOL)


#: the rigid modes of a free slender body stay below this fraction of the first elastic one
#: (measured 2e-3 Hz vs 53 Hz: 4e-5)
RIGID_SEPARATION = 1e-3
#: slender bar (1 x 0.01 x 0.01 m, tet10, 2 elements across) vs Euler-Bernoulli: measured 3.5e-4
SLENDER_EB_RTOL = 5e-3


@pytest.mark.parametrize("backend", ["auto", "lobpcg"])
def test_slender_free_body_keeps_six_rigid_modes_apart(tmp_path, backend):
    """Aspect ratio 100, free-free: exactly 6 zero modes, far below the first bending pair, whose
    frequency follows Euler-Bernoulli (both eigen backends)."""
    L, b = 1.0, 0.01
    mesh = box_mesh(tmp_path, L, b, b, h=0.005)
    near_null = rigid_body_modes(mesh.points) if backend == "lobpcg" else None
    ev = free_frequencies(mesh, STEEL, count=2, backend=backend, near_null=near_null)
    f = ev.frequencies_hz
    assert ev.n_rigid == 6
    assert np.max(np.abs(f[:6])) < RIGID_SEPARATION * f[6]
    np.testing.assert_allclose(f[6:8], euler_bernoulli_free_hz(STEEL, L, b, b)[:2], rtol=SLENDER_EB_RTOL)


#: first free-free mode of a square Kirchhoff plate, nu = 0.3: f = LAMBDA2 / (2 pi a^2) sqrt(D / (rho t))
#: (code_aster validation SDLS01 / V2.03.001 after Barton 1951; Leissa 1973 gives 13.49 too)
FREE_PLATE_LAMBDA2 = 13.49
#: thin plate 0.5 x 0.5 x 0.005 m, one tet10 layer, h = 4 t: measured -2.9e-3
THIN_PLATE_RTOL = 1e-2


def test_thin_free_plate_keeps_six_rigid_modes_apart(tmp_path):
    """Aspect ratio 100 (0.5 x 0.5 x 0.005 m), one element layer: 6 rigid modes far below the
    first elastic one, which follows Kirchhoff plate theory."""
    a, t = 0.5, 0.005
    ev = free_frequencies(box_mesh(tmp_path, a, a, t, h=0.02), STEEL, count=1)
    f = ev.frequencies_hz
    D = STEEL.E * t**3 / (12 * (1 - STEEL.nu**2))
    assert ev.n_rigid == 6
    assert np.max(np.abs(f[:6])) < RIGID_SEPARATION * f[6]
    assert f[6] == pytest.approx(FREE_PLATE_LAMBDA2 / (2 * np.pi * a**2) * np.sqrt(D / (STEEL.rho * t)),
                                 rel=THIN_PLATE_RTOL)


#: f ~ sqrt(E) for E x 1e6 and E x 1e-6 (measured 7e-13, 1.8e-12)
MODULUS_SCALING_RTOL = 1e-8


@pytest.mark.parametrize("factor", [1e6, 1e-6])
def test_frequencies_scale_with_sqrt_of_the_modulus(factor):
    mesh = read_mesh(BAR)
    ref = free_frequencies(mesh, STEEL, count=8)
    ev = free_frequencies(mesh, replace(STEEL, E=STEEL.E * factor), count=8)
    assert ev.n_rigid == 6
    np.testing.assert_allclose(ev.frequencies_hz[6:], np.sqrt(factor) * ref.frequencies_hz[6:],
                               rtol=MODULUS_SCALING_RTOL)


#: frequencies of a free body 1 km from the origin (coordinates lose 5 digits to the offset;
#: measured 2.4e-12)
FAR_FREQUENCY_RTOL = 1e-8
#: mass and the centre of mass shift (measured 1.0e-13, 7e-16 of the offset)
FAR_MASS_RTOL = 1e-12
#: inertia about the CM: J about the origin (~m 1e6 m^2) minus the Steiner term cancels ~7 digits
#: (measured 2.2e-8 of the largest entry)
FAR_INERTIA_RTOL = 1e-6


def test_body_far_from_the_origin_keeps_frequencies_and_invariants():
    from sidprep.sid.model import inertia_matrix, sid_invariants

    offset = np.array([1e3, -1e3, 1e3])
    near = read_mesh(BAR)
    far = replace(near, points=near.points + offset)

    def body(mesh):
        ev = free_frequencies(mesh, STEEL, count=6)
        Ms = scalar_mass_matrix(mesh, STEEL.rho)
        sid = sid_invariants(mesh.points, Ms, ev.vectors[:, ev.n_rigid:], [],
                             frequencies_hz=ev.frequencies_hz[ev.n_rigid:])
        c = sid.mdCM.M0[:, 0] / sid.mass
        i_cm = inertia_matrix(sid.J.M0) - sid.mass * (c @ c * np.eye(3) - np.outer(c, c))
        return ev, sid, c, i_cm

    ev0, sid0, c0, i0 = body(near)
    ev1, sid1, c1, i1 = body(far)
    assert ev1.n_rigid == 6
    np.testing.assert_allclose(ev1.frequencies_hz[6:], ev0.frequencies_hz[6:], rtol=FAR_FREQUENCY_RTOL)
    assert sid1.mass == pytest.approx(sid0.mass, rel=FAR_MASS_RTOL)
    np.testing.assert_allclose(c1 - offset, c0, atol=FAR_MASS_RTOL * np.abs(offset).max())
    assert np.abs(i1 - i0).max() < FAR_INERTIA_RTOL * np.abs(i0).max()


#: the sliver mesh has elements below this volume ratio |V| / l_rms^3 (regular tet: 0.118;
#: read_mesh rejects < 1e-8 as flat)
SLIVER_RATIO = 1e-6
#: patch test and rigid modes: |K u|_interior / |K| |u|
SLIVER_PATCH_TOL = 1e-10
SLIVER_RESIDUAL_TOL = 1e-8


def sliver_mesh(tmp_path) -> FEMesh:
    """Delaunay tets of an almost regular grid (1 % jitter): nearly cospherical point
    quadruples give slivers; written as VTU and read back (read_mesh accepts it as valid)."""
    import meshio
    from scipy.spatial import Delaunay

    g = np.stack(np.meshgrid(np.linspace(0, 0.2, 9), np.linspace(0, 0.05, 3), np.linspace(0, 0.05, 3),
                             indexing="ij"), -1).reshape(-1, 3)
    rng = np.random.default_rng(3)
    g = g + 1e-2 * 0.025 * rng.standard_normal(g.shape)
    cells = Delaunay(g).simplices
    a, b_, c, d = (g[cells[:, k]] for k in range(4))
    neg = np.einsum("ij,ij->i", np.cross(b_ - a, c - a), d - a) < 0
    cells[neg] = cells[neg][:, [0, 2, 1, 3]]
    path = tmp_path / "sliver.vtu"
    meshio.write(path, meshio.Mesh(g, [("tetra", cells)]))
    return read_mesh(path)


def quality(mesh) -> np.ndarray:
    """|V| / l_rms^3 per tet (l_rms: RMS of the 6 edge lengths)."""
    p = mesh.points[mesh.cells[:, :4]]
    vol = np.abs(np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0])) / 6
    edges = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
    l_rms = np.sqrt(np.mean([np.sum((p[:, i] - p[:, j]) ** 2, axis=1) for i, j in edges], axis=0))
    return vol / l_rms**3


def test_sliver_mesh_assembles_spd_with_exact_patch_test(tmp_path):
    mesh = sliver_mesh(tmp_path)
    assert quality(mesh).min() < SLIVER_RATIO
    K, M = stiffness_matrix(mesh, STEEL), mass_matrix(mesh, STEEL)
    scale = sp.linalg.norm(K, np.inf)
    # rigid-body motions: no force; a linear field: no force at interior nodes (constant strain)
    R = rigid_body_modes(mesh.points)
    assert np.abs(K @ R).max() < SLIVER_PATCH_TOL * scale * np.abs(R).max()
    u = (mesh.points @ np.array([[1e-3, 2e-4, 0], [0, -3e-4, 1e-4], [5e-4, 0, 2e-4]]).T).ravel()
    interior = np.setdiff1d(np.arange(mesh.n_nodes), surface_node_indices(mesh))
    f = (K @ u).reshape(-1, 3)
    assert len(interior) and np.abs(f[interior]).max() < SLIVER_PATCH_TOL * scale * np.abs(u).max()
    # clamped at x = 0: SPD (Cholesky succeeds), eigen residuals reported and small
    clamp = clamp_dofs(mesh.n_dof, node_dofs(np.flatnonzero(mesh.points[:, 0] < 1e-3)))
    Kc, Mc = clamp.restrict(K), clamp.restrict(M)
    factorize(Kc)
    assert np.linalg.eigvalsh(Kc.toarray()).min() > 0
    ev = eigen_modes(Kc, Mc, count=6)
    assert ev.n_rigid == 0 and len(ev.residuals) == 6
    assert np.max(ev.residuals) < SLIVER_RESIDUAL_TOL


# ---------------------------------------------------------------------------------------------
# solver
# ---------------------------------------------------------------------------------------------

_Z_TO_Y = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]).T   # marker z along y


def reduced_bar(tmp_path, *options):
    """`sidprep reduce` of the bundled bar with an interface at fixed_end -> SID."""
    from sidprep.cli.main import main
    from sidprep.sid.io import read_sid

    out = tmp_path / "bar.sid.h5"
    assert main(["reduce", str(BAR), "--interface", "fixed_end", "--no-frm", "--damping", "0",
                 "--no-check-frequencies", "--no-obj", "--no-sid-fem", "-q", "-o", str(out), *options]) == 0
    return read_sid(out)


#: stiff 16-mode pendulum, h = 10 ms, rho_inf = 0.8: largest excursion of the total energy above
#: its start, in m g L (measured 8.5e-5: the O(h^2) swing error; 6.5e-7 at h = 1 ms)
STIFF_ENERGY_EXCURSION = 2e-4
#: ... and the energy at the end may not exceed the start by more than (measured -4.5e-7)
STIFF_ENERGY_GROWTH = 1e-7


def test_stiff_sixteen_mode_body_with_large_step_stays_bounded(tmp_path):
    """16 free-free modes of the steel bar (264 Hz ... kHz), hinged and released horizontally
    without static start (the modes ring), h = 10 ms >> 1/f_max, rho_inf = 0.8: the energy does
    not grow and the modal amplitudes stay at the quasi-static sag."""
    from sidprep.solver import FlexibleBody, Revolute, System

    sid = reduced_bar(tmp_path, "--modes", "16")
    f_max = float(np.max(sid.frequencies_hz))
    h = 1e-2
    assert sid.nq == 16 and h * f_max > 20
    s = System(gravity=(0.0, 0.0, -9.81))
    bar = s.add(FlexibleBody(sid, name="bar"))
    s.add(Revolute(s.ground.marker(rotation=_Z_TO_Y), bar.node_marker(0, rotation=_Z_TO_Y), name="hinge"))
    r = simulate(s, 2.0, h=h, rho_inf=0.8, output_dt=h)
    e = r.energy["total"]
    mgl = sid.mass * 9.81 * 1.0
    q = r.bodies["bar"].q
    assert np.all(np.isfinite(q)) and np.all(np.isfinite(e))
    assert np.max(e - e[0]) < STIFF_ENERGY_EXCURSION * mgl
    assert e[-1] - e[0] < STIFF_ENERGY_GROWTH * mgl
    # sag of the hinged bar under gravity (~1e-5 in modal units): no growth over the run
    assert np.abs(q[len(q) // 2:]).max() <= 1.5 * np.abs(q[: len(q) // 2]).max()


#: lead-lag Southwell coefficient of a uniform cantilever spun about an axis through its root,
#: perpendicular to it: f^2 = f0^2 + (K1 - 1) Omega^2, K1 = 1.193 (validation README 1.4)
SOUTHWELL_LAG = 1.193 - 1.0
#: 3D tet bar, 4 clamped modes, 0.95 x the first critical speed: measured 2.8e-3
LAG_FREQUENCY_RTOL = 1e-2
#: bound of the lag amplitude, in units of its start 1e-4: the Coriolis exchange with the other
#: modes lifts it to 1.0451 (DOP853, rtol 1e-10; genalpha 1.0448 at h = 0.25 ms, 1.0451 at
#: 0.125 ms; an R^3 x SO(3) stepper damped it to <= 1.01)
LAG_AMPLITUDE_BOUND = 1.06


def test_spinning_near_the_first_critical_speed_is_stable_with_stiffening(tmp_path):
    """The clamped bar (4 modes, `--stiffening`) driven about z through its root at 0.95 x its
    first in-plane (lag) frequency, lag mode displaced by 1e-4: with centrifugal stiffening the
    lag motion stays bounded and oscillates at the Southwell frequency; without it the effects
    report warns (the change of q it would make, estimated on the run)."""
    from sidprep.solver.model.joints import ConstantSpeed, Driver
    from sidprep.solver import FlexibleBody, Revolute, System

    sid = reduced_bar(tmp_path, "--modes", "4", "--frame", "fixed_end", "--stiffening")
    lag = int(np.argmax(np.abs(sid.Ct.M0[:, 1])))          # first mode moving along y
    f0 = float(sid.frequencies_hz[lag])
    spin = 0.95 * 2 * np.pi * f0

    def run(effects):
        s = System(gravity=(0, 0, 0), effects=effects)
        q0 = np.zeros(sid.nq)
        q0[lag] = 1e-4
        beam = s.add(FlexibleBody(sid, name="beam", q0=q0, omega=(0, 0, spin)))
        hub = s.add(Revolute(s.ground.marker(position=sid.nodes[0].origin.M0[:, 0]), beam.node_marker(0)))
        s.add(Driver(hub, ConstantSpeed(spin)))
        return simulate(s, 0.3, h=2.5e-4)

    base = ["coupling", "coriolis", "centrifugal", "inertia_change"]
    r = run(base + ["centrifugal_stiffening"])
    x = r.bodies["beam"].q[:, lag]
    assert np.all(np.isfinite(x)) and np.abs(x).max() <= LAG_AMPLITUDE_BOUND * 1e-4
    xm = x - x.mean()
    up = np.flatnonzero((xm[:-1] < 0) & (xm[1:] >= 0))
    tz = r.t[up] - xm[up] * (r.t[up + 1] - r.t[up]) / (xm[up + 1] - xm[up])
    f = (len(tz) - 1) / (tz[-1] - tz[0])
    assert f == pytest.approx(np.sqrt(f0**2 + SOUTHWELL_LAG * (spin / (2 * np.pi)) ** 2), rel=LAG_FREQUENCY_RTOL)
    assert not any("centrifugal_stiffening" in w for w in r.effects.warnings)

    without = run(base).effects
    e = next(e for e in without.bodies["beam"] if e.effect == "centrifugal_stiffening")
    # estimated on the run itself (max |dq| / max |q|: 4.9 measured; the run with it differs by 2.0)
    assert not e.included and e.warning and e.estimate > 0.1
    assert any("centrifugal_stiffening" in w for w in without.warnings)


#: rigid pendulum (2 kg, CM 0.5 m from the hinge), released horizontally, 100 s, h = 10 ms:
#: secular energy drift = |mean over the last 10 s - mean over the first 10 s| / (m g L)
#: (measured 3.8e-6); the O(h^2) excursion within a swing (measured 1.5e-4)
LONG_RUN_DRIFT = 1e-5
LONG_RUN_EXCURSION = 3e-4
#: position-level constraint error, m: within the Newton tolerance (newton_tol L), no drift
#: (measured 1.5e-10 with the SE(3) steps: the hinge is nonlinear in them; 4e-22 before, linear)
LONG_RUN_CONSTRAINT = 1e-9


def test_hundred_seconds_of_a_rigid_pendulum_keep_energy_and_constraints():
    from sidprep.solver import Revolute, RigidBody, System

    s = System(gravity=(0, 0, -9.81))
    rod = s.add(RigidBody(2.0, com=(0.5, 0, 0), inertia=(0.001, 0.05, 0.05), name="rod"))
    s.add(Revolute(s.ground.marker(rotation=_Z_TO_Y), rod.marker(rotation=_Z_TO_Y), name="hinge"))
    r = simulate(s, 100.0, h=1e-2, output_dt=0.05)
    e = r.energy["total"] / (2.0 * 9.81 * 0.5)
    first, last = e[r.t <= 10.0], e[r.t >= 90.0]
    assert abs(last.mean() - first.mean()) < LONG_RUN_DRIFT
    assert np.abs(e - e[0]).max() < LONG_RUN_EXCURSION
    assert r.constraint_error.max() < LONG_RUN_CONSTRAINT


# ---------------------------------------------------------------------------------------------
# Hard cases
# ---------------------------------------------------------------------------------------------

#: whirl of the hinged bar spin about the hinge, rad/s, run length, s, step, s
WHIRL_SPIN, WHIRL_T, WHIRL_H = 50.0, 10.0, 1e-3
#: energy law: |E - E0| / E0 over the run, no work done (measured 2.5e-6 free-free modes, 4.6e-5
#: clamped-frame modes, 2.2e-6 rigid twin; R^3 x SO(3) before: +2.5e-2, divergence at 7.95 s, +1e-2)
WHIRL_ENERGY_RTOL = 1e-4
#: hinge rate of the flexible bar against its rigid twin at the end of the run (stiff bar:
#: the elastic sag changes the inertia by ~Omega^2 / omega_1^2 at most)
WHIRL_RATE_RTOL = 2e-3


def whirl(body_factory, h=WHIRL_H, t_end=WHIRL_T, rho_inf=0.9, method="genalpha", rtol=None):
    """A body built by ``body_factory(system)`` -> (body, hinge marker on it), hinged to ground
    about y at its marker, started spinning at WHIRL_SPIN about the hinge under gravity."""
    from sidprep.solver import Revolute, System, simulate

    s = System(gravity=(0.0, 0.0, -9.81))
    body, marker = body_factory(s)
    s.add(Revolute(s.ground.marker(rotation=_Z_TO_Y), marker, name="hinge"))
    return simulate(s, t_end, h=h, rho_inf=rho_inf, output_dt=0.01, method=method, rtol=rtol)


def hinged_flexible(sid, spin=WHIRL_SPIN):
    from sidprep.solver import FlexibleBody

    def make(s):
        bar = s.add(FlexibleBody(sid, name="bar", omega=(0, spin, 0)))
        return bar, bar.node_marker(0, rotation=_Z_TO_Y)
    return make


def hinged_rigid_twin(sid, spin=WHIRL_SPIN):
    """A rigid body with the SID's mass, first moment and inertia, frame where the SID's is."""
    from sidprep.sid.model import inertia_matrix
    from sidprep.solver import RigidBody

    com = sid.mdCM.M0[:, 0] / sid.mass
    j_o = inertia_matrix(sid.J.M0[:, 0])
    j_cm = j_o - sid.mass * (com @ com * np.eye(3) - np.outer(com, com))
    hinge = sid.nodes[0].origin.M0[:, 0]

    def make(s):
        body = s.add(RigidBody(sid.mass, com=com, inertia=j_cm, name="bar", omega=(0, spin, 0),
                               position=-hinge))
        return body, body.marker(position=hinge, rotation=_Z_TO_Y)
    return make


@pytest.mark.parametrize("frame", [(), ("--frame", "fixed_end")], ids=["free-free", "clamped-frame"])
def test_hinged_flexible_bar_whirling_fast_keeps_its_energy(tmp_path, frame):
    """Issue 22 item 1: the bundled bar (frame origin at a corner, hinge at the end-face centre)
    whirling at 50 rad/s under gravity, h = 1 ms, rho_inf = 0.9, 10 s: energy is conserved
    (no work is done) and the spin follows the rigid twin of the same mass properties, which
    obeys the same energy law.  Before the SE(3) coordinates the energy grew ~h^2 Omega^3."""
    sid = reduced_bar(tmp_path, *frame)
    flexible = whirl(hinged_flexible(sid))
    rigid = whirl(hinged_rigid_twin(sid))
    for r in (flexible, rigid):
        e = r.energy["total"]
        assert r.t[-1] == pytest.approx(WHIRL_T)
        assert np.max(np.abs(e - e[0])) <= WHIRL_ENERGY_RTOL * e[0]
    rate_flex, rate_rigid = flexible.joints["hinge"].rate[-1], rigid.joints["hinge"].rate[-1]
    assert rate_flex == pytest.approx(rate_rigid, rel=WHIRL_RATE_RTOL)


PENDULUM_SID = ROOT / "examples" / "flexible_pendulum" / "bar.sid.h5"


def broken_sids():
    """(what is broken, the entry the message must name, the broken SID) from the bundled bar."""
    from sidprep.sid.io import read_sid
    from sidprep.sid.model import Taylor

    sid = read_sid(PENDULUM_SID)

    def taylor(t, m0):
        return replace(t, M0=m0)

    j = sid.J.M0.copy()
    j[1, 0] = -j[1, 0]                                    # Jyy < 0
    j_flat = sid.J.M0.copy()
    j_flat[0, 0] = 3.0 * (j_flat[1, 0] + j_flat[2, 0])    # Jxx > Jyy + Jzz about the CM
    ke_inf = sid.Ke.M0.copy()
    ke_inf[2, 2] = np.inf
    ke_neg = sid.Ke.M0.copy()
    ke_neg[3, 3] = -ke_neg[3, 3]
    ke_skew = sid.Ke.M0.copy()
    ke_skew[0, 1] += 1e-3 * ke_skew[0, 0]
    me_neg = sid.Me.M0.copy()
    me_neg[1, 1] = -1.0
    assert isinstance(sid.J, Taylor)
    return [
        ("negative Jyy", "not positive definite", replace(sid, J=taylor(sid.J, j))),
        ("triangle inequality", "triangle inequality", replace(sid, J=taylor(sid.J, j_flat))),
        ("NaN mass", "mass", replace(sid, mass=float("nan"))),
        ("mass D+999", "mass", replace(sid, mass=float("inf"))),
        ("zero mass", "mass = 0", replace(sid, mass=0.0)),
        ("Ke = inf", "Ke.M0[2, 2] = inf", replace(sid, Ke=taylor(sid.Ke, ke_inf))),
        ("Ke indefinite", "Ke.M0 not positive semidefinite", replace(sid, Ke=taylor(sid.Ke, ke_neg))),
        ("Ke not symmetric", "Ke.M0 not symmetric", replace(sid, Ke=taylor(sid.Ke, ke_skew))),
        ("Me indefinite", "Me.M0 not positive definite", replace(sid, Me=taylor(sid.Me, me_neg))),
    ]


@pytest.mark.parametrize("case", range(9))
def test_a_physically_impossible_sid_is_refused_before_any_step(case):
    """Issue 22 item 6: each broken SID gives one InputError line naming the SID and the entry
    when the FlexibleBody is made (before any step); the intact SID has no problem."""
    from sidprep.sid.checks import physical_problems
    from sidprep.errors import InputError
    from sidprep.sid.io import read_sid
    from sidprep.solver import FlexibleBody

    assert physical_problems(read_sid(PENDULUM_SID)) == []
    what, entry, sid = broken_sids()[case]
    with pytest.raises(InputError) as exc:
        FlexibleBody(sid, name="bar")
    message = str(exc.value)
    assert "\n" not in message and "SID of body 'bar'" in message and entry in message, (what, message)


def test_simulate_cli_refuses_a_sid_fem_with_negative_jyy_with_exit_2(tmp_path):
    """The CLI path: a scene pointing at a SID_FEM file whose Jyy is negative stops with exit
    code 2 and one line naming the file and the entry, before any step."""
    import subprocess
    import sys

    from sidprep.sid.io.sid_fem import write_sid_fem

    write_sid_fem(broken_sids()[0][2], tmp_path / "bar.SID_FEM")
    (tmp_path / "scene.toml").write_text(
        '[solver]\nt_end = 0.1\n[bodies.bar]\ntype = "flexible"\nsid = "bar.SID_FEM"\n', encoding="ascii")
    out = subprocess.run([sys.executable, "-m", "sidprep.cli.main", "simulate", "scene.toml", "-o", "r.h5", "-q"],
                         cwd=tmp_path, capture_output=True, text=True, timeout=600)
    lines = out.stderr.strip().splitlines()
    assert out.returncode == 2 and len(lines) == 1 and "Traceback" not in out.stderr, out.stderr
    assert "bar.SID_FEM" in lines[0] and "not positive definite" in lines[0] and "Jyy" in lines[0]
    assert not (tmp_path / "r.h5").exists()


#: the examples' energy balance closes with the geometric-stiffening work booked (measured 1.1e-4
#: beam_buckling, 7.4e-5 Beam slider crank; 0.89 and 0.074 without the stiffening work)
STIFFENED_BALANCE_TOL = 1e-3
#: beam_buckling's balance error at the scene's Newton tolerance against a 100x tighter one:
#: the figure is the integration's, not the Newton iterates' round-off (measured 1.11e-4 against
#: 1.04e-4; at newton_tol = 1e-8 it was 3.4e-4 ... 9.0e-4 with the OpenBLAS kernel chosen)
NEWTON_CONVERGED_RTOL = 0.15


@pytest.mark.parametrize("example", ["beam_buckling", "beam_slider_crank"])
def test_energy_books_close_with_geometric_stiffening(example):
    """Issue 22 item 4: kinetic + strain + potentials + dissipated - work of loads and drives +
    the work of the stiffening terms (load, centrifugal, acceleration) stays constant: the
    balance error is within 1e-3 of the energy exchanged, and no energy warning is raised; the
    stiffening work is not zero (the terms are active)."""
    from sidprep.solver.scene import load_scene, simulate

    r = simulate(load_scene(ROOT / "examples" / example / "scene.toml"))
    balance = r.stats.energy_balance
    assert balance.balance_error <= STIFFENED_BALANCE_TOL and balance.warning is None
    assert np.ptp(r.energy["stiffening"]) > 10 * STIFFENED_BALANCE_TOL * balance.exchanged


def test_beam_buckling_books_do_not_depend_on_the_newton_round_off():
    """The 16.6 kN end load works on every position error, so the books hold only when Newton
    converges well below the figure: the balance error at the scene's newton_tol equals that at
    a 100x tighter one (which is the same whatever the LAPACK kernel's round-off)."""
    from sidprep.solver.scene import load_scene, simulate

    scene = load_scene(ROOT / "examples" / "beam_buckling" / "scene.toml")
    at_scene = simulate(scene).stats.energy_balance.balance_error
    tight = simulate(scene, newton_tol=scene.settings.newton_tol / 100).stats.energy_balance.balance_error
    assert at_scene == pytest.approx(tight, rel=NEWTON_CONVERGED_RTOL)
    assert at_scene <= STIFFENED_BALANCE_TOL / 5


def test_energy_watchdog_is_silent_when_almost_nothing_is_exchanged():
    """A change of the books below the floor (1e-9 of the largest booked energy, at least
    1e-12 J) is no evidence of an integration error, however large relative to an exchange of
    almost nothing (a body at rest: 0.93 of 2.6e-11 J warned before); the same relative error
    of a real exchange warns, with the sign of the largest change, not of the end's."""
    from sidprep.solver.energy import balance_warning, energy_balance

    t = np.linspace(0.0, 1.0, 11)
    at_rest = {"kinetic": 1.3e-11 * np.sin(np.pi * t) ** 2, "gravity": 10.0 + 1.3e-11 * np.cos(np.pi * t) ** 2}
    at_rest["total"] = at_rest["kinetic"] + at_rest["gravity"] + 2.4e-11 * t
    quiet = energy_balance(at_rest)
    assert quiet.balance_error > 0.5 and balance_warning(quiet, "genalpha", 1e-3, 0.9, None) is None
    swinging = {k: v * 1e10 if k == "kinetic" else v for k, v in at_rest.items()}
    swinging["total"] = swinging["kinetic"] + swinging["gravity"] + 0.1 * np.sin(np.pi * t)  # rises, ends at 0
    loud = energy_balance(swinging)
    warning = balance_warning(loud, "genalpha", 1e-3, 0.9, None)
    assert loud.change == pytest.approx(0.0, abs=1e-12) and "energy grew" in warning


def test_energy_watchdog_warns_with_cause_and_fix_on_a_coarse_step():
    """Issue 22 item 2: the hinged bar at h = 50 ms, rho_inf = 0.5 loses 0.6 % of the energy it
    exchanges to numerical damping: the balance error passes energy_tol and the one warning
    names rho_inf, h and a fix; at h = 1 ms the same scene stays within it without a warning."""
    from sidprep.sid.io import read_sid

    sid = read_sid(PENDULUM_SID)

    def swing(h):
        from sidprep.solver import Revolute, System, simulate

        s = System(gravity=(0.0, 0.0, -9.81))
        body, marker = hinged_flexible(sid)(s)
        body.omega0 = np.zeros(3)
        s.add(Revolute(s.ground.marker(rotation=_Z_TO_Y), marker, name="hinge"))
        return simulate(s, 1.0, h=h, rho_inf=0.5).stats.energy_balance

    coarse, fine = swing(5e-2), swing(1e-3)
    assert coarse.balance_error > coarse.tolerance and "\n" not in coarse.warning
    assert all(word in coarse.warning for word in ("rho_inf = 0.5", "h = 0.05 s", "fix:"))
    assert fine.balance_error <= fine.tolerance and fine.warning is None


#: rho_inf = 1 whirl blew up at 0.30 s before): energy law over 3 s
#: (measured 2.5e-6)
WHIRL_NO_DAMPING_RTOL = 1e-4


def test_hinged_bar_whirling_is_stable_without_numerical_damping():
    """Issue 22 item 3: rho_inf = 1 (no numerical damping) on the whirling hinged bar keeps the
    energy for 3 s (the R^3 x SO(3) stepper's energy exploded and Newton failed at 0.30 s)."""
    from sidprep.sid.io import read_sid

    r = whirl(hinged_flexible(read_sid(PENDULUM_SID)), t_end=3.0, rho_inf=1.0)
    e = r.energy["total"]
    assert r.t[-1] == pytest.approx(3.0) and np.max(np.abs(e - e[0])) <= WHIRL_NO_DAMPING_RTOL * e[0]


def test_an_explicit_run_that_blows_up_stops_and_says_so():
    """RK4 beyond its stability limit on the 2 kHz bar (h omega_max ~ 13 > 2.8): the run stops
    at the first non-finite state with status failed, one line naming the time, the step and
    the fix, and keeps the finite samples before it (it finished with NaN results before)."""
    from sidprep.errors import SimulationFailed
    from sidprep.sid.io import read_sid
    from sidprep.solver import Revolute, System, simulate

    s = System(gravity=(0.0, 0.0, -9.81))
    body, marker = hinged_flexible(read_sid(PENDULUM_SID))(s)
    body.omega0 = np.zeros(3)
    s.add(Revolute(s.ground.marker(rotation=_Z_TO_Y), marker, name="hinge"))
    with np.errstate(all="ignore"), pytest.raises(SimulationFailed) as exc:
        simulate(s, 0.2, h=1e-3, method="rk4")
    message, r = str(exc.value), exc.value.result
    assert "\n" not in message and "non-finite state" in message and "h = 0.001 s" in message
    assert "genalpha" in message and "smaller step" in message
    assert 0 < r.t[-1] < 0.2 and r.stats.failed in message
    assert all(np.all(np.isfinite(a)) for a in (r.t, r.energy["total"], r.bodies["bar"].q))


#: hinge angle of the whirling rigid twin after 2 s (100 rad turned), genalpha (h = 1 ms,
#: rho_inf 0.9) against DOP853 (rtol 1e-10), rad: measured 1.2e-7 (energy 2.5e-6 and 3.1e-9)
WHIRL_ANGLE_TOL = 1e-5


def test_whirling_rigid_twin_genalpha_follows_dop853():
    """The rigid twin of the hinged bar (frame off the hinge) whirling at 50 rad/s under gravity:
    generalised-alpha on SE(3) follows DOP853 at a tight tolerance (a second formulation, the
    index-1 form with quaternions) in the hinge angle, and both keep the energy."""
    from sidprep.sid.io import read_sid

    twin = hinged_rigid_twin(read_sid(PENDULUM_SID))
    ga = whirl(twin, t_end=2.0)
    ref = whirl(twin, t_end=2.0, method="dop853", rtol=1e-10)
    assert ga.joints["hinge"].coordinate[-1] == pytest.approx(ref.joints["hinge"].coordinate[-1], abs=WHIRL_ANGLE_TOL)
    for r in (ga, ref):
        e = r.energy["total"]
        assert np.max(np.abs(e - e[0])) <= WHIRL_ENERGY_RTOL * e[0]


#: the whirling hinged 10-mode bar at 200 rad/s, genalpha, rho_inf = 1 (no numerical damping),
#: h = 5 ms (6 steps a turn), 1.5 s: the velocities are projected onto the hinge's velocity
#: constraints after each step, and the books close to energy_tol (measured 3.2e-4; unprojected,
#: Newton failed at 1.24 s after the balance went off by 0.40 of the energy exchanged)
FAST_WHIRL_SPIN, FAST_WHIRL_H, FAST_WHIRL_T = 200.0, 5e-3, 1.5


def test_a_fast_whirl_without_numerical_damping_keeps_its_books():
    from sidprep.sid.io import read_sid

    r = whirl(hinged_flexible(read_sid(PENDULUM_SID), spin=FAST_WHIRL_SPIN), h=FAST_WHIRL_H, t_end=FAST_WHIRL_T,
              rho_inf=1.0)
    balance = r.stats.energy_balance
    assert r.t[-1] == pytest.approx(FAST_WHIRL_T)
    assert balance.balance_error <= balance.tolerance and balance.warning is None


def test_a_failure_after_the_energy_went_astray_names_the_integration_and_the_fix():
    """A run that failed after its energy balance went off by 0.4 of the energy exchanged (no work
    or dissipation accounts for it): the failure's cause names the integration, its settings and
    the fix (halve h, lower rho_inf), not the scene; within BALANCE_BEFORE_FAILURE it adds nothing."""
    from sidprep.solver.energy import EnergyBalance
    from sidprep.solver.integrators.settings import SolverSettings
    from sidprep.solver.run import BALANCE_BEFORE_FAILURE, numerical_cause

    settings = SolverSettings(method="genalpha", h=FAST_WHIRL_H, rho_inf=1.0)
    astray = EnergyBalance(balance_error=0.4, exchanged=1.0e4, change=4.0e3, excursion=4.0e3, worst=4.0e3)
    message = numerical_cause(astray, settings)
    assert "\n" not in message and "the energy grew by 4e+03 J" in message
    assert "numerical instability of the integration (genalpha, h = 0.005 s, rho_inf = 1), not the scene" in message
    assert "fix: halve h or lower rho_inf to 0.9" in message
    within = EnergyBalance(balance_error=BALANCE_BEFORE_FAILURE / 2, exchanged=1.0e4, change=5e2, excursion=5e2,
                           worst=5e2)
    assert numerical_cause(within, settings) == ""


#: the undriven slider crank through its 9 dead centres at rho_inf near 1 (little or no numerical
#: damping; unprojected it diverged or Newton failed at 0.38 s whatever h): energy excursion
#: |E - E0| / E0 and crank angle against DOP853 (rad) at h = 1 ms (measured rho_inf = 1: 1.27e-2,
#: 6.6e-2; 0.99: 1.27e-2, 6.6e-2), both second order in h (halving h: 4.35, 5.13), and the
#: projection never adds energy (measured: E <= E0 to the last bit)
UNDAMPED_CRANK_ENERGY_RTOL = 2e-2
UNDAMPED_CRANK_ANGLE_TOL = 0.1
UNDAMPED_CRANK_ORDER = (3.5, 6.0)


@pytest.mark.parametrize("rho_inf", [1.0, 0.99])
def test_the_undriven_slider_crank_runs_without_numerical_damping(rho_inf, dead_centre_reference):
    from sidprep.solver import simulate

    runs = [simulate(slider_crank(), 1.0, h=h, rho_inf=rho_inf, output_dt=1e-3) for h in (1e-3, 5e-4)]
    (energy, angle), (energy2, angle2) = (dead_centre_errors(r, dead_centre_reference) for r in runs)
    assert energy <= UNDAMPED_CRANK_ENERGY_RTOL and abs(angle) <= UNDAMPED_CRANK_ANGLE_TOL
    for coarse, fine in ((energy, energy2), (angle, angle2)):
        assert UNDAMPED_CRANK_ORDER[0] <= coarse / fine <= UNDAMPED_CRANK_ORDER[1]
    for r in runs:
        e = r.energy["total"]
        assert np.max(e - e[0]) <= 1e-12 * e[0]


# ---------------------------------------------------------------------------------------------
# Hard-case suite on every integrator.  Each case runs on genalpha, rk4, rk45
# and dop853; where a method cannot do a case (an explicit method on a stiff body at a large
# step) the test asserts that it stops and says so.  Long runs: benchmarks/stability.py.
# ---------------------------------------------------------------------------------------------

#: per method, the settings of the cases on the 10-mode bar (f_max 2.7 kHz, omega_max 1.7e4
#: rad/s): genalpha the scene's step; rk4 a step inside its stability limit (h omega_max = 1.7
#: < 2.8); rk45 / dop853 an error tolerance (they find the stable step themselves)
ON = {"genalpha": {"h": 1e-3}, "rk4": {"h": 1e-4}, "rk45": {"rtol": 1e-8}, "dop853": {"rtol": 1e-8}}


def run_on(method, system, t_end, **kw):
    """simulate ``system`` with ``method`` and its settings ON[method] (overridden by kw)."""
    from sidprep.solver import simulate

    return simulate(system, t_end, method=method, **{**ON[method], "output_dt": 1e-3, **kw})


#: whirl of the hinged 10-mode bar at 50 rad/s for 0.3 s (15 rad), sampled every 1 ms: energy
#: law |E - E0| / E0 (measured genalpha 3.5e-5: the O(h^2) excursion of the modes ringing from
#: the start; rk4 2.8e-5: its damping of the modes at h omega_max = 1.7; rk45 4.9e-9, dop853 9e-10)
SUITE_WHIRL_RTOL = WHIRL_ENERGY_RTOL
#: ... hinge angle at the end against the rigid twin by dop853 at rtol 1e-10, rad (the elastic
#: stretch changes the inertia by ~Omega^2 / omega_1^2 = 9e-4: measured 8.7e-4 genalpha, 8.4e-4
#: on each explicit method: the flexible bar turns that much slower than its rigid twin)
SUITE_WHIRL_ANGLE_TOL = 2e-3


@pytest.fixture(scope="module")
def whirl_reference():
    """Hinge angle (rad) at 0.3 s of the rigid twin of the 10-mode bar, DOP853 rtol 1e-10."""
    from sidprep.sid.io import read_sid

    r = whirl(hinged_rigid_twin(read_sid(PENDULUM_SID)), t_end=0.3, method="dop853", rtol=1e-10)
    return float(r.joints["hinge"].coordinate[-1])


@pytest.mark.parametrize("method", METHODS)
def test_suite_spinning_flexible_body_on_a_joint(method, whirl_reference):
    """The hinged 10-mode bar whirling at 50 rad/s under gravity, 0.3 s: the energy law holds
    and the hinge angle follows the rigid twin (a second formulation, DOP853 at rtol 1e-10)."""
    from sidprep.sid.io import read_sid
    from sidprep.solver import Revolute, System

    s = System(gravity=(0.0, 0.0, -9.81))
    body, marker = hinged_flexible(read_sid(PENDULUM_SID))(s)
    s.add(Revolute(s.ground.marker(rotation=_Z_TO_Y), marker, name="hinge"))
    r = run_on(method, s, 0.3)
    e = r.energy["total"]
    assert r.t[-1] == pytest.approx(0.3)
    assert np.max(np.abs(e - e[0])) <= SUITE_WHIRL_RTOL * e[0]
    assert r.joints["hinge"].coordinate[-1] == pytest.approx(whirl_reference, abs=SUITE_WHIRL_ANGLE_TOL)


#: undriven rigid slider crank (crank 0.25 m, conrod 1 m, 5 kg slider, no gravity, no friction)
#: started at 30 rad/s: 1 s passes 9 dead centres.  Explicit methods: energy law |E - E0| / E0
#: (measured rk4 2.6e-8, rk45 3.5e-7, dop853 1.1e-7) and crank angle at 1 s against DOP853 at
#: rtol 1e-10, rad (measured 7e-8, 2.7e-6, 8e-7)
DEAD_CENTRE_ENERGY_RTOL = 1e-5
DEAD_CENTRE_ANGLE_TOL = 1e-5
#: genalpha at h = 1 ms: an energy excursion of 9.9e-3 at each dead centre (where index-3
#: generalised-alpha's velocity-level constraint error meets the fastest change of the slider's
#: speed; it does not accumulate: E(end) - E(0) 2.9e-4) and a crank angle 2.7e-2 rad behind,
#: both O(h^2): halving h divides both by 4 (measured 4.00 and 4.04)
DEAD_CENTRE_GA_ORDER = (3.0, 5.0)
DEAD_CENTRE_GA_ENERGY_RTOL = 1.5e-2
DEAD_CENTRE_GA_ANGLE_TOL = 4e-2


def slider_crank(speed=30.0):
    """Rigid slider crank in the xy plane, crank along +y at t = 0 (the slider half-way
    between its dead centres), crank rate ``speed`` rad/s, nothing driving it."""
    from sidprep.solver import Prismatic, Revolute, RigidBody, System

    r, l = 0.25, 1.0
    xs = np.sqrt(l**2 - r**2)
    s = System(gravity=(0.0, 0.0, 0.0))
    crank = s.add(RigidBody(2.0, com=(r / 2, 0, 0), inertia=(1e-3, 0.02, 0.02), name="crank",
                            rotation=(0, 0, np.pi / 2)))
    rod = s.add(RigidBody(3.0, com=(l / 2, 0, 0), inertia=(1e-3, 0.25, 0.25), name="rod", position=(0, r, 0),
                          rotation=(0, 0, -np.arcsin(r / l))))
    slider = s.add(RigidBody(5.0, inertia=(0.01, 0.01, 0.01), name="slider", position=(xs, 0, 0)))
    s.add(Revolute(s.ground.marker(), crank.marker(), name="crank_joint", initial_rate=speed))
    s.add(Revolute(crank.marker(position=(r, 0, 0)), rod.marker(), name="pin"))
    s.add(Revolute(rod.marker(position=(l, 0, 0)), slider.marker(), name="small_end"))
    along_x = np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]])          # marker z along x
    s.add(Prismatic(s.ground.marker(position=(xs, 0, 0), rotation=along_x), slider.marker(rotation=along_x),
                    name="guide"))
    return s


@pytest.fixture(scope="module")
def dead_centre_reference():
    from sidprep.solver import simulate

    return float(simulate(slider_crank(), 1.0, method="dop853", rtol=1e-10, output_dt=1e-3)
                 .joints["crank_joint"].coordinate[-1])


def dead_centre_errors(r, reference) -> tuple[float, float]:
    """(largest |E - E0| / E0, crank angle at the end - reference (rad)) of a slider-crank run."""
    e = r.energy["total"]
    crank = r.joints["crank_joint"].coordinate
    assert (crank[-1] - crank[0]) / np.pi > 9          # dead centres at every half turn
    return float(np.max(np.abs(e - e[0])) / e[0]), float(crank[-1] - reference)


@pytest.mark.parametrize("method", METHODS)
def test_suite_dead_centres(method, dead_centre_reference):
    """The undriven slider crank at 30 rad/s through 9 dead centres in 1 s: the explicit
    methods keep the energy law and follow DOP853 at a tight tolerance; generalised-alpha's
    energy excursion and phase error are second order in h (a convergence check: halving h
    divides both by 4)."""
    energy, angle = dead_centre_errors(run_on(method, slider_crank(), 1.0), dead_centre_reference)
    if method != "genalpha":
        assert energy <= DEAD_CENTRE_ENERGY_RTOL and abs(angle) <= DEAD_CENTRE_ANGLE_TOL
        return
    assert energy <= DEAD_CENTRE_GA_ENERGY_RTOL and abs(angle) <= DEAD_CENTRE_GA_ANGLE_TOL
    energy2, angle2 = dead_centre_errors(run_on(method, slider_crank(), 1.0, h=ON[method]["h"] / 2),
                                         dead_centre_reference)
    for coarse, fine in ((energy, energy2), (angle, angle2)):
        assert DEAD_CENTRE_GA_ORDER[0] <= coarse / fine <= DEAD_CENTRE_GA_ORDER[1]


#: start off the assembled pose: the constraint error after the projection, m (the assembly's
#: POSITION_TOL scale; measured 9e-21 on every method: the hinge is met exactly)
PROJECTED_CONSTRAINT_TOL = 1e-9
#: the energy at t = 0 against m g z_cm of the projected pose computed here, relative (measured 0)
PROJECTED_ENERGY_RTOL = 1e-9
#: energy law over the 0.5 s swing |E - E0| / (m g L) (measured genalpha 1.6e-6, rk4 4e-15, rk45
#: 9.4e-8, dop853 3.9e-8)
PROJECTED_SWING_RTOL = 1e-5


@pytest.mark.parametrize("method", METHODS)
def test_suite_start_off_the_assembled_pose(method):
    """A 2 kg rod placed 5 cm off its hinge and turned off the hinge axis, with a velocity
    along the hinge axis: the consistent start lands on the constraints (error within the
    assembly tolerance, velocity along the axis removed), its energy is m g z_cm of the pose
    it lands on (computed here from R, A, no kinetic energy), and the swing keeps it."""
    from scipy.spatial.transform import Rotation

    from sidprep.solver import Revolute, RigidBody, System

    m, com = 2.0, np.array([0.5, 0.0, 0.0])
    s = System(gravity=(0.0, 0.0, -9.81))
    rod = s.add(RigidBody(m, com=com, inertia=(1e-3, 0.04, 0.04), name="rod", position=(0.03, 0.04, -0.02),
                          rotation=Rotation.from_rotvec([0.1, 0.0, 0.2]).as_matrix(), velocity=(0, 0.3, 0)))
    s.add(Revolute(s.ground.marker(rotation=_Z_TO_Y), rod.marker(rotation=_Z_TO_Y), name="hinge"))
    r = run_on(method, s, 0.5)
    body = r.bodies["rod"]
    z_cm = body.position[0, 2] + (body.rotation[0] @ com)[2]
    assert r.constraint_error[0] <= PROJECTED_CONSTRAINT_TOL
    assert np.linalg.norm(body.position[0]) <= PROJECTED_CONSTRAINT_TOL
    assert r.energy["kinetic"][0] == pytest.approx(0.0, abs=1e-12)
    assert r.energy["total"][0] == pytest.approx(m * 9.81 * z_cm, rel=PROJECTED_ENERGY_RTOL)
    e = r.energy["total"]
    assert np.max(np.abs(e - e[0])) <= PROJECTED_SWING_RTOL * m * 9.81 * 0.5


#: pendulum of a 1 kg bob on a 1e-9 kg link of 1 m released at 60 deg: the bob's first pass
#: through the vertical at T/4 = sqrt(l/g) K(sin(theta0/2)) (complete elliptic integral),
#: relative (measured genalpha 1.9e-6, rk4 5e-10, rk45 1e-9, dop853 5e-10)
NEAR_ZERO_MASS_RTOL = 1e-5
NEAR_ZERO_LINK_KG = 1e-9


@pytest.mark.parametrize("method", METHODS)
def test_suite_near_zero_mass_link(method):
    """A 1e-9 kg link (1 m) hinged to ground carries a 1 kg bob on a second hinge: a simple
    pendulum (the bob's own spin is torque-free); its quarter period is the closed form."""
    from scipy.special import ellipk

    from sidprep.solver import Revolute, RigidBody, System

    l, theta0, g = 1.0, np.radians(60.0), 9.81
    s = System(gravity=(0.0, 0.0, -g))
    link = s.add(RigidBody(NEAR_ZERO_LINK_KG, com=(l / 2, 0, 0), inertia=(1e-12, 1e-10, 1e-10), name="link",
                           rotation=(0, np.pi / 2 - theta0, 0)))        # x axis theta0 from hanging down
    bob = s.add(RigidBody(1.0, inertia=(1e-3, 1e-3, 1e-3), name="bob",
                          position=(l * np.sin(theta0), 0, -l * np.cos(theta0))))
    s.add(Revolute(s.ground.marker(rotation=_Z_TO_Y), link.marker(rotation=_Z_TO_Y), name="hinge"))
    s.add(Revolute(link.marker(position=(l, 0, 0), rotation=_Z_TO_Y), bob.marker(rotation=_Z_TO_Y), name="bob pin"))
    r = run_on(method, s, 0.6)
    x = r.bodies["bob"].position[:, 0]
    k = int(np.flatnonzero(x <= 0)[0])
    t_quarter = r.t[k - 1] - x[k - 1] * (r.t[k] - r.t[k - 1]) / (x[k] - x[k - 1])
    assert t_quarter == pytest.approx(np.sqrt(l / g) * ellipk(np.sin(theta0 / 2) ** 2), rel=NEAR_ZERO_MASS_RTOL)


#: 60 free-free modes of the bar (264 Hz ... 22.4 kHz; omega_max 1.4e5 rad/s) hinged and
#: released horizontally without static start (the modes ring), h = 1 ms: h f_max = 22
MANY_MODES = 60
#: genalpha: largest energy excursion above the start in m g L (measured 0: the energy never
#: rises above its start) and growth at the end (STIFF_ENERGY_GROWTH; measured -2.9e-7)
MANY_MODES_EXCURSION = 2e-4
#: explicit methods with error control on this stiff body choose stable steps themselves, at a
#: cost: h_max omega_max stays below this (measured rk45 1.15, dop853 2.96; 10 ms of motion cost
#: 3.0 and 2.5 integration CPU-s, genalpha's 300 ms 0.24: ~300x per simulated second) and the
#: energy law holds to (in m g L; measured 1e-13, 5e-14)
MANY_MODES_H_OMEGA = 4.0
MANY_MODES_ENERGY = 1e-10


@pytest.fixture(scope="module")
def bar_many_modes(tmp_path_factory):
    return reduced_bar(tmp_path_factory.mktemp("many"), "--modes", str(MANY_MODES))


@pytest.mark.parametrize("method", METHODS)
def test_suite_stiff_body_with_many_high_modes_at_a_large_step(method, bar_many_modes):
    """The 60-mode bar at h = 1 ms: genalpha keeps the energy bounded (the modes it cannot
    resolve are damped, not amplified); rk4 at that step stops at the first non-finite state
    and says to use genalpha or a smaller step; rk45 / dop853 finish with the energy law by
    choosing stable steps (slow: h_max within their stability limit)."""
    from sidprep.errors import SimulationFailed
    from sidprep.solver import FlexibleBody, Revolute, System

    sid = bar_many_modes
    omega_max = 2 * np.pi * float(np.max(sid.frequencies_hz))
    assert sid.nq == MANY_MODES and 1e-3 * omega_max / (2 * np.pi) > 20
    s = System(gravity=(0.0, 0.0, -9.81))
    bar = s.add(FlexibleBody(sid, name="bar"))
    s.add(Revolute(s.ground.marker(rotation=_Z_TO_Y), bar.node_marker(0, rotation=_Z_TO_Y), name="hinge"))
    mgl = sid.mass * 9.81 * 1.0
    if method == "rk4":
        with np.errstate(all="ignore"), pytest.raises(SimulationFailed) as exc:
            run_on(method, s, 0.3, h=1e-3)
        assert "non-finite state" in str(exc.value) and "genalpha" in str(exc.value)
        assert np.all(np.isfinite(exc.value.result.bodies["bar"].q))
        return
    if method == "genalpha":
        r = run_on(method, s, 0.3, h=1e-3)
        e = r.energy["total"]
        assert np.all(np.isfinite(r.bodies["bar"].q))
        assert np.max(e - e[0]) < MANY_MODES_EXCURSION * mgl and e[-1] - e[0] < STIFF_ENERGY_GROWTH * mgl
        return
    r = run_on(method, s, 0.01, rtol=1e-6)
    e = r.energy["total"]
    assert r.t[-1] == pytest.approx(0.01) and r.stats.h_max * omega_max < MANY_MODES_H_OMEGA
    assert np.max(np.abs(e - e[0])) < MANY_MODES_ENERGY * mgl


#: rotor above its first critical speed: the clamped 4-mode bar (`--stiffening`) driven about
#: z through its root at ROTOR_ABOVE x its first lag (in-plane bending) frequency f0 = 41.9 Hz
ROTOR_ABOVE = 1.5
#: with centrifugal stiffening the lag motion oscillates at sqrt(f0^2 + (K1 - 1) (Omega / 2 pi)^2)
#: (Southwell, SOUTHWELL_LAG, of a uniform Euler-Bernoulli cantilever; 46.9 Hz here): measured
#: -2.2e-2 genalpha (h = 0.25 ms), -1.4e-2 on each explicit method (the 3D bar is not the 1D beam)
ROTOR_FREQUENCY_RTOL = 3e-2
#: ... with a bounded amplitude, in units of its start (the Coriolis exchange with the axial
#: stretch, the bar starting unstretched at full speed, lifts it: measured 1.106, 1.105)
ROTOR_AMPLITUDE_BOUND = 1.2
#: without it (Oe.M1 = Kom + K0omega left out together: the softening -Omega^2 Me and the
#: stiffening) the lag mode keeps f0 (measured -3.7e-4 genalpha, 5e-9 explicit), 11 % below Southwell: the
#: effects report warns (centrifugal_stiffening sized 1.3)
ROTOR_PLAIN_RTOL = 2e-3
#: start of the lag mode, modal units
ROTOR_Q0 = 1e-4


@pytest.fixture(scope="module")
def clamped_bar(tmp_path_factory):
    return reduced_bar(tmp_path_factory.mktemp("clamped"), "--modes", "4", "--frame", "fixed_end", "--stiffening")


def rotor(sid, stiffening: bool):
    """(system, lag mode index, f0 Hz, Omega rad/s): the clamped bar driven at ROTOR_ABOVE x f0."""
    from sidprep.solver import FlexibleBody, Revolute, System
    from sidprep.solver.model.joints import ConstantSpeed, Driver

    lag = int(np.argmax(np.abs(sid.Ct.M0[:, 1])))
    f0 = float(sid.frequencies_hz[lag])
    spin = ROTOR_ABOVE * 2 * np.pi * f0
    effects = ["coupling", "coriolis", "centrifugal", "inertia_change"] + ["centrifugal_stiffening"] * stiffening
    s = System(gravity=(0, 0, 0), effects=effects)
    q0 = np.zeros(sid.nq)
    q0[lag] = ROTOR_Q0
    beam = s.add(FlexibleBody(sid, name="beam", q0=q0, omega=(0, 0, spin)))
    hub = s.add(Revolute(s.ground.marker(position=sid.nodes[0].origin.M0[:, 0]), beam.node_marker(0)))
    s.add(Driver(hub, ConstantSpeed(spin)))
    return s, lag, f0, spin


def zero_crossing_frequency(t, x) -> float:
    """Mean frequency (Hz) of the upward zero crossings of x - mean(x)."""
    xm = x - x.mean()
    up = np.flatnonzero((xm[:-1] < 0) & (xm[1:] >= 0))
    tz = t[up] - xm[up] * (t[up + 1] - t[up]) / (xm[up + 1] - xm[up])
    return (len(tz) - 1) / (tz[-1] - tz[0])


@pytest.mark.parametrize("method", METHODS)
def test_suite_rotor_above_its_critical_speed(method, clamped_bar):
    """1.5 x above the first critical speed: with centrifugal stiffening the lag mode stays
    bounded at the Southwell frequency; without it the lag mode keeps its SID frequency f0 and
    the effects report warns that centrifugal_stiffening is left out (the speed changes it)."""
    rotor_on = {**ON, "genalpha": {"h": 2.5e-4}, "rk4": {"h": 5e-5}}
    s, lag, f0, spin = rotor(clamped_bar, stiffening=True)
    r = run_on(method, s, 0.15, **rotor_on[method], output_dt=1e-4)
    x = r.bodies["beam"].q[:, lag]
    southwell = np.sqrt(f0**2 + SOUTHWELL_LAG * (spin / (2 * np.pi)) ** 2)
    assert np.all(np.isfinite(x)) and np.abs(x).max() <= ROTOR_AMPLITUDE_BOUND * ROTOR_Q0
    assert zero_crossing_frequency(r.t, x) == pytest.approx(southwell, rel=ROTOR_FREQUENCY_RTOL)
    assert not any("centrifugal_stiffening" in w for w in r.effects.warnings)

    s, lag, f0, spin = rotor(clamped_bar, stiffening=False)
    r = run_on(method, s, 0.15, **rotor_on[method], output_dt=1e-4)
    x = r.bodies["beam"].q[:, lag]
    assert zero_crossing_frequency(r.t, x) == pytest.approx(f0, rel=ROTOR_PLAIN_RTOL)
    assert southwell / f0 - 1 > 3 * ROTOR_FREQUENCY_RTOL       # the two are told apart
    assert any("centrifugal_stiffening" in w for w in r.effects.warnings)


def test_a_singular_system_gives_nan_not_an_internal_error():
    """rk4 on the flexible engine at its 0.2 ms step reached an exactly singular KKT matrix and
    ended in an internal ZeroDivisionError; a zero pivot now gives NaN, which the steppers'
    non-finite checks report with the cause and the fix."""
    def solve(a, b):  # the core factors in place into (lu, piv) and solves into x
        lu, piv, x = np.array(a, dtype=float), np.zeros(len(a), np.int32), np.zeros(len(a))
        lu_factor(lu, piv)
        lu_solve(lu, piv, np.asarray(b, dtype=float), x)
        return x

    assert np.isnan(solve([[1.0, 2.0], [2.0, 4.0]], [1.0, 1.0])).any()
    regular = np.array([[4.0, 1.0], [2.0, 3.0]])
    np.testing.assert_allclose(solve(regular, [1.0, 2.0]), np.linalg.solve(regular, [1.0, 2.0]),
                               rtol=1e-14)


#: the work integral against scipy's cumulative_simpson (the same composite Simpson rule: round-off)
WORK_INTEGRAL_RTOL = 1e-13


def test_work_integral_is_simpsons_rule_exact_for_parabolas():
    """energy.work_integral integrates a quadratic power exactly on irregular samples (closed
    form), agrees with scipy's cumulative_simpson, and is the trapezoid for two samples."""
    from scipy.integrate import cumulative_simpson

    from sidprep.solver.energy import work_integral

    rng = np.random.default_rng(7)
    for n in (3, 4, 7, 100):
        t = np.cumsum(rng.uniform(0.01, 0.2, n))
        power = 2.0 - 3.0 * t + 5.0 * t**2                              # W
        exact = 2.0 * (t - t[0]) - 1.5 * (t**2 - t[0] ** 2) + 5.0 / 3.0 * (t**3 - t[0] ** 3)
        assert np.max(np.abs(work_integral(t, power) - exact)) <= WORK_INTEGRAL_RTOL * np.max(np.abs(exact))
        noisy = rng.normal(size=n)
        reference = cumulative_simpson(noisy, x=t, initial=0.0)
        assert np.max(np.abs(work_integral(t, noisy) - reference)) <= WORK_INTEGRAL_RTOL * np.max(np.abs(reference))
    assert work_integral(np.array([0.0, 0.5]), np.array([1.0, 3.0])) == pytest.approx([0.0, 1.0], abs=0)
