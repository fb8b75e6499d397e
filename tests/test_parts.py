"""A model reduced in parts (``sidprep reduce --parts N``: sidprep.reduction.component_modes and its
modules, sidprep.jobs.parts).

Independent references: the monolithic Craig-Bampton reduction of the same model (frequencies,
mass properties), a direct sparse solve with the whole model's K_ii (the substructured solve), a
full-model eigen solve (the eigenvalue count over the parts and the certified frequency bounds).
"""

import gc
import json
import os
import signal
import subprocess
import sys
import threading
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import psutil
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
import scipy.sparse.linalg as spla

from sidprep.errors import InputError
from sidprep.fe.assemble import stiffness_and_mass
from sidprep.fe.linalg import MEMORY_HEADROOM, eigen_modes
from sidprep.fe.material import material_from_options
from sidprep.fe.mesh import read_mesh
from sidprep.jobs.options import ReduceOptions
from sidprep.jobs import parts as jp
from sidprep.jobs.held_parts import HeldParts, NotHeld
from sidprep.jobs.parts import PART_RETRIES, PartFailed, PartLost, PartsSettings, check_parts_fit, parts_reducer
from sidprep.jobs.reduce import default_interfaces, interface_from_spec, reduce
from sidprep.progress import peak_memory_mb, resident_memory_bytes, return_freed_memory
from sidprep.reduction.interfaces import interface_model
from sidprep.reduction import block_ldlt as ldlt
from sidprep.reduction import coarse_space as cs
from sidprep.reduction import component_modes as cm
from sidprep.reduction import part_tasks as pt
from sidprep.reduction import partition
from sidprep.reduction import substructured as sub

ROOT = Path(__file__).resolve().parents[1]
ROD = ROOT / "data" / "meshes" / "piston_rod.msh"
BAR = ROOT / "data" / "meshes" / "bar.msh"
#: eigen-kind frequencies in parts vs the monolithic reduction of the same model
PARTS_FREQ_RTOL = 1e-4
#: mass, centre of mass and inertia in parts vs monolithic, relative
MASS_RTOL = 1e-10
#: the substructured K_ii solve against a direct sparse solve, relative residual
SOLVE_RTOL = 1e-9
#: part sizes (cells) within this factor of the mean (METIS 3 % imbalance, contiguity may cost more)
BALANCE = 1.15


def monolithic_and_parts(mesh, n_parts, **kwargs):
    o = ReduceOptions()
    return reduce(mesh, o), reduce(mesh, ReduceOptions(parts=n_parts), **kwargs)


def assert_same_body(mono, parts, mesh):
    kinds = np.array(mono.sid.mode_kinds)
    assert list(parts.sid.mode_kinds) == list(kinds)
    f_m, f_p = mono.sid.frequencies_hz[kinds == "eigen"], parts.sid.frequencies_hz[kinds == "eigen"]
    np.testing.assert_allclose(f_p, f_m, rtol=PARTS_FREQ_RTOL)
    assert abs(parts.sid.mass / mono.sid.mass - 1) < MASS_RTOL
    scale = mono.sid.mass * np.ptp(read_mesh(mesh).points)
    assert np.abs(parts.sid.mdCM.M0 - mono.sid.mdCM.M0).max() < MASS_RTOL * scale
    assert np.abs(parts.sid.J.M0 - mono.sid.J.M0).max() < MASS_RTOL * np.abs(mono.sid.J.M0).max()
    assert parts.passed and parts.checks["zero_energy_modes"] == 6


def full_model(path):
    mesh = read_mesh(path)
    material = material_from_options(name="steel")
    interfaces = [interface_from_spec(mesh, s) for s in default_interfaces(mesh)]
    im = interface_model(mesh.n_nodes, interfaces, mesh.points)
    K, M = stiffness_and_mass(mesh, material)
    return mesh, material, im, im.project(K), im.project(M)


