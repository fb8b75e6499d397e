"""Assemblies of components (``sidprep reduce ASSEMBLY.toml``: sidprep.jobs.assembly, sidprep.fe.joined,
sidprep.fe.ties).

Independent references: CalculiX's own element matrices of a component (ccx); the monolithic reduction of the same geometry as ONE mesh (shared joins:
frequencies within 1e-4, mass properties within 1e-10); monolithic meshes of the tied
halves' sizes and a finer one (tied joins); the closed-form mass and centre of mass of a bar of two
materials; the triangle shape functions' exact reproduction of linear fields (the ties' weights).
"""

import importlib.util
import json
import os
import shutil
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from readme_numbers import check_numbers

from sidprep.errors import InputError
from sidprep.fe.material import builtin_material
from sidprep.fe.matrices.calculix import tet_deck
from sidprep.fe.mesh import read_mesh
from sidprep.fe.ties import tie_to_faces
from sidprep.jobs.assembly import reduce_assembly
from sidprep.jobs.jobfile import read_job
from sidprep.jobs.options import ReduceOptions
from sidprep.jobs.parts import check_parts_fit
from sidprep.jobs.reduce import reduce
from sidprep.reduction.interfaces import interface_model
from sidprep.reduction.partition import part_models
from sidprep.sid.io import read_sid

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "assembly"
#: eigen-mode frequencies of a shared-node assembly vs the monolithic reduction of the same mesh
ASSEMBLY_FREQ_RTOL = 1e-4
#: mass, centre of mass and inertia vs the monolithic reduction / the closed form, relative
MASS_RTOL = 1e-10
#: a tied assembly (halves at h = 40 and 30 mm) lies between the monolithic bar at h = 20 mm (closer to
#: the converged frequencies, which conforming elements approach from above) and the stiffer of the
#: monolithic bars at its halves' sizes: the tie adds no error beyond the discretisation of its two
#: meshes.  Margin on both sides, relative; measured (first 8 modes of the example's bar): mode 2 lies
#: 4.9e-5 above the lower end and 5.4e-5 below the upper end, the other modes farther inside
TIED_MARGIN_RTOL = 1e-4
#: element size (m) of the monolithic reference of the tied assembly: half the coarser half's
TIED_REFERENCE_SIZE = 0.02
#: first root of cos(x) cosh(x) = 1 (free-free Euler-Bernoulli beam)
FREE_FREE_ROOT_1 = 4.7300407449
#: the ties' weights reproduce a linear field exactly: round-off only
TIE_LINEAR_ATOL = 1e-12


def example_meshes():
    spec = importlib.util.spec_from_file_location("make_meshes", EXAMPLE / "make_meshes.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def job_file(folder: Path, components, joins, extra: str = "", name: str = "asm.toml") -> Path:
    """An assembly job file: components [(name, mesh, material)], joins [dict of TOML values]."""
    lines = [extra]
    for comp, mesh, material in components:
        lines += ["[[component]]", f'name = "{comp}"', f'mesh = "{mesh}"'] + ([f'material = "{material}"'] if material else [])
    for join in joins:
        lines += ["[[join]]"] + [f"{k} = {json.dumps(v)}" for k, v in join.items()]
    path = folder / name
    path.write_text("\n".join(lines) + "\n")
    return path


SHARED = [{"nodes": ["left.joint", "right.joint"]}]
HALVES = [("left", "left.msh", None), ("right", "right.msh", None)]


@pytest.fixture(scope="module")
def meshes(tmp_path_factory):
    """The example's meshes written afresh (make_meshes.py), plus the monolithic bar at the tied right half's size."""
    folder = tmp_path_factory.mktemp("assembly")
    make = example_meshes()
    make.shared_halves(folder)
    make.tied_halves(folder)
    for name, size in (("fine", make.TIED_SIZES[1]), ("reference", TIED_REFERENCE_SIZE)):
        (folder / name).mkdir()
        make.shared_halves(folder / name, size=size)
    return folder


def eigen(result) -> np.ndarray:
    kinds = np.array(result.sid.mode_kinds)
    return result.sid.frequencies_hz[kinds == "eigen"]


def assert_same_mass_properties(a, b) -> None:
    assert abs(a.sid.mass / b.sid.mass - 1) < MASS_RTOL
    assert np.abs(a.sid.mdCM.M0 - b.sid.mdCM.M0).max() < MASS_RTOL * b.sid.mass
    assert np.abs(a.sid.J.M0 - b.sid.J.M0).max() < MASS_RTOL * np.abs(b.sid.J.M0).max()


def test_tie_weights_reproduce_linear_fields_and_measure_the_gap():
    rng = np.random.default_rng(3)
    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0.5, 0, 0], [0.5, 0.5, 0], [0, 0.5, 0]], float)
    faces = np.array([[0, 1, 2, 3, 4, 5]])
    l = rng.dirichlet(np.ones(3), size=20)
    gap = rng.uniform(0, 1e-3, size=20)
    slaves = np.vstack([points, l @ points[:3] + gap[:, None] * [0, 0, 1]])
    ties, measured = tie_to_faces(slaves, np.arange(6, 26), faces)
    A = rng.standard_normal((3, 3))
    field = slaves[:, :2] @ A[:2] + A[2]                       # a linear field of the in-plane position
    interpolated = np.einsum("km,kmj->kj", ties.weights, field[ties.masters])
    assert np.abs(interpolated - field[6:]).max() < TIE_LINEAR_ATOL
    np.testing.assert_allclose(measured, gap, atol=TIE_LINEAR_ATOL)


