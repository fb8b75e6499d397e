"""The layers of the code, stated here and in docs/architecture.md ("The layers, lowest first"),
table row for table row, and every import checked against them.

Import names lead to folders: ``sidprep.X`` is ``sidprep/X`` (tests/test_packaging.py checks
that pyproject installs every package).  A module belongs to the layer of the longest folder (or file)
of ``LAYERS`` its file lies in, and imports from its own layer, the layers its row names, and the
single modules its row names; nothing else.

An import is every way one module reaches another, read with ``ast`` (importing a module would
miss the ones inside functions): ``import`` and ``from ... import`` at the top of a file or inside
a function; a name imported from a package's ``__init__`` (the lazy Python API ``sidprep`` and
``sidprep.solver``: ``from sidprep import read_mesh`` depends on the API's layer); an attribute
read off an imported name (``sidprep.read_mesh``); and ``importlib.import_module`` (its string,
the literal head of an f-string, or, for a name from a table, every module the file names).

The tests at the end mutate a copy of the tree (``tmp_path``) and expect each check to fail on
what it guards against.
"""

from __future__ import annotations

import ast
import functools
import io
import re
import shutil
import tokenize
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: source folder -> the import name it installs as
INSTALLED_AS = {"sidprep": "sidprep"}


@dataclass(frozen=True)
class Layer:
    """One row of the layer table: its name, its folders / files, the layers it may import and the
    single modules of other layers it may import."""

    name: str
    paths: tuple[str, ...]
    imports: tuple[str, ...] = ()
    modules: tuple[str, ...] = ()

    def row(self) -> str:
        """The row of docs/architecture.md's table."""
        may = ", ".join(self.imports) or "nothing of sidprep"
        if self.modules:
            may += ", and " + ", ".join(f"`{m}`" for m in self.modules) + " only"
        return f"| {self.name} | {', '.join(f'`{p}`' for p in self.paths)} | {may} |"