def test_partition_gives_connected_balanced_parts_with_few_shared_faces():
    mesh = read_mesh(ROD)
    labels = partition.partition_cells(mesh.cells, 4)
    sizes = np.bincount(labels)
    assert len(sizes) == 4 and sizes.max() <= BALANCE * sizes.mean()
    xadj, adjncy = partition.face_graph(mesh.cells)
    owner = np.repeat(np.arange(len(mesh.cells)), np.diff(xadj))
    cut = np.count_nonzero(labels[owner] != labels[adjncy]) // 2
    assert cut < 0.05 * len(adjncy) // 2                      # few faces between parts
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components
    for p in range(4):
        cells = np.flatnonzero(labels == p)
        A = sp.csr_matrix((np.ones(len(adjncy)), adjncy, xadj))[cells][:, cells]
        assert connected_components(A, directed=False)[0] == 1


def test_substructured_solve_is_exact_and_counts_the_full_models_eigenvalues():
    mesh, material, im, K, M = full_model(BAR)
    b = im.master_dofs.ravel()
    labels = partition.partition_cells(mesh.cells, 8)
    parts, coarse = partition.part_models(mesh, material, labels, im, b)
    S = cs.static_schur(parts, coarse, b, out_of_core=True)     # the solves below read S's factor from disk
    space, coarse_factor = cs.coarse_space(parts, coarse, b, S, M, n_interface=24), cs.schur_factor(S)
    assert all(isinstance(step.L, np.memmap) for step in coarse_factor.steps)
    tasks = pt.InProcess(parts)
    reductions = tasks(cm.reduce_part, [(space.part_map(k), 40) for k in range(len(parts))])
    assembly = cm.assemble_parts(reductions, space)
    solver = sub.SubstructuredSolver(parts, reductions, assembly, b, K.shape[0], coarse_factor, tasks)
    interior = np.ones(K.shape[0], bool)
    interior[b] = False
    r = np.random.default_rng(1).standard_normal((interior.sum(), 3))
    x_ref = spla.spsolve(K[interior][:, interior].tocsc(), r)
    assert np.abs(solver.solve(r) - x_ref).max() < SOLVE_RTOL * np.abs(x_ref).max()
    # the cuts are reduced (24 interface modes each), the constraint modes of b stay exact
    assert space.R.shape[1] < len(coarse)
    # each part's coordinates, counted before any task (the memory check), are those the coarse space gave it
    np.testing.assert_array_equal(cs.coordinates_per_part(parts, coarse, b, 24),
                                  [len(space.columns(p)) for p in range(len(parts))])
    psi_ref = -spla.spsolve(K[interior][:, interior].tocsc(), K[interior][:, b].toarray())
    assert np.abs(solver.constraint_modes_and_recovery(K, None)[0] - psi_ref).max() < SOLVE_RTOL * np.abs(psi_ref).max()
    # each part's K_II was factored once (by its Craig-Bampton reduction), for three solves
    assert tasks(pt.part_factorisations, [()] * len(parts)) == [1] * len(parts)
    # the count over the parts against a full-model eigen solve (free body: 6 rigid modes first)
    f = eigen_modes(K, M, count=12, backend="cholmod").frequencies_hz
    held = type("Red", (), {"held": None})()
    for k in (7, 10, 14):                                   # between full-model modes k-1 and k
        sigma = (2 * np.pi) ** 2 * f[k - 1] * f[k]
        assert solver.eigenvalue_count(held, sigma) == k


def summed_random_blocks(rng, positions, n: int, shift: float, *targets) -> np.ndarray:
    """A random symmetric block B - shift I at each of ``positions``, added to every CutBlocks of
    ``targets``; their dense sum (n, n), the reference."""
    A = np.zeros((n, n))
    for pos in positions:
        B = rng.standard_normal((len(pos), len(pos)))
        B = B + B.T - shift * np.eye(len(pos))
        A[np.ix_(pos, pos)] += B
        for blocks in targets:
            blocks.add(pos, B)
    return A


