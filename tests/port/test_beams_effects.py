"""The compiled core's absolute-nodal beams (sidprep/solver/core/absolute_nodal.pyx) and effects
rows (sidprep/solver/core/effects.pyx) against their numba originals
(sidprep/solver/absolute_nodal/kernels.py, sidprep/solver/effects.py): each kernel on the bundled
two-link example and the absolute-nodal test scenes at random states, whole RK4 runs sample by
sample, elastic_rows on the example bodies' terms."""

import functools
import math
from pathlib import Path

import numpy as np
import pytest

from sidprep.solver.absolute_nodal import kernels as numba_kernels
from sidprep.solver.absolute_nodal.assembly import BAUMGARTE_RATE, assemble, initial_vector
from sidprep.solver.absolute_nodal.model import AbsoluteNodalModel, Beam, Driver, Support
from sidprep.solver.absolute_nodal.scene import load_absolute_nodal_scene
from sidprep.solver.core import absolute_nodal as core
from sidprep.tables import read_toml_text

ROOT = Path(__file__).resolve().parents[2]
TWO_LINK = ROOT / "examples" / "two_link_manipulator" / "scene.toml"
G = 9.81
#: one kernel evaluation: the same arithmetic in the same order (gcc -O2 without -ffast-math and
#: numba's LLVM both round each operation; BLAS / LAPACK are scipy's for both) - relative to the
#: largest entry of the result
KERNEL_RTOL = 1e-12
#: a whole RK4 run (thousands of steps of a chaotic double pendulum): relative to the largest state
RUN_RTOL = 1e-10
#: samples per RK4 call in the chunked runs: several calls, each resuming where the last stopped
SMALL_CHUNK = 37


def two_link():
    root, _ = read_toml_text(TWO_LINK)
    scene = load_absolute_nodal_scene(root, TWO_LINK)
    return scene.model, scene.t_end, scene.settings.h, scene.settings.output_dt or 0.0


def stiff_link(EI=1e6, rate=0.0, drivers=(), gravity=(0.0, -G), supports=True):
    """The single link of tests/test_absolute_nodal.py."""
    beam = Beam("link", 1.0, 5.0, EI, 100.0 * EI, 4, ("pin", "tip"), 0.0, rate)
    return AbsoluteNodalModel((beam,), (Support("pin", "pin"),) if supports else (), drivers, (), gravity)


#: (model, t_end s, h s, output interval s) of the runs compared: the bundled example and the
#: test scenes (rigid pendulum, free spinning link, driven link - shortened to 0.6 s, 0.2 s, 0.6 s)
SCENES = {
    "two_link": two_link,
    "stiff_pendulum": lambda: (stiff_link(), 0.6, 2e-5, 1 / 5000),
    "free_spinning_link": lambda: (stiff_link(EI=1e3, rate=10.0, gravity=(0.0, 0.0), supports=False), 0.2, 2.5e-5,
                                   1 / 200),
    "driven_link": lambda: (stiff_link(drivers=(Driver("motor", "pin", "link", 0.0, math.pi / 2, 0.5),)), 0.6, 2e-5,
                            1 / 5000),
}


def relative(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300))


def random_states(asm, count, rng):
    """States near the initial one: positions moved by up to 1 cm, velocities up to 1 m/s."""
    y0 = initial_vector(asm)
    n2 = len(y0) // 2
    for _ in range(count):
        y = y0.copy()
        y[:n2] += rng.uniform(-1e-2, 1e-2, n2)
        y[n2:] += rng.uniform(-1.0, 1.0, n2)
        yield y


@pytest.mark.parametrize("name", SCENES)
def test_each_kernel_equals_numba_at_random_states(name):
    model = SCENES[name]()[0]
    asm = assemble(model)
    params = numba_kernels_params(asm)
    system = core.BeamSystem(asm, BAUMGARTE_RATE)
    rng = np.random.default_rng(1)
    for y in random_states(asm, 5, rng):
        t = rng.uniform(0.0, 0.7)
        A, lam, strain = numba_kernels.accelerations(t, y, params)
        A2, lam2, strain2 = system.accelerations(t, y)
        assert relative(A2, A) < KERNEL_RTOL and relative([strain2], [strain]) < KERNEL_RTOL
        if lam.size:
            assert relative(lam2, lam) < KERNEL_RTOL
        X, V = np.array(system.X), np.array(system.V)  # the state's node positions and velocities
        for j in range(len(asm.beam_n)):
            n, e = asm.beam_n[j], asm.beam_e[j]
            nodes = asm.beam_nodes[j, :n]
            for got, want in zip(system.beam_kinematics(X, V, A, j), numba_kernels.beam_kinematics(X, V, A, nodes, n, e)):
                assert relative(got, want) < KERNEL_RTOL
            Q = rng.normal(size=X.shape)
            Q2 = Q.copy()
            energy = numba_kernels.beam_elastic(X, nodes, n, e, asm.beam_K[j], Q)
            assert relative([system.beam_elastic(X, j, Q2)], [energy]) < KERNEL_RTOL
            assert relative(Q2, Q) < KERNEL_RTOL
            for at_end in (False, True):
                assert relative(system.driver_value(X, V, A, j, at_end),
                                numba_kernels.driver_value(X, V, A, nodes, n, e, at_end)) < KERNEL_RTOL