def test_shared_halves_on_the_local_pool_give_the_monolithic_bar(meshes):
    mono = reduce(meshes / "bar.msh", ReduceOptions())
    asm = reduce_assembly(read_job(job_file(meshes, HALVES, SHARED)), workers=2)
    assert list(asm.sid.mode_kinds) == list(mono.sid.mode_kinds)
    np.testing.assert_allclose(eigen(asm), eigen(mono), rtol=ASSEMBLY_FREQ_RTOL)
    assert_same_mass_properties(asm, mono)
    assert asm.passed and asm.checks["zero_energy_modes"] == 6
    assert asm.checks["frequency_check"].startswith("certified")
    assert [i["name"] for i in asm.sid.metadata["interfaces"]] == ["left.fixed_end", "right.free_end"]  # not the joint
    assert any("reduced in 2 components" in n for n in asm.notes)


def test_shared_halves_on_a_dask_local_cluster_give_the_monolithic_bar(meshes):
    distributed = pytest.importorskip("distributed")
    mono = reduce(meshes / "bar.msh", ReduceOptions(modes=4))
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        asm = reduce_assembly(read_job(job_file(meshes, HALVES, SHARED, "modes = 4")), scheduler=client)
    np.testing.assert_allclose(eigen(asm), eigen(mono), rtol=ASSEMBLY_FREQ_RTOL)
    assert_same_mass_properties(asm, mono)
    assert asm.passed


def test_tied_halves_lie_between_a_finer_mesh_and_the_stiffer_of_their_meshes(meshes):
    coarse, fine, reference = (reduce(path, ReduceOptions()) for path in
                               (meshes / "bar.msh", meshes / "fine" / "bar.msh", meshes / "reference" / "bar.msh"))
    tied = reduce_assembly(read_job(job_file(meshes, [("left", "tied_left.msh", None), ("right", "tied_right.msh", None)],
                                             [{"tied": "right.joint", "to": "left.joint"}])), workers=2)
    f, lo, hi = eigen(tied), eigen(reference), np.maximum(eigen(coarse), eigen(fine))
    assert np.all((f >= lo * (1 - TIED_MARGIN_RTOL)) & (f <= hi * (1 + TIED_MARGIN_RTOL))), (f, lo, hi)
    assert_same_mass_properties(tied, coarse)                # the same straight-sided geometry
    assert tied.passed and tied.checks["zero_energy_modes"] == 6     # the tie carries rigid motions exactly
    centroids = tied.sid.surface.points[tied.sid.surface.triangles].mean(axis=1)
    on_box = np.isclose(centroids, 0.0) | np.isclose(centroids, example_meshes().BOX)
    assert on_box.any(axis=1).all()                           # the joint's faces are not on the surface