def test_the_coarse_count_by_blocks_between_cuts_is_sylvesters_count_of_the_whole_matrix():
    # a symmetric indefinite matrix on 5 groups coupled like the cuts of parts (a chain and a triple
    # junction), summed from "part" blocks; its negative eigenvalues from a dense eigen solve
    rng = np.random.default_rng(3)
    groups = [np.arange(0, 7), np.arange(7, 12), np.arange(12, 20), np.arange(20, 23), np.arange(23, 30)]
    parts = [np.r_[groups[0], groups[1]], np.r_[groups[1], groups[2], groups[3]], np.r_[groups[3], groups[4]],
             np.r_[groups[2], groups[4]]]
    for shift in (-2.0, 0.5, 3.0):
        blocks, twin = ldlt.CutBlocks(groups, 30, parts), ldlt.CutBlocks(groups, 30, parts)
        disk = ldlt.CutBlocks(groups, 30, parts, out_of_core=True)      # blocks and factor in mapped files
        streamed = ldlt.CutBlocks(groups, 30, parts, count_only=True)   # eliminated as the blocks arrive
        A = summed_random_blocks(rng, parts, 30, shift, blocks, twin, disk, streamed)
        assert len(streamed.neighbours) < len(groups)              # group 0 went once parts 0 and 1 were in
        assert blocks.planned_bytes() == sum(B.nbytes for B in blocks.blocks.values())   # the out-of-core test
        expected = int(np.sum(np.linalg.eigvalsh(A) < 0))
        assert blocks.negative_pivots() == expected
        assert streamed.negative_pivots() == expected
        with pytest.raises(ValueError, match="keeps no factor"):
            streamed.eliminate(keep=True)
        # the same elimination kept is a solver, in memory and out of core: against a dense LU solve
        b = rng.standard_normal((30, 2))
        x = twin.eliminate(keep=True).solve(b)
        np.testing.assert_allclose(x, np.linalg.solve(A, b), rtol=0, atol=1e-10 * np.abs(x).max())
        factor = disk.eliminate(keep=True)
        assert all(isinstance(step.L, np.memmap) and isinstance(step.W, np.memmap) for step in factor.steps)
        # what stays in memory is O(n) per group: D as its three bands, not a square block beside L
        assert all(step.D.shape == (3, len(step.rows)) for step in factor.steps)
        x_disk = factor.solve(b)
        np.testing.assert_allclose(x_disk, np.linalg.solve(A, b), rtol=0, atol=1e-10 * np.abs(x).max())


@settings(max_examples=200, deadline=None, derandomize=True)   # 3000 random examples passed once
@given(st.lists(st.integers(1, 5), min_size=1, max_size=6), st.integers(0, 2**32 - 1), st.floats(-3.0, 3.0))
def test_the_block_ldlt_counts_and_solves_like_dense_algebra_on_any_grouping(sizes, seed, shift):
    # groups of any sizes, "parts" holding random sets of them (every group held), symmetric blocks
    # shifted to be indefinite: Sylvester's count against a dense eigen count, the kept
    # elimination's solve against a dense LU solve (where the matrix is not near singular)
    rng = np.random.default_rng(seed)
    at = np.cumsum([0] + sizes)
    groups = [np.arange(at[k], at[k + 1]) for k in range(len(sizes))]
    n = int(at[-1])
    held = [rng.choice(len(groups), size=rng.integers(1, min(3, len(groups)) + 1), replace=False)
            for _ in range(rng.integers(1, 5))] + [[k] for k in range(len(groups))]
    positions = [np.concatenate([groups[k] for k in part]) for part in held]
    blocks, twin = ldlt.CutBlocks(groups, n, positions), ldlt.CutBlocks(groups, n, positions)
    streamed = ldlt.CutBlocks(groups, n, positions, count_only=True)   # counted as the blocks arrive
    A = summed_random_blocks(rng, positions, n, shift, blocks, twin, streamed)
    eig = np.linalg.eigvalsh(A)
    if np.abs(eig).min() < 1e-8 * np.abs(eig).max():
        return                                              # (near) singular: no count to compare
    assert blocks.negative_pivots() == int(np.sum(eig < 0))
    assert streamed.negative_pivots() == int(np.sum(eig < 0))
    b = rng.standard_normal((n, 2))
    x = twin.eliminate(keep=True).solve(b)
    x_ref = np.linalg.solve(A, b)
    assert np.abs(x - x_ref).max() <= 1e-11 * np.abs(x_ref).max() * np.abs(eig).max() / np.abs(eig).min()


