"""The memory estimate before a run (sidprep.fe.linalg.estimate_peak_memory) against peaks measured in a
fresh process, and the automatic backend choice / refusal it drives."""

import json
import os
import subprocess
import sys
from pathlib import Path

import meshio
import numpy as np
import pytest
from skfem import MeshTet

from sidprep.fe.assemble import stiffness_and_mass
from sidprep.errors import InputError
from sidprep.fe.linalg import (MemoryEstimate, available_memory_bytes, choose_backend, clamp_dofs, eigen_modes,
                            estimate_peak_memory, node_dofs)
from sidprep.progress import Phases
from test_assemble import MAT, femesh

#: the issue's acceptance: estimate within 30 % of the measured peak
ESTIMATE_RTOL = 0.30
ROOT = Path(__file__).resolve().parents[1]

#: child process: what `sidprep reduce` does up to the modes, on a tet10 mesh file (read_mesh, assembly,
#: clamp at x = 0, 10 modes by the direct path); prints n, nnz, extent and its peak RSS (VmHWM, bytes:
#: unlike ru_maxrss it starts afresh at exec, where ru_maxrss keeps the high-water mark of the forking
#: pytest process).  The mesh is built in the test process: the child holds no mesh generator's garbage
#: (scikit-fem's basis and an edge dict left ~270 MB of freed-but-kept arenas in a 45k-DOF cube, which
#: no real run has and which put the measured peak at the tolerance's edge)
PROBE = """
import json, sys
import numpy as np
sys.path.insert(0, 'tests')
from test_assemble import MAT
from sidprep.fe.assemble import stiffness_and_mass
from sidprep.fe.linalg import clamp_dofs, eigen_modes, node_dofs
from sidprep.fe.mesh import read_mesh
mesh = read_mesh({path!r})
K, M = stiffness_and_mass(mesh, MAT)
r = clamp_dofs(mesh.n_dof, node_dofs(np.flatnonzero(mesh.points[:, 0] < 1e-9)))
K, M = r.restrict(K), r.restrict(M)
res = eigen_modes(K, M, count=10, backend='cholmod')
hwm = [line for line in open('/proc/self/status') if line.startswith('VmHWM:')][0]
print(json.dumps({{"n": K.shape[0], "nnz": K.nnz, "extent": np.ptp(mesh.points, axis=0).tolist(),
                   "peak": int(hwm.split()[1]) * 1024}}))
"""


#: the probe's environment: none of what earlier tests or libraries left in this process's
#: environment (threading and allocator settings change a process's peak)
PROBE_ENV = {"PATH": os.environ.get("PATH", ""), "HOME": os.environ.get("HOME", "/tmp"), "PYTHONPATH": str(ROOT),
             "OMP_NUM_THREADS": "1"}


@pytest.mark.parametrize("box", [(1.0, 0.05, 0.08, 60, 3, 4), (0.2, 0.2, 0.2, 12, 12, 12)], ids=["bar", "cube"])
def test_estimate_within_30_percent_of_the_measured_peak(box, tmp_path):
    a, b, c, nx, ny, nz = box
    mesh = femesh(MeshTet.init_tensor(np.linspace(0, a, nx + 1), np.linspace(0, b, ny + 1), np.linspace(0, c, nz + 1)), 2)[0]
    path = tmp_path / "box.msh"
    meshio.write(path, meshio.Mesh(mesh.points, [("tetra10", mesh.cells)]), file_format="gmsh22", binary=True)
    proc = subprocess.run([sys.executable, "-c", PROBE.format(path=str(path))], capture_output=True, text=True,
                          cwd=ROOT, env=PROBE_ENV, check=True)
    run = json.loads(proc.stdout.strip().splitlines()[-1])
    est = estimate_peak_memory(run["n"], run["nnz"], run["extent"], n_modes=10)
    assert abs(est.direct_peak_bytes - run["peak"]) / run["peak"] < ESTIMATE_RTOL, (est, run)