def test_components_of_two_materials_have_the_closed_form_mass(meshes):
    asm = reduce_assembly(read_job(job_file(meshes, [("left", "left.msh", "steel"), ("right", "right.msh", "aluminium")],
                                            SHARED, "modes = 4")), workers=2)
    (L, b, h), x = example_meshes().BOX, example_meshes().JOINT_X
    m = [builtin_material(name).rho * x * b * h for name in ("steel", "aluminium")]
    assert abs(asm.sid.mass / sum(m) - 1) < MASS_RTOL
    cm = (m[0] * x / 2 + m[1] * (x + L) / 2) / sum(m)
    assert abs(asm.sid.mdCM.M0[0, 0] / asm.sid.mass - cm) < MASS_RTOL * L
    assert asm.passed
    assert [d["name"] for d in asm.sid.metadata["material"]] == ["steel", "aluminium"]


@pytest.mark.parametrize("components, joins, match", [
    ([("left", "nope.msh", None), ("right", "right.msh", None)], SHARED, r"\[\[component\]\] left: mesh nope.msh not found"),
    (HALVES, [{"nodes": ["left.fixed_end", "right.free_end"]}], r"matches no nodes"),
    ([("left", "tied_left.msh", None), ("right", "tied_right.msh", None)], SHARED,
     r"\d+ of the \d+ nodes of the \w+ set have no node of the other within tol = .* use a tied join"),
    (HALVES + [("extra", "left.msh", None)], SHARED, r"component\(s\) extra joined to nothing that reaches left"),
    (HALVES, [{"nodes": ["left.joint", "right.nope"]}], r"component right has no such node set; valid: right\."),
    (HALVES, [{"tied": "right.joint", "to": "left.fixed_end"}], r"matches no nodes: the tied nodes are 0.5 m"),
    (HALVES, [{"nodes": ["left.joint", "left.fixed_end"]}], r"both node sets belong to component left"),
    (HALVES, [{"nodes": ["left.joint", "right.joint"], "tied": "right.joint"}], r"not both or neither"),
])
def test_bad_assemblies_are_refused_with_one_line_before_any_solve(meshes, components, joins, match):
    with pytest.raises(InputError, match=match) as exc:
        reduce_assembly(read_job(job_file(meshes, components, joins)), workers=1)
    assert "\n" not in str(exc.value)


def test_cli_reduces_the_example_as_its_readme_says_and_exits_2_on_a_bad_assembly(tmp_path, meshes):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = tmp_path / "bar.sid.h5"
    run = subprocess.run([sys.executable, "-m", "sidprep.cli.main", "reduce", str(EXAMPLE / "assembly.toml"),
                          "--workers", "2", "--no-obj", "-o", str(out), "--json", "-q"],
                         capture_output=True, text=True, env=env, timeout=600)
    assert run.returncode == 0, run.stderr
    assert json.loads(run.stdout)["checks"]["passed"]
    shared = read_sid(out)
    mono = reduce(EXAMPLE / "bar.msh", ReduceOptions(modes=6, cutoff_factor=13, interfaces=("fixed_end", "free_end")))
    tied = reduce_assembly(read_job(EXAMPLE / "tied.toml"), workers=2)
    kinds = np.array(shared.mode_kinds) == "eigen"
    L, b, h = example_meshes().BOX
    steel = builtin_material("steel")
    euler_bernoulli = FREE_FREE_ROOT_1 ** 2 / (2 * np.pi * L ** 2) * np.sqrt(steel.E * b ** 2 / (12 * steel.rho))
    check_numbers(EXAMPLE / "README.md", "assembly", [
        *shared.frequencies_hz[kinds], *eigen(mono), *eigen(tied),
        np.abs(shared.frequencies_hz[kinds] / eigen(mono) - 1).max(), ASSEMBLY_FREQ_RTOL,
        np.abs(eigen(tied) / eigen(mono) - 1).max(), euler_bernoulli])
    assert np.abs(shared.frequencies_hz[kinds] / eigen(mono) - 1).max() < ASSEMBLY_FREQ_RTOL
    bad = job_file(tmp_path, [("left", str(meshes / "left.msh"), None), ("right", str(meshes / "right.msh"), None)],
                   [{"nodes": ["left.fixed_end", "right.free_end"]}])
    run = subprocess.run([sys.executable, "-m", "sidprep.cli.main", "reduce", str(bad), "-q", "-o",
                          str(tmp_path / "bad.sid.h5")], capture_output=True, text=True, env=env, timeout=120)
    assert run.returncode == 2 and "matches no nodes" in run.stderr and len(run.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "bad.sid.h5").exists()