def test_piston_rod_in_4_parts_on_the_local_pool_matches_the_monolithic_reduction():
    mono, parts = monolithic_and_parts(ROD, 4, workers=2)
    assert_same_body(mono, parts, ROD)
    assert parts.checks["frequency_check"].startswith("certified")
    _, _, im, K, M = full_model(ROD)
    f_full = eigen_modes(K, M, count=8, backend="cholmod").frequencies_hz[6:]
    bounds = np.array(parts.checks["frequencies_full_hz_bounds"])
    assert np.all((bounds[:, 0] <= f_full * (1 + 1e-9)) & (f_full <= bounds[:, 1] * (1 + 1e-9)))
    coarse, coordinates = coarse_note(parts, 4)
    assert coordinates < coarse                             # the cuts were reduced to interface modes


def test_bar_in_8_parts_on_a_dask_local_cluster_matches_the_monolithic_reduction(monkeypatch):
    distributed = pytest.importorskip("distributed")
    monkeypatch.setattr(cm, "INTERFACE_PER_MODE", 1.0)             # few interface modes: the cuts are reduced
    monkeypatch.setattr(cm, "INTERFACE_MIN_MODES", 12)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        mono, parts = monolithic_and_parts(BAR, 8, scheduler=client)
    assert_same_body(mono, parts, BAR)
    assert parts.checks["frequency_check"].startswith("certified")
    coarse, coordinates = coarse_note(parts, 8)
    assert coordinates < 0.5 * coarse


def test_a_dask_worker_for_parts_stops_where_dask_would_pause_it_and_gets_large_arrays_scattered():
    # a Dask worker above distributed.worker.memory.pause of its limit starts no task: with the parts it
    # holds still held it would never run the next one, so the parts' budget ends below that fraction
    distributed = pytest.importorskip("distributed")
    import dask.config

    from sidprep.jobs.executor import task_pool
    from sidprep.jobs.parts import worker_memory_bytes

    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False, memory_limit="2GB",
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        pool = task_pool(client)
        with dask.config.set({"distributed.worker.memory.pause": 0.5}):
            assert worker_memory_bytes(pool) == pytest.approx(0.5 * 2e9)
        with dask.config.set({"distributed.worker.memory.pause": False}):
            assert worker_memory_bytes(pool) == pytest.approx(0.95 * 2e9)   # the terminate fraction
        # a large array argument reaches the pinned worker scattered (not inside the task the
        # scheduler holds), a small one inline; the task sees both
        scattered = []
        scatter = client.scatter
        client.scatter = lambda data, **kw: scattered.append(data.nbytes) or scatter(data, **kw)
        big, small = np.arange(2**18, dtype=float), np.ones(3)
        slot = pool.slots[0]
        assert pool.run_on(slot, np.dot, big, big).result() == pytest.approx(big @ big)
        assert pool.run_on(slot, np.dot, small, small).result() == 3.0
        assert scattered == [big.nbytes, big.nbytes]
        pool.close()


def test_a_local_pools_workers_share_what_the_driver_leaves(monkeypatch):
    from sidprep.jobs.executor import task_pool
    from sidprep.jobs.parts import LOCAL_DRIVER_SHARE, worker_memory_bytes

    monkeypatch.setenv("SIDPREP_MEMORY_LIMIT", "10G")
    pool = task_pool(None, 2)
    try:
        assert worker_memory_bytes(pool) == pytest.approx((1 - LOCAL_DRIVER_SHARE) * 10 * 2**30 / 2)
    finally:
        pool.close()


def coarse_note(result, n_parts: int) -> tuple[int, int]:
    """(coarse DOF, coarse coordinates) from the parts note."""
    note = next(n for n in result.notes if f"reduced in {n_parts} parts" in n)
    words = note.split(" coarse DOF in ")
    return int(words[0].split()[-1]), int(words[1].split()[0])