def test_the_fill_follows_the_shape():
    """Same DOF count: a compact cube fills its factor far more than a slender bar (separators
    ~ n^(2/3) nodes against a fixed cross-section), and the fill grows faster than n."""
    cube = estimate_peak_memory(300_000, extent=(1, 1, 1))
    bar = estimate_peak_memory(300_000, extent=(1, 0.05, 0.08))
    assert cube.factor_bytes > 1.5 * bar.factor_bytes
    big = estimate_peak_memory(600_000, extent=(1, 1, 1))
    assert big.factor_bytes > 2.3 * cube.factor_bytes         # ~ n^(4/3) for a compact body
    assert big.iterative_peak_bytes < big.direct_peak_bytes


def test_backend_choice_and_refusal():
    est = MemoryEstimate(n_dof=10**6, nnz=75 * 10**6, factor_bytes=8e9, direct_peak_bytes=12e9,
                         iterative_peak_bytes=6e9)
    assert choose_backend(est, available=20e9) in ("cholmod", "superlu")
    assert choose_backend(est, available=10e9) == "lobpcg"
    with pytest.raises(InputError, match="--backend lobpcg") as err:
        choose_backend(est, available=4e9)
    assert "\n" not in str(err.value)


def test_auto_backend_switches_to_amg_lobpcg_under_a_small_memory_limit(capsys, monkeypatch):
    """The choice wired into eigen_modes: a model whose (pretended) direct peak exceeds the limit
    goes to AMG-LOBPCG and gets the direct path's eigenvalues; a limit below both is refused."""
    import sidprep.fe.linalg as la

    mesh = femesh(__import__("test_assemble").skfem_box(n=3), 2)[0]
    K, M = stiffness_and_mass(mesh, MAT)
    r = clamp_dofs(mesh.n_dof, node_dofs(np.flatnonzero(mesh.points[:, 0] < 1e-9)))
    K, M = r.restrict(K), r.restrict(M)
    direct = eigen_modes(K, M, count=4, extent=(1, 1, 1), memory_limit=1e12, phases=Phases())
    monkeypatch.setattr(la, "estimate_peak_memory", lambda *a, **k: MemoryEstimate(
        K.shape[0], K.nnz, factor_bytes=8e9, direct_peak_bytes=12e9, iterative_peak_bytes=6e9))
    amg = eigen_modes(K, M, count=4, extent=(1, 1, 1), memory_limit=10e9, phases=Phases())
    assert direct.backend == "cholmod" and amg.backend == "lobpcg"
    assert np.allclose(amg.eigenvalues, direct.eigenvalues, rtol=1e-6)
    err = capsys.readouterr().err
    assert "memory estimate" in err and "backend lobpcg" in err and "backend cholmod" in err
    with pytest.raises(InputError, match="too large"):
        eigen_modes(K, M, count=4, memory_limit=4e9)


def test_memory_limit_from_the_environment(monkeypatch):
    monkeypatch.setenv("SIDPREP_MEMORY_LIMIT", "2G")
    assert available_memory_bytes() == 2 * 1024.0 ** 3
    monkeypatch.setenv("SIDPREP_MEMORY_LIMIT", "lots")
    with pytest.raises(InputError, match="SIDPREP_MEMORY_LIMIT"):
        available_memory_bytes()
    monkeypatch.delenv("SIDPREP_MEMORY_LIMIT")
    assert 0 < available_memory_bytes()


def test_reduction_refused_before_the_work_when_it_cannot_fit():
    from sidprep.reduction.craig_bampton import craig_bampton

    mesh = femesh(__import__("test_assemble").skfem_box(n=2), 2)[0]
    K, M = stiffness_and_mass(mesh, MAT)
    boundary = node_dofs(np.flatnonzero(mesh.points[:, 0] < 1e-9))
    with pytest.raises(InputError, match="SIDPREP_MEMORY_LIMIT") as err:
        craig_bampton(K, M, boundary, n_modes=4, memory_limit=50e6)
    assert "\n" not in str(err.value)
    assert craig_bampton(K, M, boundary, n_modes=4, memory_limit=1e12).basis.shape[1] == len(boundary) + 4
