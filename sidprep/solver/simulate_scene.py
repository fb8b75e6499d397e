"""One run of a scene file, end to end: load it, simulate it, write the results file and the
companion files the scene's [output] or the caller asks for (PNG plot, CSV of the signals,
ParaView animation).  ``sidprep simulate`` is this call plus printing; a script calls the same::

    run = simulate_scene("examples/flexible_pendulum/scene.toml", "out/pendulum.results.h5")
    run.result.energy["total"], run.files["results"], run.summary()

Outputs are named after the scene (``Scene.name``: its ``[scene] name``, else the folder of a
``scene.toml``, else the file's stem): ``./<name>.results.h5``, and beside it ``<name>.png``,
``<name>.csv``, ``<name>.pvd`` + ``<name>_vtu/``.  Replacing a results file that another scene
wrote is reported in ``SceneRun.notes``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import h5py

from sidprep.errors import InputError, SimulationFailed
from sidprep.progress import Phases, SimulationProgress
from sidprep.solver.results import (Result, energy_summary, plot_signals, signal_names, write_csv,
                                    write_results)
from sidprep.solver.scene import Scene, empty_result, load_scene, simulate

#: signals plotted / exported when the scene's [output] names none
DEFAULT_SIGNALS = ("energy.kinetic", "energy.total")
#: the ending of a results file (its stem names the companion files)
RESULTS_SUFFIX = ".results.h5"


@dataclass(frozen=True)
class SceneRun:
    """A finished run: the parsed scene, the solver's Result (SI units), the files written
    ({"results", "plot", "csv", "animation"}: Path) and notes (e.g. a file of another scene replaced)."""

    scene: Scene
    result: Result
    files: dict = field(default_factory=dict)
    notes: tuple[str, ...] = ()

    def summary(self) -> dict:
        """The JSON summary of the run (docs/scenes.md, "Output"): steps, CPU s, energy (J),
        effects, final body states, largest constraint error, statistics, files."""
        result, stats = self.result, self.result.stats
        balance = {} if stats.energy_balance is None else asdict(stats.energy_balance)
        return {
            "scene": str(self.scene.path),
            "t_end": float(result.t[-1]),
            "steps": int(stats.steps),
            "cpu_s": float(stats.cpu_time),
            "energy": {**energy_summary(result), **{k: balance[k] for k in ("balance_error", "tolerance", "warning")
                                                     if k in balance}},
            "effects": effects_summary(result.effects),
            "bodies": {name: {"position": b.position[-1].tolist(), "rotation": b.rotation[-1].tolist(),
                              "q": b.q[-1].tolist()} for name, b in result.bodies.items()},
            "max_constraint_error": float(result.constraint_error.max()) if len(result.constraint_error) else 0.0,
            "stats": stats.as_dict(),
            "outputs": {kind: str(path) for kind, path in self.files.items()},
        }


def effects_summary(report) -> dict:
    """{"included": {body: [...]}, "left_out": {body: [...]}, "not_in_sid": {...}, "estimates": {body:
    {effect: {"value", "measure"}}}, "warnings": [...]}."""
    out = {"included": {}, "left_out": {}, "not_in_sid": {}, "estimates": report.estimates(),
           "warnings": list(report.warnings)}
    for body, entries in report.bodies.items():
        out["included"][body] = [e.effect for e in entries if e.included]
        out["left_out"][body] = [e.effect for e in entries if not e.included and e.available]
        out["not_in_sid"][body] = [e.effect for e in entries if not e.available]
    return out


def results_path(scene: Scene, output=None) -> Path:
    """``output`` when given, else ``./<scene name>.results.h5`` in the current folder."""
    return Path(output) if output else Path(scene.name + RESULTS_SUFFIX)


def companion(results: Path, suffix: str) -> Path:
    """The file beside ``results`` sharing its stem: run.results.h5 + ".png" -> run.png."""
    name = results.name
    base = name[:-len(RESULTS_SUFFIX)] if name.endswith(RESULTS_SUFFIX) else name.removesuffix(".h5")
    return results.with_name(base + suffix)


def replaced_note(results: Path, scene: Scene) -> str | None:
    """A note when ``results`` exists and was written from another scene file (or is no results file)."""
    if not results.exists():
        return None
    try:
        with h5py.File(results, "r") as f:
            source = f["scene"].attrs.get("path") if "scene" in f else None
    except OSError:
        source = None
    if source is None:
        return f"{results}: replaced a file that was not a results file"
    if Path(str(source)).resolve() != Path(scene.path).resolve():
        return f"{results}: replaced the results of {source} (another scene; name the output with -o)"
    return None


def animation_surfaces(scene: Scene) -> dict:
    """{body name: Surface} of every body that has a shape (flexible: SID surface; rigid: OBJ)."""
    from sidprep.sid.io.obj import read_obj  # deferred: only an animation needs the surfaces
    from sidprep.sid.surface import rigid_surface, sid_surface  # deferred: as above

    surfaces = {}
    for b in getattr(scene.system, "bodies", ()):          # absolute-nodal beams carry no surface
        src = scene.sources[b.name]
        if src.kind in ("flexible", "beam"):
            surfaces[b.name] = sid_surface(b.sid)
        elif src.source:
            surfaces[b.name] = rigid_surface(*read_obj(src.source), src.source)
    return surfaces


def scene_signals(path) -> list[str]:
    """The signal names of a scene (for its [output] signals and ``sidprep plot``), without simulating."""
    return signal_names(empty_result(load_scene(path).system))


def simulate_scene(path, output=None, *, t_end: float | None = None, plot: bool = False, csv: bool = False,
                   animate: bool = False, verbose: bool = False, **overrides) -> SceneRun:
    """Load the scene file ``path``, simulate it and write its files.

    Parameters
    ----------
    path : scene file (.toml, docs/scenes.md).
    output : results file (default ``./<scene name>.results.h5``); the plot, CSV and animation go
        beside it with its stem.
    t_end : s, overrides [solver] t_end.
    plot, csv, animate : write the PNG / CSV of the [output] signals / the ParaView series, also
        when the scene's [output] does not ask for them.
    verbose : progress lines on stderr (phases, simulated time).
    overrides : SolverSettings fields by name (h, method, rtol, output_dt; None keeps the scene's).

    Returns
    -------
    SceneRun
        On a failed simulation the motion up to the failure is written to ``<stem>.failed.h5`` and
        an InputError names it (the results file is not written).
    """
    phases = Phases(verbose=verbose)
    with phases("scene", str(path)):
        scene = load_scene(path, t_end=t_end)
    out = results_path(scene, output)
    notes = tuple(n for n in (replaced_note(out, scene),) if n)
    animate = animate or scene.output.animate
    surfaces = animation_surfaces(scene) if animate else {}          # its OBJ files read before the run
    settings = replace(scene.settings, **{k: v for k, v in overrides.items() if v is not None})
    with phases("simulate", f"0 .. {scene.t_end:g} s, {settings.method}, step {settings.h:g} s"):
        try:
            with SimulationProgress(scene.t_end, enabled=verbose) as progress:
                result = simulate(scene, replace(settings, progress=progress))
        except SimulationFailed as exc:  # keep what was computed, under a name no one takes for the whole run
            kept = write_results(exc.result, companion(out, ".failed.h5"), scene=scene.provenance(),
                                 bodies=scene.sources)
            raise InputError(f"{exc} in {kept} ({out} not written)") from None
    files = {}
    signals = list(scene.output.signals or DEFAULT_SIGNALS)
    with phases("write", str(out)):
        files["results"] = write_results(result, out, scene=scene.provenance(), bodies=scene.sources)
        if plot or scene.output.plot:
            files["plot"] = plot_signals(result, signals, companion(out, ".png"), title=scene.title)
        if csv or scene.output.csv:
            files["csv"] = write_csv(result, signals, companion(out, ".csv"))
    if animate:
        from sidprep.solver.animation import write_animation  # deferred: meshio, only for --animate

        with phases("animate", f"{len(result.t)} frames"):
            files["animation"] = write_animation(result, surfaces, companion(out, ".pvd"))
    return SceneRun(scene, result, files, notes)
