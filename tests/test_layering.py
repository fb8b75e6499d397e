"""The layers of the code, with every import counted: those at the top of a file and those inside
functions, parsed with ``ast`` (importing a module would miss the ones inside functions).

Import names lead to folders: ``sidprep.X`` is ``sidprep/X``, except ``sidprep.solver`` ->
``solver/`` and ``sidprep.cli`` -> ``cli/`` (README, section Layout; tests/test_packaging.py checks
that pyproject installs them so).  Data flows one way::

    base (errors, progress, tables, interpolation) -> sid -> fe -> reduction -> jobs
    base, sid -> solver -> view -> cli

and inside solver/: geometry (rotations) -> model, equations -> compile -> integrators -> results -> run -> scenes.
"""

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: source folder -> the import name it installs as
INSTALLED_AS = {"sidprep": "sidprep", "solver": "sidprep.solver", "cli": "sidprep.cli"}

#: layer of each package (longest prefix wins); a module imports only from its layer and lower ones
LAYERS = {
    "sidprep.errors": 0, "sidprep.progress": 0, "sidprep.tables": 0, "sidprep.interpolation": 0,
    "sidprep.sid": 1,
    "sidprep.fe": 2,
    "sidprep.reduction": 3,
    "sidprep.jobs": 4,
    "sidprep.solver": 5,
    "sidprep.view": 6,
    "sidprep.cli": 7,
    "sidprep": 8,          # the package's lazy Python API (sidprep/__init__.py) stands over everything
}
#: what the solver may take from the FE side's layers: the analytical Beam builds a SID in memory
#: (scene ``type = "beam"``) from its closed form and its material table, never from a mesh
SOLVER_MAY_IMPORT = ("sidprep.reduction.beam", "sidprep.fe.material")
#: at most this many modules directly in sidprep/ (the rest live in the subpackages)
MAX_FLAT_MODULES = 10
#: solver/ from the first layer to the last (docs/solver.md): a module imports its own layer and
#: the ones before it only
SOLVER_LAYERS = (
    ("geometry", ("sidprep.solver.equations.rotations", "sidprep.solver.equations.aot", "sidprep.solver.equations.kernel_cache")),       # first match: before equations
    ("model", ("sidprep.solver.model",)),
    ("equations", ("sidprep.solver.equations",)),
    ("compile", ("sidprep.solver.compile",)),
    ("integrators", ("sidprep.solver.integrators",)),
    ("results", ("sidprep.solver.effects", "sidprep.solver.results", "sidprep.solver.energy")),
    ("run", ("sidprep.solver.run", "sidprep.solver.postprocess", "sidprep.solver.stiffening_work",
             "sidprep.solver.linear")),
    ("scenes", ("sidprep.solver.scene_tables", "sidprep.solver.scene", "sidprep.solver.absolute_nodal",
                "sidprep.solver.animation", "sidprep.solver.stress", "sidprep.solver.fatigue",
                "sidprep.solver.prebuild")),
)
#: solver layers that share nothing: the compiled kernels never see the descriptions, nor they the kernels
INDEPENDENT = {("model", "equations"), ("equations", "model")}
#: the most parameters a function may take (named structures carry the rest)
MAX_PARAMETERS = 12
#: folders whose imports stand at the top of files; an import inside a function says why on its
#: line or the line above ("deferred": a measured start-up cost or an optional dependency). The
#: CLI's command modules import their library inside ``run`` by design (docs/architecture.md).
IMPORTS_AT_TOP = ("sidprep", "solver")


def module_files() -> dict[str, Path]:
    """{installed module name: file} of every module of the three source folders."""
    mods = {}
    for folder, name in INSTALLED_AS.items():
        for path in (ROOT / folder).rglob("*.py"):
            parts = [p for p in path.relative_to(ROOT / folder).with_suffix("").parts if p != "__init__"]
            mods[".".join([name, *parts])] = path
    return mods


def imported_modules(name: str, path: Path, mods: dict[str, Path]) -> set[str]:
    """The project modules ``name`` imports anywhere in its file (parents of itself excluded)."""
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = ".".join(package[:len(package) - node.level + 1] + [node.module or ""]).strip(".") \
                if node.level else node.module
            targets = [base] + [f"{base}.{a.name}" for a in node.names]
        else:
            continue
        for target in targets:
            while target and target not in mods:
                target = target.rpartition(".")[0]
            if target and target != name and not name.startswith(target + "."):
                found.add(target)
    return found