#: the layers, lowest first (docs/architecture.md, the same rows)
LAYERS = (
    Layer("base", ("sidprep/errors.py", "sidprep/progress.py", "sidprep/tables.py", "sidprep/interpolation.py",
                   "sidprep/lazy.py")),
    Layer("sid", ("sidprep/sid/",), ("base",)),
    Layer("fe", ("sidprep/fe/",), ("base",)),
    Layer("reduction", ("sidprep/reduction/",), ("base", "sid", "fe")),
    Layer("jobs", ("sidprep/jobs/",), ("base", "sid", "fe", "reduction")),
    # the analytical Beam builds a SID in memory (scene ``type = "beam"``) from its closed form and
    # its material table, never from a mesh
    Layer("solver", ("sidprep/solver/",), ("base", "sid"), ("sidprep.reduction.beam", "sidprep.fe.material")),
    Layer("view", ("sidprep/view/",), ("base", "sid"), ("sidprep.solver.results", "sidprep.solver.stress")),
    Layer("api", ("sidprep/__init__.py",), ("base", "sid", "fe", "reduction", "jobs", "solver", "view")),
    Layer("cli", ("sidprep/cli/",), ("base", "sid", "fe", "reduction", "jobs", "solver", "view", "api")),
)
#: inside sidprep/solver/, lowest first (docs/architecture.md, the second table): a module imports its own
#: layer and the ones before it only.  The compiled formulas know no description; the descriptions
#: use their rotations (each formula once)
SOLVER_LAYERS = (
    Layer("core", ("sidprep/solver/core/",)),
    Layer("model", ("sidprep/solver/model/",)),
    Layer("compile", ("sidprep/solver/compile/",)),
    Layer("integrators", ("sidprep/solver/integrators/",)),
    Layer("results", ("sidprep/solver/effects.py", "sidprep/solver/energy.py", "sidprep/solver/statistics.py",
                          "sidprep/solver/results.py")),
    Layer("run", ("sidprep/solver/run.py", "sidprep/solver/postprocess.py", "sidprep/solver/linear.py", "sidprep/solver/stiffening_work.py")),
    Layer("scenes", ("sidprep/solver/scene_tables.py", "sidprep/solver/scene.py", "sidprep/solver/absolute_nodal/", "sidprep/solver/animation.py",
                     "sidprep/solver/stress.py", "sidprep/solver/fatigue.py", "sidprep/solver/simulate_scene.py",
                     "sidprep/solver/scene_modes.py")),
    Layer("studies", ("sidprep/solver/converge.py",)),
    Layer("solver api", ("sidprep/solver/__init__.py",)),
)
#: names a package's ``__init__`` defines that every layer may read: the version, set before anything
#: is imported, which every file a layer writes records
PACKAGE_METADATA = {"__version__"}
#: modules that import by a name known only at run time, each with its reason
RUNTIME_IMPORTS = {
    "sidprep.lazy": "a package's module on first use, by the attribute name asked for (PEP 562 __getattr__)",
}
#: at most this many parameters (``self`` counts): a function that needs more takes a named structure
#: (a frozen dataclass of options, a model, a layout)
MAX_PARAMETERS = 8
#: the functions that take more, {file:qualified name: (parameters, why)}; the count is a ceiling
WIDE_FUNCTIONS = {
    "sidprep/fe/linalg.py:eigen_modes": (11, "the eigen solver's keyword options with one default each, as scipy's eigsh"),
    "sidprep/fe/linalg.py:_iterative_modes": (10, "eigen_modes' options passed on unchanged to its iterative branch"),
    "sidprep/jobs/reduce.py:reduce_body": (12, "ReduceOptions' fields as keywords, for callers without a job"),
    "sidprep/reduction/modes.py:modal_basis": (9, "keyword options of the second FEMBS step, one default each"),
    "sidprep/sid/model.py:sid_invariants": (12, "the optional SID fields as keywords (sid-spec 4.2-4.7)"),
    "sidprep/solver/integrators/initial.py:assemble_positions": (10, "the layout's state arrays of the consistent start"),
    "sidprep/solver/integrators/initial.py:damped_gauss_newton": (10, "the layout's state arrays of the consistent start"),
    "sidprep/solver/integrators/initial.py:project_velocities": (9, "the layout's state arrays of the consistent start"),
    "sidprep/solver/integrators/initial.py:accelerations": (10, "the layout's state arrays of the consistent start"),
    "sidprep/solver/integrators/initial.py:quasi_static_elastic": (11, "the layout's state arrays of the consistent start"),
    "sidprep/solver/model/bodies.py:RigidBody.__init__": (10, "a rigid body's mass, centre, inertia and start state as keywords"),
    "sidprep/solver/model/bodies.py:FlexibleBody.__init__": (12, "a flexible body's SID, start state and effects as keywords"),
}
#: at most this many modules directly in sidprep/ (the rest live in the subpackages)
MAX_FLAT_MODULES = 10
#: folders whose imports stand at the top of files; an import inside a function carries the comment
#: ``# deferred: <reason>`` (a measured start-up cost or an optional dependency) on its line or the
#: line above.  The CLI's command modules import their library inside ``run`` by design
#: (docs/architecture.md), and the lazy Python API (sidprep/__init__.py) is made of such imports
IMPORTS_AT_TOP = ("sidprep",)
DEFERRED = re.compile(r"#\s*deferred:\s*\S")
#: the module a line of a Cython file imports or cimports
CYTHON_IMPORT = re.compile(r"^\s*(?:from|c?import)\s+([\w.]+)", re.M)


# ---------------------------------------------------------------------------------------------
# The import graph
# ---------------------------------------------------------------------------------------------
def module_files(root: Path = ROOT) -> dict[str, Path]:
    """{installed module name: file} of every module of the three source folders (Cython's too)."""
    mods = {}
    for folder, name in INSTALLED_AS.items():
        for path in [*(root / folder).rglob("*.py"), *(root / folder).rglob("*.pyx")]:
            parts = [p for p in path.relative_to(root / folder).with_suffix("").parts if p != "__init__"]
            mods[".".join([name, *parts])] = path
    return mods


