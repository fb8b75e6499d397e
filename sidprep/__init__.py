"""sidprep: tetrahedral FE models to reduced flexible bodies (SID, Wallrapp 1994).

Data flows one way: mesh -> model -> reduction -> SID -> files.  Importing this package is cheap:
the functions below import the FE modules (mesh, assemble, linalg, reduce, ...) when called.
`sidprep.sid.model` and `sidprep.sid.io` depend on numpy and h5py only, so the solver can read SID files
without pulling in the FE side.

The solver and the command line are the subpackages ``sidprep.solver`` and ``sidprep.cli``.

Python API (all lengths m, masses kg, times s, frequencies Hz)::

    read_mesh(path, size=None, order=2, units="si") -> FEMesh
    modal_analysis(mesh_or_path, ModalOptions(...)) -> ModalResult
    reduce_model(mesh_or_path, ReduceOptions(...)) -> ReductionResult (.sid, .checks, .notes)
    reduce_assembly(read_job("assembly.toml")) -> ReductionResult   (components joined: docs/scale.md)
    read_sid(path) -> SID;  write_sid(sid, path)           (.sid.h5, .SID_FEM, .obj by suffix)
    sid_info(path) -> dict  (mass, CM, inertia, modes, nodes, model checks {name: Check}: ``sidprep info``)
    check_sid(path) -> {name: Check}                       (the model checks re-run: ``sidprep check``)
    run_batch(jobs, BatchOptions(...)) -> BatchReport
    beam(BeamOptions(...)) -> SID                           (analytical Euler-Bernoulli beam)
    load_scene(path) -> Scene;  simulate(scene) -> Result  (the solver: docs/scenes.md)
    simulate_scene(path, output=None, plot=..., csv=...) -> SceneRun   (what ``sidprep simulate`` runs)
    linearize_scene(path) -> SceneModes  (eigenmodes of the mechanism at its start: ``sidprep linearize``)
    plot_results(results, signals, output) -> ResultsPlot   (signals of a results file: ``sidprep plot``)
    recover_stress(results, body=None, at=None) -> StressRecovery (hot spots, envelope, histories, Pa)
"""

from __future__ import annotations

__version__ = "0.1.0"

__all__ = ["__version__", "read_mesh", "modal_analysis", "reduce_model", "reduce", "read_sid", "write_sid",
           "sid_info", "check_sid", "run_batch", "beam", "load_scene", "simulate", "simulate_scene", "linearize_scene",
           "plot_results", "recover_stress",
           "ModalOptions", "ReduceOptions", "OutputOptions", "BatchOptions", "BeamOptions", "Job",
           "read_job", "reduce_assembly"]

#: names resolved on first use (module, attribute): keeps ``import sidprep`` and ``sidprep --help`` fast
_LAZY = {
    "ModalOptions": ("sidprep.jobs.options", "ModalOptions"),
    "ReduceOptions": ("sidprep.jobs.options", "ReduceOptions"),
    "OutputOptions": ("sidprep.jobs.options", "OutputOptions"),
    "BatchOptions": ("sidprep.jobs.batch", "BatchOptions"),
    "Job": ("sidprep.jobs.jobfile", "Job"),
    "read_job": ("sidprep.jobs.jobfile", "read_job"),                 # job file (one mesh or an assembly) -> Job
    "reduce_assembly": ("sidprep.jobs.assembly", "reduce_assembly"),  # assembly Job -> ReductionResult
    "sid_info": ("sidprep.sid.summary", "sid_info"),
    "check_sid": ("sidprep.sid.summary", "check_sid"),
    "BeamOptions": ("sidprep.reduction.beam", "BeamOptions"),
    "beam": ("sidprep.reduction.beam", "beam_sid"),                   # BeamOptions -> SID (analytical beam)
    "load_scene": ("sidprep.solver.scene", "load_scene"),   # scene TOML -> Scene (system, settings)
    "simulate": ("sidprep.solver.scene", "simulate"),       # Scene -> solver Result
    "simulate_scene": ("sidprep.solver.simulate_scene", "simulate_scene"),   # scene file -> SceneRun + files
    "linearize_scene": ("sidprep.solver.scene_modes", "linearize_scene"),    # scene file -> SceneModes
    "plot_results": ("sidprep.solver.results", "plot_results"),              # results file -> PNG
    "recover_stress": ("sidprep.solver.stress", "recover_stress"),  # results file -> StressRecovery
}