def import_graph() -> dict[str, set[str]]:
    mods = module_files()
    return {name: imported_modules(name, path, mods) for name, path in mods.items()}


def layer(module: str) -> int:
    key = max((k for k in LAYERS if module == k or module.startswith(k + ".")), key=len)
    return LAYERS[key]


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in graph:
        if v not in index:
            visit(v)
    return found


def test_no_import_cycle():
    assert cycles(import_graph()) == []


def test_imports_follow_the_layers():
    upward = [f"{m} -> {t}" for m, targets in import_graph().items() for t in sorted(targets)
              if layer(t) > layer(m)]
    assert not upward, "\n".join(upward)


def test_solver_does_not_import_fe_side():
    fe = [f"{m} -> {t}" for m, targets in import_graph().items() if m.startswith("sidprep.solver")
          for t in sorted(targets) if 2 <= layer(t) <= 4 and t not in SOLVER_MAY_IMPORT]
    assert not fe, "\n".join(fe)


def test_sid_package_needs_no_fe_library():
    """sidprep.sid is what the solver reads SID files with: no FE library may enter it (numpy, h5py
    and scipy, which the solver needs anyway, may)."""
    heavy = ("skfem", "meshio", "gmsh", "pyamg", "sksparse_minimal", "numba")
    offenders = []
    for name, path in module_files().items():
        if name.startswith("sidprep.sid"):
            for node in ast.walk(ast.parse(path.read_text())):
                roots = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                    [node.module or ""] if isinstance(node, ast.ImportFrom) and not node.level else []
                offenders += [f"{name}: {r}" for r in roots if r.split(".")[0] in heavy]
    assert not offenders, "\n".join(offenders)


def test_few_modules_directly_in_sidprep():
    flat = [p.name for p in (ROOT / "sidprep").glob("*.py") if p.name != "__init__.py"]
    assert len(flat) <= MAX_FLAT_MODULES, flat


def test_the_layering_test_sees_function_level_imports():
    """A guard for the test itself: an import inside a function is an edge of the graph."""
    graph = import_graph()
    assert "sidprep.jobs.reduce" in graph["sidprep"]       # the lazy API imports it inside a function


def solver_layer(name: str):
    for rank, (label, prefixes) in enumerate(SOLVER_LAYERS):
        if any(name == p or name.startswith(p + ".") for p in prefixes):
            return rank, label
    return None


def test_solver_layers_import_one_way():
    graph = import_graph()
    solver = [m for m in graph if m.startswith("sidprep.solver.")]
    assert [m for m in solver if solver_layer(m) is None] == []           # every module has its layer
    wrong = []
    for m in solver:
        rank, label = solver_layer(m)
        for target in graph[m]:
            other = solver_layer(target)
            if other is not None and (other[0] > rank or (label, other[1]) in INDEPENDENT):
                wrong.append(f"{m} ({label}) imports {target} ({other[1]})")
    assert wrong == []


def test_imports_sit_at_the_top_of_files():
    hidden = []
    for folder in IMPORTS_AT_TOP:
        for path in (ROOT / folder).rglob("*.py"):
            if path == ROOT / "sidprep" / "__init__.py":
                continue                                    # the lazy Python API (its docstring says why)
            text = path.read_text().splitlines()
            tree = ast.parse("\n".join(text))
            for f in ast.walk(tree):
                if isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef)):
                    for n in ast.walk(f):
                        if isinstance(n, (ast.Import, ast.ImportFrom)) and n is not f:
                            reason = text[n.lineno - 1] + text[n.lineno - 2]
                            if "deferred" not in reason:
                                hidden.append(f"{path.relative_to(ROOT)}:{n.lineno}")
    assert hidden == []


def test_no_function_takes_more_than_twelve_parameters():
    wide = []
    for folder in INSTALLED_AS:
        for path in (ROOT / folder).rglob("*.py"):
            for node in ast.walk(ast.parse(path.read_text(), str(path))):
                if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                    count = len(node.args.posonlyargs) + len(node.args.args) + len(node.args.kwonlyargs)
                    if count > MAX_PARAMETERS:
                        wide.append(f"{path.relative_to(ROOT)}:{node.lineno} {node.name} ({count})")
    assert wide == []