def owner(dotted: str, mods) -> str | None:
    """The project module a dotted name lies in (longest module prefix); None: another library."""
    while dotted and dotted not in mods:
        dotted = dotted.rpartition(".")[0]
    return dotted or None


def dotted_name(node) -> str | None:
    """'a.b.c' of the expression ``a.b.c``; None for anything else."""
    parts = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    return ".".join([node.id, *reversed(parts)]) if isinstance(node, ast.Name) else None


def runtime_import_targets(call: ast.Call, name: str, nodes, mods) -> set[str] | None:
    """The project modules ``importlib.import_module(...)`` / ``__import__(...)`` may load: its
    string; for an f-string, the other modules under its literal head that the file names (a table of
    readers), else all of them (plug-ins); for any other argument, every module whose name the
    file spells out (a table).  None: none of these."""
    arg = call.args[0] if call.args else None
    if isinstance(arg, ast.Constant) and isinstance(arg.value, str):
        return {owner(arg.value, mods)} - {None}
    strings = {n.value for n in nodes if isinstance(n, ast.Constant) and isinstance(n.value, str)}
    if isinstance(arg, ast.JoinedStr) and arg.values and isinstance(arg.values[0], ast.Constant):
        head = arg.values[0].value
        under = {m for m in mods if m.startswith(head)} - {name}
        return {m for m in under if m[len(head):] in strings} or under or None
    return (strings & set(mods)) or None


def is_runtime_import(call: ast.Call) -> bool:
    name = dotted_name(call.func)
    return name is not None and (name == "__import__" or name.endswith("import_module"))


@functools.lru_cache(maxsize=None)
def parsed(text: str) -> tuple[ast.Module, tuple[ast.AST, ...]]:
    """The tree of a file's text and all its nodes (cached: the mutated copies share most files)."""
    tree = ast.parse(text)
    return tree, tuple(ast.walk(tree))


def imported_modules(name: str, path: Path, mods) -> set[str]:
    """The project modules ``name`` reaches anywhere in its file (module docstring)."""
    if path.suffix == ".pyx":                          # Cython, not Python: its import and cimport lines
        return {owner(m, mods) for m in CYTHON_IMPORT.findall(path.read_text())} - {None, name}
    return set(module_edges(name, path.name == "__init__.py", path.read_text(), frozenset(mods)))


@functools.lru_cache(maxsize=None)
def module_edges(name: str, is_package: bool, text: str, mods: frozenset) -> frozenset:
    package = name.split(".") if is_package else name.split(".")[:-1]
    tree, nodes = parsed(text)
    found, bound = set(), {}
    for node in nodes:
        if isinstance(node, ast.Import):
            for alias in node.names:
                found.add(owner(alias.name, mods))
                top = alias.name.split(".")[0]
                bound[alias.asname or top] = alias.name if alias.asname else top
        elif isinstance(node, ast.ImportFrom):
            base = ".".join(package[:len(package) - node.level + 1] + [node.module or ""]).strip(".") \
                if node.level else node.module
            for alias in node.names:
                bound[alias.asname or alias.name] = f"{base}.{alias.name}"
                if alias.name not in PACKAGE_METADATA:
                    found.add(owner(f"{base}.{alias.name}", mods))
        elif isinstance(node, ast.Call) and is_runtime_import(node):
            targets = runtime_import_targets(node, name, nodes, mods)
            if targets is None and name not in RUNTIME_IMPORTS:
                found.add(f"<a module known only at run time, line {node.lineno}>")
            found |= targets or set()
    inner = {id(n.value) for n in nodes if isinstance(n, ast.Attribute)}
    for node in nodes:                                 # whole chains a.b.c only, not their heads
        if isinstance(node, ast.Attribute) and id(node) not in inner and node.attr not in PACKAGE_METADATA:
            chain = dotted_name(node)
            head, _, rest = (chain or "").partition(".")
            if head in bound:
                found.add(owner(f"{bound[head]}.{rest}", mods))
    return frozenset(t for t in found if t is not None and t != name)