def test_parts_short_of_modes_run_a_second_round_and_match_the_monolithic_reduction(monkeypatch):
    monkeypatch.setattr(cm, "PART_FIRST_ROUND", 0.01)      # first round: PART_MIN_MODES per part
    mono, parts = monolithic_and_parts(ROD, 4, workers=2)
    note = next(n for n in parts.notes if "reduced in 4 parts" in n)
    assert int(note.split(" part modes")[0].split()[-1]) > 4 * cm.PART_MIN_MODES   # some ran again
    assert_same_body(mono, parts, ROD)


def test_an_attached_frame_rbe3_interfaces_and_fmax_in_parts_match_the_monolithic_reduction():
    o = ReduceOptions(interfaces=("fixed_end:rbe3", "free_end:rbe3"), frame="fixed_end", fmax=1500.0)
    mono = reduce(BAR, o)
    parts = reduce(BAR, replace(o, parts=4), workers=2)
    kinds = np.array(mono.sid.mode_kinds)
    np.testing.assert_allclose(parts.sid.frequencies_hz[kinds == "eigen"], mono.sid.frequencies_hz[kinds == "eigen"],
                               rtol=PARTS_FREQ_RTOL)
    assert abs(parts.sid.mass / mono.sid.mass - 1) < MASS_RTOL
    assert parts.passed and parts.checks["zero_energy_modes"] == 0
    assert parts.checks["frequency_check"].startswith("certified")


def test_cli_reduces_in_parts_and_rejects_a_scheduler_without_parts(tmp_path):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = tmp_path / "bar.sid.h5"
    run = subprocess.run([sys.executable, "-m", "sidprep.cli.main", "reduce", str(BAR), "--parts", "4", "--workers",
                          "2", "--modes", "4", "--no-obj", "-o", str(out), "--json", "-q"],
                         capture_output=True, text=True, env=env, timeout=600)
    assert run.returncode == 0, run.stderr
    summary = json.loads(run.stdout)
    assert summary["checks"]["passed"] and out.is_file()
    bad = subprocess.run([sys.executable, "-m", "sidprep.cli.main", "reduce", str(BAR), "--scheduler", "tcp://x:1"],
                         capture_output=True, text=True, env=env, timeout=120)
    assert bad.returncode == 2 and "add --parts N" in bad.stderr and len(bad.stderr.strip().splitlines()) == 1


def pool_workers():
    """The local pool's worker processes: spawned children of this process (sidprep.jobs.executor)."""
    workers = []
    for child in psutil.Process().children():
        try:
            if "spawn_main" in " ".join(child.cmdline()):
                workers.append(child)
        except psutil.NoSuchProcess:
            pass
    return workers


def killer(stop: threading.Event, every: bool, killed: list):
    """Kill a pool worker as soon as one exists (``every``: all of them, until ``stop``)."""
    while not stop.is_set():
        for w in pool_workers():
            try:
                os.kill(w.pid, signal.SIGKILL)
                killed.append(w.pid)
            except ProcessLookupError:
                pass
            if not every:
                return
        time.sleep(0.005)


def run_with_killer(every: bool, n_parts: int):
    stop, killed = threading.Event(), []
    thread = threading.Thread(target=killer, args=(stop, every, killed), daemon=True)
    thread.start()
    try:
        return reduce(BAR, ReduceOptions(parts=n_parts, modes=4), workers=2), killed
    finally:
        stop.set()
        thread.join()


#: seconds after which a reduction whose Dask workers all died is taken as hung (it takes ~20 s)
HANG_S = 240


class Hung(BaseException):
    """The run did not end within HANG_S (raised by SIGALRM in the main thread)."""


def kill_all_dask_workers_once_busy(client, stop: threading.Event, killed: list) -> None:
    """SIGKILL every Dask worker process at once as soon as both have part tasks (the scheduler's
    ``processing``)."""
    while not stop.is_set():
        busy = [w for w, keys in client.processing().items() if any("held_task" in str(k) for k in keys)]
        if len(busy) == 2:
            for w in pool_workers():
                os.kill(w.pid, signal.SIGKILL)
                killed.append(w.pid)
            return
        time.sleep(0.01)