def __getattr__(name):
    import importlib

    from sidprep.lazy import submodule

    if name in _LAZY:
        module, attr = _LAZY[name]
        return getattr(importlib.import_module(module), attr)
    return submodule("sidprep", name)      # the subpackages on first use: ``sidprep.jobs.batch.read_study``


def read_mesh(path, *, size: float | None = None, order: int = 2, units: str = "si"):
    """Read a tetrahedral mesh (.msh .inp .bdf .vtu ...) or mesh a geometry file (.geo .step .brep).

    Parameters
    ----------
    path : str or Path
    size : float, optional
        Element size of a geometry file, in the file's length unit.
    order : int
        1 (tet4) or 2 (tet10) for geometry files.
    units : str
        "si" or "mm-t-s": the unit system of the file's coordinates; the mesh returned is in metres.

    Returns
    -------
    sidprep.fe.mesh.FEMesh
        points (n, 3) m, cells (e, 4|10), node sets, notes.
    """
    from sidprep.fe.material import unit_system
    from sidprep.fe.mesh import read_mesh as _read

    u = unit_system(units)
    return _read(path, size=size, order=order).in_metres(u.length_to_m, u.name)


def modal_analysis(mesh, options=None, *, phases=None):
    """Natural frequencies and modes of a tetrahedral FE model (free-free or clamped node sets).

    Parameters
    ----------
    mesh : FEMesh or path
    options : sidprep.ModalOptions, optional
        count (elastic modes, default 10) or fmax (Hz); clamp node sets; material (default steel); backend.
    phases : sidprep.progress.Phases, optional
        Progress lines on stderr and per-phase timings (default silent).

    Returns
    -------
    sidprep.jobs.modal.ModalResult
        frequencies_hz (n,) Hz, rigid modes first; modes (n_free_dof, n) mass-normalised (1/sqrt(kg));
        residuals (n,); n_rigid; mass_kg; timings_s (s per phase); notes.
    """
    from sidprep.jobs.modal import modal_analysis as _modal
    from sidprep.jobs.options import ModalOptions

    return _modal(mesh, options or ModalOptions(), phases=phases)


def reduce_model(mesh, options=None, *, phases=None):
    """Reduce a tetrahedral FE model to a flexible body: an in-memory SID with its checks.

    No printing, no files (write them with ``write_sid``).

    Parameters
    ----------
    mesh : FEMesh or path
    options : sidprep.ReduceOptions, optional
        Material, interfaces, frame, modes (default 8) or fmax (Hz), FRMs, cut-off factor (5),
        damping ratio (0.02), stiffening, checks.
    phases : sidprep.progress.Phases, optional

    Returns
    -------
    sidprep.jobs.reduce.ReductionResult
        sid (SI units), checks (dict; ``passed``), notes, n_dof, timings_s (s), peak_memory_mb (MiB).
    """
    from sidprep.jobs.reduce import reduce as _reduce
    from sidprep.jobs.options import ReduceOptions

    return _reduce(mesh, options or ReduceOptions(), phases=phases)


def read_sid(path):
    """Read a SID file by its ending: .sid.h5 / .h5 / .hdf5 or .SID_FEM; returns sidprep.sid.model.SID (SI)."""
    from sidprep.sid.io import read_sid as _read

    return _read(path)


def write_sid(sid, path, *, comment: str = ""):
    """Write a SID by the file ending: .sid.h5 (HDF5), .SID_FEM (ASCII), .obj (its surface); atomic.
    Returns the Path written."""
    from sidprep.sid.io import write_sid as _write

    return _write(sid, path, comment=comment)


def run_batch(jobs, options=None, *, progress=None):
    """Run many reduction jobs (process pool or Dask cluster, content-addressed cache); see sidprep.jobs.batch."""
    from sidprep.jobs.batch import BatchOptions, run_batch as _run

    return _run(jobs, options or BatchOptions(), progress=progress)


def reduce(mesh, options=None, *, phases=None):
    """The same as ``reduce_model`` (the CLI's ``sidprep reduce`` without files)."""
    return reduce_model(mesh, options, phases=phases)