def import_graph(root: Path = ROOT) -> dict[str, set[str]]:
    mods = module_files(root)
    names = frozenset(mods)
    return {name: imported_modules(name, path, names) for name, path in mods.items()}


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in graph:
                continue
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


# ---------------------------------------------------------------------------------------------
# The checks (each returns what breaks its rule; the tests below expect nothing)
# ---------------------------------------------------------------------------------------------
def layer_of(path: Path, layers, root: Path) -> Layer | None:
    """The layer whose longest folder (or file) holds ``path``."""
    rel = path.relative_to(root).as_posix()
    held = [(len(p), layer) for layer in layers for p in layer.paths
            if rel == p or (p.endswith("/") and rel.startswith(p))]
    return max(held, key=lambda t: t[0])[1] if held else None


def layer_breaches(root: Path = ROOT) -> list[str]:
    """Imports that leave what a module's row allows, and modules of no layer."""
    mods = module_files(root)
    where = {m: layer_of(p, LAYERS, root) for m, p in mods.items()}
    wrong = [f"{m}: in no layer" for m, layer in where.items() if layer is None]
    for m, targets in import_graph(root).items():
        mine = where[m]
        for t in sorted(targets):
            theirs = where.get(t)
            if mine is None or theirs is mine:
                continue
            if theirs is None or (theirs.name not in mine.imports and t not in mine.modules):
                wrong.append(f"{m} ({mine.name}) imports {t} ({theirs.name if theirs else 'run time'})")
    return wrong


def solver_breaches(root: Path = ROOT) -> list[str]:
    """Imports inside sidprep/solver/ that go up its layers, and solver modules of no layer."""
    mods = {m: p for m, p in module_files(root).items() if m == "sidprep.solver" or m.startswith("sidprep.solver.")}
    rank = {m: layer_of(p, SOLVER_LAYERS, root) for m, p in mods.items()}
    order = {layer.name: k for k, layer in enumerate(SOLVER_LAYERS)}
    wrong = [f"{m}: in no solver layer" for m, layer in rank.items() if layer is None]
    graph = import_graph(root)
    for m in mods:
        for t in sorted(graph[m]):
            if t in rank and rank[m] and rank[t] and order[rank[t].name] > order[rank[m].name]:
                wrong.append(f"{m} ({rank[m].name}) imports {t} ({rank[t].name})")
    return wrong


def hidden_imports(root: Path = ROOT) -> list[str]:
    """Imports inside functions without ``# deferred: <reason>`` on their line or the line above."""
    hidden = []
    for folder in IMPORTS_AT_TOP:
        for path in (root / folder).rglob("*.py"):
            if path != root / "sidprep" / "__init__.py" and (root / "sidprep" / "cli") not in path.parents:
                # (the lazy Python API and the command modules: their docstrings say why)
                hidden += [f"{path.relative_to(root)}:{line}" for line in undeferred_imports(path.read_text())]
    return sorted(hidden)


def imports_in_functions(node, inside: bool = False):
    """The import statements inside the functions under ``node``."""
    for child in ast.iter_child_nodes(node):
        if inside and isinstance(child, (ast.Import, ast.ImportFrom)):
            yield child
        yield from imports_in_functions(child, inside or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)))


@functools.lru_cache(maxsize=None)
def undeferred_imports(text: str) -> tuple[int, ...]:
    """Lines of the imports inside functions of ``text`` that carry no ``# deferred: <reason>``."""
    comments = {tok.start[0]: tok.string for tok in tokenize.generate_tokens(io.StringIO(text).readline)
                if tok.type == tokenize.COMMENT}
    tree, _ = parsed(text)
    inside = list(imports_in_functions(tree))
    return tuple(sorted(n.lineno for n in inside
                        if not any(DEFERRED.match(comments.get(k, "")) for k in range(n.lineno - 1, n.end_lineno + 1))))