def test_a_dask_cluster_whose_workers_all_die_at_once_still_gives_the_same_body():
    # the nannies restart the workers at new addresses: a task pinned to a gone worker is never run by
    # Dask when no worker was left at all (found at 2.4M DOF: both 5 GB workers passed 95 % within 2 s and
    # the run waited for ever); the parts must go to the new workers
    distributed = pytest.importorskip("distributed")

    def hung(*_):
        raise Hung(f"no result {HANG_S} s after the workers died")

    stop, killed = threading.Event(), []
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        thread = threading.Thread(target=kill_all_dask_workers_once_busy, args=(client, stop, killed), daemon=True)
        thread.start()
        previous = signal.signal(signal.SIGALRM, hung)
        signal.alarm(HANG_S)
        try:
            parts = reduce(BAR, ReduceOptions(parts=4, modes=4), scheduler=client)
        finally:
            signal.alarm(0)
            signal.signal(signal.SIGALRM, previous)
            stop.set()
            thread.join()
    assert len(killed) == 2                                 # both workers died mid-run
    assert_same_body(reduce(BAR, ReduceOptions(modes=4)), parts, BAR)


def test_a_killed_worker_is_recomputed_and_gives_the_same_body():
    parts, killed = run_with_killer(every=False, n_parts=4)
    assert killed                                           # a worker did die mid-run
    mono = reduce(BAR, ReduceOptions(modes=4))
    assert_same_body(mono, parts, BAR)


def test_workers_that_keep_dying_stop_the_run_with_one_line_naming_the_part():
    with pytest.raises(PartLost, match=rf"^part \d/4: its worker was lost {PART_RETRIES + 1} times") as exc:
        run_with_killer(every=True, n_parts=4)
    assert "\n" not in str(exc.value)


DISK_LIMIT_SCRIPT = """
import resource, signal
from sidprep.errors import InputError
from sidprep.reduction.block_ldlt import disk_zeros
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)                # a file past the limit: EFBIG, not a kill
resource.setrlimit(resource.RLIMIT_FSIZE, (2**20, 2**20))    # files of at most 1 MiB: a disk that is full
disk_zeros((100, 100))[:] = 1.0                              # 80 kB: fits
try:
    disk_zeros((1000, 1000))                                 # 8 MB
except InputError as exc:
    print(exc)
"""