def numba_kernels_params(asm):
    """The numba kernels' parameter tuple (assembly.kernel_params as the numba kernels read it)."""
    return (asm.X0.copy(), asm.free, asm.Minv, asm.f0, asm.beam_nodes, asm.beam_n, asm.beam_e, asm.beam_K, asm.drv,
            float(BAUMGARTE_RATE))


def test_driver_motion_and_wrapping_equal_numba():
    rng = np.random.default_rng(2)
    for t in np.concatenate([rng.uniform(0.0, 2.0, 50), [0.0, 0.5, 1.0]]):
        for args in ((0.3, 2.0, math.pi / 2, 0.5), (0.0, 0.0, -1.0, 0.0), (1.0, -3.0, 0.0, 0.7)):
            assert relative(core.driver_angle(t, *args), numba_kernels.driver_angle(t, *args)) < KERNEL_RTOL
    for a in np.concatenate([rng.uniform(-20.0, 20.0, 100), [math.pi, -math.pi, 0.0]]):
        assert core.wrapped_angle(a) == numba_kernels.wrapped_angle(a)


@pytest.mark.parametrize("name", SCENES)
def test_whole_rk4_runs_equal_numba(name):
    model, t_end, h, dt = SCENES[name]()
    asm = assemble(model)
    y0 = initial_vector(asm)
    params, system = numba_kernels_params(asm), core.BeamSystem(asm, BAUMGARTE_RATE)
    chunks, progress = [], core.RK4Progress(0.0, y0, dt, 0)
    t, y, next_out, steps = 0.0, y0, dt, 0
    while t < t_end - 1e-12 * max(1.0, t_end):        # the stepper's chunked calls (run.BeamRK4.advance)
        t, y, next_out, steps, ts, Ys = numba_kernels.rk4_loop(t, y, t_end, h, dt, next_out, params, SMALL_CHUNK, steps)
        ts2, Ys2 = core.rk4_loop(system, progress, t_end, h, dt, SMALL_CHUNK)
        chunks.append((ts, Ys, ts2, Ys2))
        assert (progress.t, progress.next_out, progress.steps) == (t, next_out, steps)
    ts, Ys, ts2, Ys2 = (np.concatenate(c) for c in zip(*chunks))
    assert len(ts) == len(ts2) > 10 and np.array_equal(ts, ts2)
    assert relative(Ys2, Ys) < RUN_RTOL


#: the example scenes whose flexible bodies' SID files are bundled
EFFECT_SCENES = ("beam_buckling", "beam_slider_crank", "flexible_pendulum", "helicopter_rotor")


def flexible_bodies(example):
    from sidprep.solver.model.bodies import FlexibleBody
    from sidprep.solver.scene import load_scene

    system = load_scene(ROOT / "examples" / example / "scene.toml").system
    return system, [b for b in system.bodies if isinstance(b, FlexibleBody)]


@functools.cache
def numba_elastic_rows():
    """The numba kernel effects.py had before the core (its reference here), compiled on first use."""
    import numba

    from sidprep.solver.equations.body import body_equations

    @numba.njit
    def elastic_rows(pack, w, gk, ud, modes):
        F, off, flags, mass = pack
        nq, n = modes.shape
        out = np.zeros((w.shape[0], 1 + 2 * n, nq))
        zero = np.zeros(nq)
        for s in range(w.shape[0]):
            m, h = body_equations(F, off, flags, mass, zero, zero, w[s], gk[s])
            out[s, 0] = (m @ ud[s] - h)[6:]
            for j in range(n):
                mode = modes[:, j].copy()
                m, h = body_equations(F, off, flags, mass, mode, zero, w[s], gk[s])
                out[s, 1 + j] = (m @ ud[s] - h)[6:] - out[s, 0]
                m, h = body_equations(F, off, flags, mass, zero, mode, w[s], gk[s])
                out[s, 1 + n + j] = (m @ ud[s] - h)[6:] - out[s, 0]
        return out

    return elastic_rows


@pytest.mark.parametrize("example", EFFECT_SCENES)
def test_elastic_rows_equal_numba_on_the_example_bodies(example):
    from sidprep.solver.core.effects import elastic_rows
    from sidprep.solver.effects import assembled, choose_effects, free_modes, packed, probe_states
    from sidprep.solver.model.effects import EFFECTS

    system, bodies = flexible_bodies(example)
    assert bodies
    rng = np.random.default_rng(4)
    for body in bodies:
        chosen = choose_effects(system, body, "auto")[0]
        avail = body.available()
        terms = packed(body, chosen)[1]
        modes = np.ascontiguousarray(free_modes(terms.Ke, terms.Me)[1])
        nq = modes.shape[0]
        w, a, wdot, g = probe_states()
        probes = (w, g, np.concatenate([a, wdot, np.zeros((len(w), nq))], axis=1), modes)
        states = (rng.normal(size=(3, 3)), rng.normal(size=(3, 3)), rng.normal(size=(3, 6 + nq)),
                  rng.normal(size=(nq, 2)))
        sets = [chosen, assembled({e for e in EFFECTS if avail[e]}, avail)]
        sets += [assembled(chosen | {e}, avail) for e in EFFECTS if avail[e] and e not in chosen]
        for effects in sets:
            pack = packed(body, effects)[0]
            for args in (probes, states):
                want = numba_elastic_rows()(pack, *args)
                got = elastic_rows(pack, *args)
                assert got.shape == want.shape and relative(got, want) < KERNEL_RTOL, (body.name, sorted(effects))