def qualified_functions(tree):
    """(qualified name, node) of every function, methods as Class.method."""
    def walk(node, prefix):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                yield prefix + child.name, child
                yield from walk(child, prefix + child.name + ".")
            elif isinstance(child, ast.ClassDef):
                yield from walk(child, prefix + child.name + ".")
            else:
                yield from walk(child, prefix)
    yield from walk(tree, "")


def wide_functions(root: Path = ROOT) -> list[str]:
    """Functions with more than MAX_PARAMETERS parameters (or above their WIDE_FUNCTIONS ceiling)."""
    wide = []
    for folder in INSTALLED_AS:
        for path in sorted((root / folder).rglob("*.py")):
            rel = path.relative_to(root).as_posix()
            for qualname, line, count in parameter_counts(path.read_text()):
                if count > WIDE_FUNCTIONS.get(f"{rel}:{qualname}", (MAX_PARAMETERS,))[0]:
                    wide.append(f"{rel}:{line} {qualname} ({count})")
    return wide


@functools.lru_cache(maxsize=None)
def parameter_counts(text: str) -> tuple[tuple[str, int, int], ...]:
    """(qualified name, line, number of parameters) of every function of ``text``."""
    return tuple((qualname, node.lineno, len(node.args.posonlyargs) + len(node.args.args) + len(node.args.kwonlyargs))
                 for qualname, node in qualified_functions(parsed(text)[0]))


def documented_rows(root: Path = ROOT) -> tuple[list[str], list[str]]:
    """The rows of the two layer tables of docs/architecture.md's "The layers, lowest first"."""
    text = (root / "docs" / "architecture.md").read_text()
    section = text.split("## The layers, lowest first", 1)[1].split("\n## ", 1)[0]
    tables = re.findall(r"((?:^\|.*\|\n)+)", section, flags=re.M)
    rows = [[line for line in t.splitlines()[2:]] for t in tables]
    return (rows + [[], []])[0], (rows + [[], []])[1]


# ---------------------------------------------------------------------------------------------
# The tree as it is
# ---------------------------------------------------------------------------------------------
def test_no_import_cycle():
    assert cycles(import_graph()) == []


def test_imports_follow_the_layers():
    assert layer_breaches() == []


def test_solver_layers_import_one_way():
    assert solver_breaches() == []


def test_imports_sit_at_the_top_of_files():
    assert hidden_imports() == []


def test_no_function_takes_more_than_eight_parameters():
    assert wide_functions() == []


def test_the_documented_layers_are_the_tested_ones():
    layers, solver = documented_rows()
    assert layers == [layer.row() for layer in LAYERS]
    assert solver == [layer.row().replace(" | nothing of sidprep |", " |") for layer in SOLVER_LAYERS]


def test_sid_package_needs_no_fe_library():
    """sidprep.sid is what the solver reads SID files with: no FE library may enter it (numpy, h5py
    and scipy, which the solver needs anyway, may)."""
    heavy = ("skfem", "meshio", "gmsh", "pyamg", "sksparse_minimal")
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


def test_the_graph_sees_function_level_and_lazy_imports():
    graph = import_graph()
    assert "sidprep.jobs.reduce" in graph["sidprep"]           # inside a function of the lazy API
    assert "sidprep.solver.scene" in graph["sidprep"]          # a string of the API's table
    assert "sidprep.fe.matrices.calculix" in graph["sidprep.fe.matrices"]   # an f-string's head


# ---------------------------------------------------------------------------------------------
# Each check fails on what it guards against (a copy of the tree, mutated)
# ---------------------------------------------------------------------------------------------
@pytest.fixture
def tree(tmp_path):
    """A copy of the sources and docs/architecture.md."""
    def other_files(folder, names):
        return [n for n in names if n == "__pycache__"
                or not (n.endswith((".py", ".pyx", ".md")) or (Path(folder) / n).is_dir())]

    for folder in (*INSTALLED_AS, "docs"):
        shutil.copytree(ROOT / folder, tmp_path / folder, ignore=other_files)
    return tmp_path


def append(path: Path, text: str) -> None:
    path.write_text(path.read_text() + "\n\n" + text)


