"""Absolute-nodal planar beams (sidprep/solver/absolute_nodal.py, Kisu Lee's paper) against independent references:
energy and angular-momentum conservation, the rigid pendulum (scipy ODE), the rigid driven link
(closed-form motor torque) and RK4's order of convergence."""

import math
from pathlib import Path

import numpy as np
import pytest
from readme_numbers import check_numbers
from scipy.integrate import solve_ivp

from sidprep.errors import InputError
from sidprep.solver.absolute_nodal.assembly import assemble, beam_system, initial_vector, unpack
from sidprep.solver.absolute_nodal.model import AbsoluteNodalModel, Beam, Driver, Support
from sidprep.solver.absolute_nodal.run import integrate, simulate_absolute_nodal
from sidprep.solver.absolute_nodal.scene import load_absolute_nodal_scene
from sidprep.solver.core.absolute_nodal import RK4Progress, rk4_loop
from sidprep.solver.integrators.settings import SolverSettings
from sidprep.tables import read_toml_text

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "two_link_manipulator" / "scene.toml"
G = 9.81
#: energy error of the two-link example over 2 s, relative to the initial total
#: (the paper, section 3, reports 0.03 %; we ask ten times better)
TWO_LINK_ENERGY_TOL = 3e-5
#: a very stiff link against the rigid pendulum (rad)
RIGID_PENDULUM_TOL = 1e-4
#: fourth order: the step-halving ratio of the position error is 16 +- 10 %
ORDER_RATIO, ORDER_RATIO_TOL = 16.0, 0.10


def _smooth(x, n):
    """Moving average over n samples (removes the link's vibration, ~250 Hz, from forces)."""
    return np.convolve(x, np.ones(n) / n, mode="valid")


def _two_link(t_end=None):
    root, _ = read_toml_text(EXAMPLE)
    return load_absolute_nodal_scene(root, EXAMPLE, t_end=t_end)


def _stiff_link(EI=1e6, angle=0.0, rate=0.0, drivers=(), gravity=(0.0, -G), supports=True):
    beam = Beam("link", 1.0, 5.0, EI, 100.0 * EI, 4, ("pin", "tip"), angle, rate)
    sup = (Support("pin", "pin"),) if supports else ()
    return AbsoluteNodalModel((beam,), sup, drivers, (), gravity)


def test_two_link_energy_is_conserved():
    scene = _two_link(t_end=2.0)
    assert scene.settings.h == 2.5e-4 and scene.model.beams[1].angle == pytest.approx(math.radians(15))
    r = simulate_absolute_nodal(scene.model, scene.t_end, scene.settings)
    total = r.energy["total"]
    assert np.max(np.abs(total - total[0])) / total[0] < TWO_LINK_ENERGY_TOL
    # the motion is large: most of the potential energy turns into kinetic energy and back
    assert np.max(r.energy["kinetic"]) > 0.8 * total[0]
    # zero gravitational energy for the straight hanging links: 5 kg g (0.5 + 1.5 + sin 15 deg / 2) m at the start
    assert r.energy["gravity"][0] == pytest.approx(5 * G * (2.0 + 0.5 * math.sin(math.radians(15))), rel=1e-12)
    at = [int(np.argmin(np.abs(r.t - x))) for x in (0.5, 1.0, 2.0)]
    phi1, rel = r.joints["pin"].coordinate, r.joints["elbow"].coordinate
    check_numbers(EXAMPLE.parent / "README.md", "results", [
        np.max(np.abs(total - total[0])) / total[0], 0.03, 0, TWO_LINK_ENERGY_TOL,
        r.energy["gravity"][0], 1e-12,
        0.5, 1.0, 2.0, *phi1[at], 0.5, 1.0, 2.0, *rel[at],
        0.5, *r.markers["tip"][at[0], :2],
        1e3 * np.max(np.abs(r.bodies["link1"].q[:, 0])), 1e3 * 5 * G * 1.0**3 / (8 * 1e3)])


def test_rk4_is_fourth_order_on_the_two_link_system():
    asm = assemble(_two_link().model)
    system, y0 = beam_system(asm), initial_vector(asm)
    # node positions at t = 0.1 s for h = 1.25e-4, 6.25e-5, 3.125e-5 s (the paper's 2.5e-4 s is
    # close to RK4's stability limit of the axial modes, h omega_max = 2.4 < 2.8, not yet asymptotic)
    t_end, x = 0.1, []
    nf2 = 2 * len(asm.free)
    for n in (800, 1600, 3200):
        _, Y = rk4_loop(system, RK4Progress(0.0, y0.copy(), 0.0, 0), t_end, t_end / n, 0.0, n)
        x.append(Y[-1, :nf2])
    ratio = np.linalg.norm(x[0] - x[1]) / np.linalg.norm(x[1] - x[2])
    assert abs(ratio / ORDER_RATIO - 1.0) < ORDER_RATIO_TOL, ratio