#: a component from CalculiX's own C3D10 matrices vs the same mesh assembled by sidprep: mass to
#: 1e-8 (ccx's 13-digit files); frequencies to 1e-4 (CalculiX's C3D10 mass quadrature differs from the
#: exact one by ~3e-5: tests/test_import_calculix.py)
CCX_MASS_RTOL = 1e-8
CCX_FREQUENCY_RTOL = 1e-4


@pytest.mark.skipif(shutil.which("ccx") is None, reason="CalculiX (ccx) is not installed: apt-get install calculix-ccx")
def test_a_component_from_calculix_matrices_gives_the_assembly_of_its_mesh(meshes, tmp_path):
    deck = tmp_path / "right.inp"
    tet_deck(read_mesh(meshes / "right.msh"), deck, builtin_material("steel"))
    env = {**os.environ, "OMP_NUM_THREADS": "1", "CCX_NPROC_STIFFNESS": "1", "CCX_NPROC_EQUATION_SOLVER": "1"}
    done = subprocess.run(["ccx", deck.stem], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0 and "*ERROR" not in done.stdout, done.stdout[-2000:]
    (tmp_path / "left.msh").write_bytes((meshes / "left.msh").read_bytes())
    own = reduce_assembly(read_job(job_file(meshes, HALVES, SHARED, "modes = 4")), workers=2)
    job = job_file(tmp_path, HALVES, SHARED, "modes = 4").read_text().replace(
        'mesh = "right.msh"', 'mesh = "right.inp"\nmatrices = "right.sti"')
    (tmp_path / "ccx.toml").write_text(job)
    ccx = reduce_assembly(read_job(tmp_path / "ccx.toml"), workers=2)
    assert abs(ccx.sid.mass / own.sid.mass - 1) < CCX_MASS_RTOL
    np.testing.assert_allclose(eigen(ccx), eigen(own), rtol=CCX_FREQUENCY_RTOL)
    assert ccx.passed and any("right: stiffness and mass: " in n for n in ccx.notes)
    assert ccx.sid.metadata["material"][1]["name"].startswith("none: K and M from")


def test_parts_and_matrices_of_a_single_mesh_do_not_apply_to_an_assembly(meshes):
    path = job_file(meshes, HALVES, SHARED, "parts = 2", name="parts.toml")
    with pytest.raises(InputError, match=r"parts = \.\.\. does not apply to an assembly"):
        read_job(path)
    job = read_job(job_file(meshes, HALVES, SHARED))
    for options in (ReduceOptions(parts=2), ReduceOptions(matrices="k.sti")):
        with pytest.raises(InputError, match=r"does not apply to an assembly"):
            reduce_assembly(replace(job, options=options))


def test_a_component_that_does_not_fit_a_worker_is_named_before_it_starts():
    mesh = read_mesh(EXAMPLE / "bar.msh")
    im = interface_model(mesh.n_nodes, [], mesh.points)
    labels = (mesh.points[mesh.cells[:, :4]].mean(axis=1)[:, 0] > example_meshes().JOINT_X).astype(np.int64)
    parts, _ = part_models(mesh, builtin_material("steel"), labels, im, np.zeros(0, np.int64), ["left", "right"])
    with pytest.raises(InputError, match=r"^components = 2: (left|right) \(\d+ of 4323 DOF\) needs ~.* GB, a worker has "
                                         r"0.00 GB; split it into smaller components"):
        check_parts_fit(parts, mesh.n_dof, 1e3, components=True)