@pytest.mark.parametrize("code", [
    "def probe(path):\n    from sidprep import read_mesh  # deferred: a probe\n    return read_mesh(path)\n",
    "import sidprep\n\n\ndef probe(path):\n    return sidprep.read_mesh(path)\n",
    "import importlib\n\n\ndef probe():\n    return importlib.import_module('sidprep.fe.mesh')\n",
    "import importlib\n\n\ndef probe(name):\n    return importlib.import_module(name)\n",
], ids=["lazy-api-import", "lazy-api-attribute", "import-module-string", "import-module-unknown"])
def test_the_solver_reaching_the_fe_side_fails(tree, code):
    append(tree / "sidprep" / "solver" / "linear.py", code)
    assert any(b.startswith("sidprep.solver.linear (solver) imports") for b in layer_breaches(tree))


@pytest.mark.parametrize("target", ["sidprep.fe.mesh", "sidprep.jobs.options"])
def test_the_view_importing_fe_or_jobs_fails(tree, target):
    append(tree / "sidprep" / "view" / "modes.py", f"import {target}\n")
    assert [b for b in layer_breaches(tree) if "sidprep.view" in b] == [f"sidprep.view.modes (view) imports {target} "
                                                                         f"({target.split('.')[1]})"]


def test_a_module_of_no_layer_fails(tree):
    (tree / "sidprep" / "geometry.py").write_text('"""A new flat module."""\n')
    assert layer_breaches(tree) == ["sidprep.geometry: in no layer"]


def test_the_compiled_formulas_importing_a_description_fails(tree):
    append(tree / "sidprep" / "solver" / "core" / "rotations.pyx", "from sidprep.solver.model.effects import EFFECTS\n")
    assert solver_breaches(tree) == ["sidprep.solver.core.rotations (core) imports sidprep.solver.model.effects (model)"]


def test_the_solver_importing_its_own_api_fails(tree):
    append(tree / "sidprep" / "solver" / "run.py", "from sidprep.solver import System\n")
    assert solver_breaches(tree) == ["sidprep.solver.run (run) imports sidprep.solver (solver api)"]


def test_an_import_cycle_fails(tree):
    append(tree / "sidprep" / "fe" / "topology.py", "from sidprep.fe.mesh import FEMesh\n")
    assert any({"sidprep.fe.mesh", "sidprep.fe.topology"} <= set(c) for c in cycles(import_graph(tree)))


@pytest.mark.parametrize("comment, hidden", [("# deferred: 0.2 s import", False), ("# not deferred", True),
                                             ("# deferred", True), ("", True)])
def test_a_function_level_import_needs_its_reason(tree, comment, hidden):
    append(tree / "sidprep" / "solver" / "linear.py", f"def probe():\n    import json  {comment}\n    return json\n")
    assert any(h.startswith("sidprep/solver/linear.py") for h in hidden_imports(tree)) == hidden


def test_a_ninth_parameter_fails(tree):
    append(tree / "sidprep" / "tables.py", "def probe(a, b, c, d, e, f, g, h, i):\n    return a\n")
    append(tree / "sidprep" / "sid" / "model.py", "def sid_invariants_again(*, a, b, c, d, e, f, g, h):\n    return a\n")
    assert [w.split(" ", 1)[1] for w in wide_functions(tree)] == ["probe (9)"]


def test_a_named_wide_function_may_not_grow(tree):
    path = tree / "sidprep" / "sid" / "model.py"
    path.write_text(path.read_text().replace("def sid_invariants(points,", "def sid_invariants(extra, points,"))
    assert [w.split(" ", 1)[1] for w in wide_functions(tree)] == ["sid_invariants (13)"]


def test_docs_and_test_disagreeing_fails(tree):
    path = tree / "docs" / "architecture.md"
    row = "| view | `sidprep/view/` | base, sid,"
    path.write_text(path.read_text().replace(row, row.replace("sid,", "sid, fe,")))
    assert documented_rows(tree)[0] != [layer.row() for layer in LAYERS]