def test_stiff_link_is_the_rigid_pendulum():
    # rigid bar pinned at one end, released horizontally: psi'' = -(3 g / 2 L) cos psi (I = m L^2 / 3,
    # which the linear interpolation of eq. 1 reproduces exactly for a straight bar)
    r = simulate_absolute_nodal(_stiff_link(), 0.6, SolverSettings(method="rk4", h=2e-5, output_dt=1 / 5000))
    ref = solve_ivp(lambda t, y: [y[1], -1.5 * G * math.cos(y[0])], (0, r.t[-1]), [0.0, 0.0],
                    t_eval=np.minimum(r.t, r.t[-1]), rtol=1e-12, atol=1e-12)
    assert np.max(np.abs(r.joints["pin"].coordinate - ref.y[0])) < RIGID_PENDULUM_TOL
    # pin reaction of the rigid pendulum, m (a_cm - g), against the vibration-averaged one (20 ms)
    psi, w = ref.y
    wd = -1.5 * G * np.cos(psi)
    a_cm = 0.5 * np.array([-wd * np.sin(psi) - w * w * np.cos(psi), wd * np.cos(psi) - w * w * np.sin(psi)])
    for c in range(2):
        rigid = 5.0 * (a_cm[c] - (0.0, -G)[c])
        assert np.max(np.abs(_smooth(r.joints["pin"].force[:, c] - rigid, 100))) < 1e-2 * 5 * G  # 1 % of the weight


def test_free_spinning_link_keeps_length_energy_and_angular_momentum():
    model = _stiff_link(EI=1e3, rate=10.0, gravity=(0.0, 0.0), supports=False)
    asm = assemble(model)
    r = simulate_absolute_nodal(model, 1.0, SolverSettings(method="rk4", h=2.5e-5, output_dt=1 / 200))
    tip, root = r.markers["tip"][:, :2], r.markers["pin"][:, :2]
    length = np.linalg.norm(tip - root, axis=1)
    # centrifugal stretch of a bar spinning about its centre: m w^2 L^2 / (12 EA) = 4e-4 m; bending: none
    assert np.max(np.abs(length - 1.0)) < 1e-3
    total = r.energy["total"]
    assert np.max(np.abs(total - total[0])) / total[0] < 1e-9
    assert r.energy["kinetic"][0] == pytest.approx(0.5 * 5.0 / 3.0 * 10.0**2, rel=1e-12)  # about its end: m L^2 / 3
    # angular momentum sum_ij M_ij x_i x v_j about the origin (exact for the C0 interpolation) is conserved
    t, Y, _ = integrate(asm, 1.0, SolverSettings(method="rk4", h=2.5e-5, output_dt=1 / 200))
    X, V = unpack(asm, Y)
    H = np.einsum("ij,si,sj->s", asm.Ms, X[:, :, 0], V[:, :, 1]) - np.einsum("ij,si,sj->s", asm.Ms, X[:, :, 1], V[:, :, 0])
    assert np.max(np.abs(H - H[0])) < 1e-9 * abs(H[0])


def test_driven_stiff_link_follows_the_motion_with_the_rigid_motor_torque():
    # rest-to-rest cycloid of 90 deg in 0.5 s against gravity; rigid motor torque I psi'' + m g L/2 cos psi
    drv = Driver("motor", "pin", "link", 0.0, math.pi / 2, 0.5)
    r = simulate_absolute_nodal(_stiff_link(drivers=(drv,)), 0.6,
                                SolverSettings(method="rk4", h=2e-5, output_dt=1 / 5000))
    tau = np.minimum(r.t / 0.5, 1.0)
    psi = math.pi / 2 * (tau - np.sin(2 * math.pi * tau) / (2 * math.pi))
    psidd = np.where(tau < 1, math.pi / 2 * 2 * math.pi * np.sin(2 * math.pi * tau) / 0.25, 0.0)
    # the chord lags the clamped tangent by the link's bending under the motor torque (~1e-5 rad)
    assert np.max(np.abs(r.joints["pin"].coordinate - psi)) < RIGID_PENDULUM_TOL
    assert np.max(r.constraint_error) < 1e-8
    torque = 5.0 / 3.0 * psidd + 5.0 * G * 0.5 * np.cos(psi)
    assert np.max(np.abs(_smooth(r.joints["pin"].effort - torque, 100))) < 1e-2 * np.max(np.abs(torque))
    # energy balance with the driver's work
    total = r.energy["total"]
    assert np.max(np.abs(total - total[0])) < 1e-3 * np.max(np.abs(r.energy["external"]))