def test_an_out_of_core_coarse_problem_without_room_on_disk_stops_with_one_line_before_it_writes():
    # the 2.4M row's driver died of SIGBUS writing a mapped sparse file on a full disk: the room is
    # checked against the planned blocks before they are made, and each file's blocks are reserved
    n = 3_000_000                                             # one dense cut: 72 TB planned
    with pytest.raises(InputError, match=r"^coarse problem out of core: .* GB do not fit in the temporary "
                                         r"directory .*; set TMPDIR to a disk with room") as exc:
        ldlt.CutBlocks([np.arange(n)], n, [np.arange(n)], out_of_core=True)
    assert "\n" not in str(exc.value)
    run = subprocess.run([sys.executable, "-c", DISK_LIMIT_SCRIPT], capture_output=True, text=True,
                         env={**os.environ, "PYTHONPATH": str(ROOT)}, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    assert run.stdout.startswith("coarse problem out of core: 0.00745 GB do not fit") and "File too large" in run.stdout


SCHUR_PEAK_SCRIPT = """
import sys
import numpy as np
from sidprep.fe.pardiso import ldlt_inertia
K = np.load(sys.argv[1], allow_pickle=True)[()]
def high_water():
    with open("/proc/self/status") as fh:
        return 1024 * int(next(line for line in fh if line.startswith("VmHWM")).split()[1])
open("/proc/self/clear_refs", "w").write("5")              # reset the high-water mark
base = high_water()
ldlt_inertia(K, None if sys.argv[2] == "0" else np.arange(int(sys.argv[2])))
print(high_water() - base)
"""


def schur_task_peak_bytes(K, n_rows: int, tmp_path) -> float:
    """Measured peak RSS increase (bytes, VmHWM) of ldlt_inertia(K) with its dense Schur complement on
    the first n_rows rows (0: none), in a fresh process."""
    path = tmp_path / "K.npy"
    np.save(path, K, allow_pickle=True)
    run = subprocess.run([sys.executable, "-c", SCHUR_PEAK_SCRIPT, str(path), str(n_rows)], capture_output=True,
                         text=True, env={**os.environ, "PYTHONPATH": str(ROOT)}, timeout=300, check=True)
    return float(run.stdout)


def test_the_schur_tasks_dense_blocks_stay_within_the_copies_the_estimate_counts(tmp_path):
    # the measured peak RSS (an independent reference) of the sparse LDL^T with its dense Schur block,
    # over the same LDL^T without it: at most pt.SCHUR_DENSE_COPIES (nb, nb) arrays
    _, _, _, K, _ = full_model(ROD)
    nb = 3000
    extra = schur_task_peak_bytes(K, nb, tmp_path) - schur_task_peak_bytes(K, 0, tmp_path)
    assert 8.0 * nb ** 2 <= extra <= pt.SCHUR_DENSE_COPIES * 8.0 * nb ** 2


def test_a_part_larger_than_a_worker_is_refused_before_it_starts_with_the_parts_that_fit(tmp_path):
    mesh, material, im, K, M = full_model(ROD)
    b = im.master_dofs.ravel()
    parts, coarse = partition.part_models(mesh, material, partition.partition_cells(mesh.cells, 2), im, b)
    coordinates = cs.coordinates_per_part(parts, coarse, b, cm.interface_count(30))
    need = max(pt.part_peak_bytes(p, c) for p, c in zip(parts, coordinates))
    memory = 0.9 * need / MEMORY_HEADROOM
    with pytest.raises(InputError, match=r"parts = 2: part \d/2 \(\d+ of 16029 DOF\) needs .* use --parts (\d+)") as exc:
        check_parts_fit(parts, mesh.n_dof, memory, coordinates=coordinates)
    suggested = int(exc.value.args[0].split("use --parts ")[1].split()[0])
    finer, coarse = partition.part_models(mesh, material, partition.partition_cells(mesh.cells, suggested), im, b)
    check_parts_fit(finer, mesh.n_dof, memory,              # the suggestion fits
                    coordinates=cs.coordinates_per_part(finer, coarse, b, cm.interface_count(30)))
    limit = 2 * memory / (1 - jp.LOCAL_DRIVER_SHARE)        # two local workers with ``memory`` each
    env = {**os.environ, "PYTHONPATH": str(ROOT), "SIDPREP_MEMORY_LIMIT": str(int(limit))}
    run = subprocess.run([sys.executable, "-m", "sidprep.cli.main", "reduce", str(ROD), "--parts", "2", "--workers",
                          "2", "-q", "-o", str(tmp_path / "rod.sid.h5")],
                         capture_output=True, text=True, env=env, timeout=300)
    assert run.returncode == 2 and "use --parts" in run.stderr, run.stderr
    assert not list(tmp_path.iterdir())                     # nothing written


def test_a_workers_peak_is_its_own_not_the_spawning_drivers():
    import multiprocessing

    ballast = np.ones(2**27)                                # 1 GiB in this process when the worker spawns
    with multiprocessing.get_context("spawn").Pool(1) as pool:
        peak = pool.apply(peak_memory_mb)
    assert peak < 0.5 * ballast.nbytes / 2**20              # numpy + scipy + sidprep: ~100-200 MiB


def test_each_part_is_factored_once_where_it_is_held_and_a_worker_killed_after_it_held_parts_gives_the_same_solve():
    mesh, material, im, K, M = full_model(BAR)
    b = im.master_dofs.ravel()
    red = parts_reducer(mesh, material, PartsSettings(4, workers=2))(im, K, M, b, n_modes=4)
    solver, tasks = red.interior_factor, red.interior_factor.tasks
    try:
        interior = np.ones(K.shape[0], bool)
        interior[b] = False
        r = np.random.default_rng(2).standard_normal((interior.sum(), 2))
        x_ref = spla.spsolve(K[interior][:, interior].tocsc(), r)
        made = tasks(pt.part_factorisations, [()] * 4)      # by the parts' reductions (a second round: 2)
        sent = tasks.sent_mb
        for _ in range(3):                                  # later solves send right-hand sides only
            assert np.abs(solver.solve(r) - x_ref).max() < SOLVE_RTOL * np.abs(x_ref).max()
        assert tasks(pt.part_factorisations, [()] * 4) == made and tasks.sent_mb == sent
        victim = pool_workers()[0]
        victim.kill()
        victim.wait(10)
        assert np.abs(solver.solve(r) - x_ref).max() < SOLVE_RTOL * np.abs(x_ref).max()
        after = tasks(pt.part_factorisations, [()] * 4)
        again = [p for p in range(4) if after[p] != made[p]]
        assert tasks.sent_mb > sent and all(after[p] == 1 for p in again)   # re-sent, factored once more
    finally:
        tasks.close()


def test_a_worker_releases_held_parts_while_its_resident_memory_exceeds_its_budget_and_makes_one_again_unsent():
    mesh, material, im, K, M = full_model(ROD)
    parts, _ = partition.part_models(mesh, material, partition.partition_cells(mesh.cells, 3), im, im.master_dofs.ravel())
    unbounded = float("inf")
    store = HeldParts()                                     # what one worker process holds
    for p in (0, 1):
        assert store.task(("run", p), parts[p], unbounded, pt.part_factorisations) == 0
        store.task(("run", p), None, unbounded, pt.HeldPart.factor)
    gc.collect()                                            # what earlier tests left is freed before, not during
    return_freed_memory()
    before = resident_memory_bytes()
    store.task(("run", 2), parts[2], unbounded, pt.HeldPart.factor)
    return_freed_memory()
    held_2 = resident_memory_bytes() - before               # part 2's matrices and factor, measured
    held = store.parts[("run", 2)].part
    assert held_2 > sum(A.data.nbytes + A.indices.nbytes for A in (held.K, held.M))   # more than its matrices
    # with room for two parts' worth the next task releases one; in a cycle over the parts the one
    # just used is needed last: part 1 (used after part 0) goes
    budget = before + 0.5 * held_2
    store.task(("run", 2), None, budget, pt.part_factorisations)
    assert [key[1] for key, h in store.parts.items() if key[0] == "run" and h.holds] == [0, 2]
    assert resident_memory_bytes() <= budget
    # a released part's task runs without the part sent again: K_BI K_II^-1 r against a direct solve
    part = partition.assembled(parts[1])
    r = np.random.default_rng(0).standard_normal((len(part.interior), 2))
    I, B = part.interior, part.boundary
    expected = part.K[B][:, I] @ spla.spsolve(part.K[I][:, I].tocsc(), r)
    np.testing.assert_allclose(store.task(("run", 1), None, unbounded, pt.part_coarse_load, r), expected,
                               rtol=1e-9, atol=1e-9 * np.abs(expected).max())
    assert store.task(("run", 1), None, unbounded, pt.part_factorisations) == 2   # made again once
    with pytest.raises(NotHeld):                         # a worker that never held the part asks for it
        store.task(("run", 7), None, unbounded, pt.part_factorisations)
    store.release_run("run")
    assert not [key for key in store.parts if key[0] == "run"]


def test_a_task_that_fails_on_a_living_worker_stops_the_run_naming_the_part_without_retries():
    mesh, material, im, K, M = full_model(ROD)
    parts, _ = partition.part_models(mesh, material, partition.partition_cells(mesh.cells, 3), im, im.master_dofs.ravel())
    tasks = jp.PartTasks(PartsSettings(3, workers=1), parts)
    try:
        assert tasks(pt.part_factorisations, {0: ()}) == [0]
        worker = pool_workers()
        wrong = np.zeros((3, 1))                            # not the part's own DOFs: the solve raises
        with pytest.raises(PartFailed, match=r"^part 1/3: part_coarse_load failed: ValueError"):
            tasks(pt.part_coarse_load, {0: (wrong,)})
        assert pool_workers() == worker                     # the same process: nothing was lost or renewed
    finally:
        tasks.close()