@pytest.mark.parametrize("edit, message", [
    (("elements = 4", "elements = 1", 1), "elements"),
    (('points = ["elbow", "tip"]', 'points = ["elbow"]', 1), "points"),
    (("EI = 1.0e3", "EI = -1.0", 1), "EI"),
    (('"tip.position.x"', '"tip.position.q"', 1), "signals"),
    (('point = "pin"', 'point = "hub"', 1), "unknown point"),
])
def test_bad_scene_gives_one_line_error(tmp_path, edit, message):
    old, new, count = edit
    text = EXAMPLE.read_text().replace(old, new, count)
    path = tmp_path / "bad.toml"
    path.write_text(text)
    root, _ = read_toml_text(path)
    with pytest.raises(InputError) as exc:
        load_absolute_nodal_scene(root, path)
    assert str(path) in str(exc.value) and message in str(exc.value) and "\n" not in str(exc.value)


def test_step_beyond_rk4_stability_is_refused_before_the_run():
    # 8 elements per link: the axial modes need h <= 2.6 / omega_max ~ 1.3e-4 s (the paper's
    # 2.5e-4 s suits 4 elements); bar estimate omega_max ~ 2 sqrt(3) sqrt(EA L / m) / e
    scene = _two_link(t_end=0.01)
    model = AbsoluteNodalModel(tuple(Beam(b.name, b.length, b.mass, b.EI, b.EA, 8, b.points, b.angle)
                                     for b in scene.model.beams), scene.model.supports)
    with pytest.raises(InputError, match="stability limit"):
        simulate_absolute_nodal(model, 0.01, SolverSettings(method="rk4", h=2.5e-4))


#: FFR cross-check over the first swing (t <= 0.5 s): the FFR model is the coarse one (20 mm tet10
#: strip, 2 eigenmodes + FRMs; within 1.6e-5 of its finest refinement there); absolute nodal with
#: 16 elements per link measured 5.7e-5 rad, 1.3e-4 rad, 4.3e-5 m, 1.0e-4 m against the 10 mm /
#: 8-mode model (README table); allowed about twice that:
FFR_TOL = {"phi1": 1.2e-4, "phi2 - phi1": 2.5e-4, "tip x": 1e-4, "tip y": 2e-4}


def test_floating_frame_solver_agrees_and_the_difference_shrinks(tmp_path):
    import sys

    sys.path.insert(0, str(EXAMPLE.parent))
    try:
        import ffr_crosscheck as fc
    finally:
        sys.path.pop(0)
    t_end = 0.5
    size, modes, h = fc.LEVELS[0][1]
    t, coarse = fc.anc_signals(4, t_end, rate=200.0)
    _, fine = fc.anc_signals(16, t_end, rate=200.0)
    _, rigid = fc.anc_signals(4, t_end, rate=200.0, EI=1e3 * fc.EI)
    ffr = fc.ffr_signals(fc.reduced_strip(size, modes, tmp_path), t_end, h, t, tmp_path)
    for key, tol in FFR_TOL.items():
        d_coarse, d_fine = (np.max(np.abs(a[key] - ffr[key])) for a in (coarse, fine))
        flexible = np.max(np.abs(fine[key] - rigid[key]))
        assert d_fine < tol, (key, d_fine)
        assert d_fine < 0.5 * d_coarse, (key, d_fine, d_coarse)          # shrinks with refinement
        assert d_fine < flexible / 3, (key, d_fine, flexible)             # and is small against the flexibility


def test_scene_file_runs_through_sidprep_simulate(tmp_path):
    """The two-link scene through `sidprep simulate` (the scene dispatches to this formulation):
    the results file holds the run, whose total energy stays within the conservation tolerance, and
    the signals are listed before a run."""
    from sidprep.cli.main import main
    from sidprep.solver.results import read_results, signal

    scene = Path(__file__).resolve().parents[1] / "examples" / "two_link_manipulator" / "scene.toml"
    out = tmp_path / "two.results.h5"
    assert main(["simulate", str(scene), "--t-end", "0.05", "-o", str(out), "--json", "--quiet"]) == 0
    total = signal(read_results(out).result, "energy.total")[0]
    assert np.max(np.abs(total - total[0])) / total[0] < TWO_LINK_ENERGY_TOL
    assert main(["simulate", str(scene), "--list-signals"]) == 0
