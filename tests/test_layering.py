"""Layering: the solver reads SID files only (it never imports sidprep's FE side), and solver/ is a
one-way stack with no import cycle, every import counted (module level and inside functions)."""

import ast
import subprocess
import sys
from pathlib import Path

FE_MODULES = ("sidprep.mesh", "sidprep.assemble", "sidprep.linalg", "sidprep.craig_bampton",
              "sidprep.modes", "sidprep.interfaces", "sidprep.stiffening", "sidprep.job", "sidprep.analysis", "skfem")

ROOT = Path(__file__).resolve().parents[1]
#: the source folders and their installed import names (pyproject's package-dir)
PACKAGES = {"sidprep": "sidprep", "solver": "sidprep.solver", "cli": "sidprep.cli"}
#: solver/ from the first layer to the last (docs/solver.md): a module imports its own layer and
#: the ones before it only
SOLVER_LAYERS = (
    ("geometry", ("sidprep.solver.equations.rotations",)),
    ("model", ("sidprep.solver.model",)),
    ("equations", ("sidprep.solver.equations",)),
    ("compile", ("sidprep.solver.compile",)),
    ("integrators", ("sidprep.solver.integrators",)),
    ("results", ("sidprep.solver.effects", "sidprep.solver.results", "sidprep.solver.energy")),
    ("run", ("sidprep.solver.run", "sidprep.solver.postprocess", "sidprep.solver.stiffening_work",
             "sidprep.solver.linear")),
    ("scenes", ("sidprep.solver.scene_tables", "sidprep.solver.scene", "sidprep.solver.absolute_nodal",
                "sidprep.solver.animation")),
)
#: layers that share nothing: the compiled kernels never see the descriptions, nor they the kernels
INDEPENDENT = {("model", "equations"), ("equations", "model")}


def modules() -> dict:
    """{installed module name: source file} of every module of the checkout."""
    out = {}
    for folder, name in PACKAGES.items():
        for path in (ROOT / folder).rglob("*.py"):
            parts = [p for p in path.relative_to(ROOT / folder).with_suffix("").parts if p != "__init__"]
            out[".".join([name] + parts)] = path
    return out


def imports(name: str, path: Path, known: dict):
    """(imported module, line, inside a function) of every import statement of a module, resolved
    to the modules of the checkout (relative imports and ``from package import module`` too)."""
    tree = ast.parse(path.read_text(), str(path))
    inner = {id(n) for f in ast.walk(tree) if isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef))
             for n in ast.walk(f) if n is not f}
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = ".".join(package[:len(package) - node.level + 1] + ([node.module] if node.module else [])) \
                if node.level else node.module
            targets = [base] + [f"{base}.{a.name}" for a in node.names]
        else:
            continue
        for target in targets:
            while target and target not in known:
                target = target.rpartition(".")[0]
            if target and target != name and not name.startswith(target + "."):
                yield target, node.lineno, id(node) in inner


def graph() -> dict:
    known = modules()
    return {name: {t for t, _, _ in imports(name, path, known)} for name, path in known.items()}


def layer(name: str):
    for rank, (label, prefixes) in enumerate(SOLVER_LAYERS):  # the first match: geometry before equations
        if any(name == p or name.startswith(p + ".") for p in prefixes):
            return rank, label
    return None


def test_no_import_cycle_counting_every_import():
    edges = graph()
    index, low, stack, on, cycles, counter = {}, {}, [], set(), [], [0]

    def visit(v):  # Tarjan's strongly connected components
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in edges[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    sys.setrecursionlimit(10000)
    for v in edges:
        if v not in index:
            visit(v)
    assert cycles == []


def test_solver_layers_import_one_way():
    edges = graph()
    solver = [m for m in edges if m.startswith("sidprep.solver.")]
    assert [m for m in solver if layer(m) is None] == []           # every module has its layer
    wrong = []
    for m in solver:
        rank, label = layer(m)
        for target in edges[m]:
            other = layer(target)
            if other is not None and (other[0] > rank or (label, other[1]) in INDEPENDENT):
                wrong.append(f"{m} ({label}) imports {target} ({other[1]})")
    assert wrong == []


def test_solver_imports_sit_at_the_top_of_files():
    """An import inside a function needs a reason named on its line or the line above it (a
    measured start-up cost or an optional dependency: 'deferred')."""
    known = modules()
    hidden = []
    for name, path in known.items():
        if not name.startswith("sidprep.solver"):
            continue
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


def test_solver_does_not_import_fe_side():
    code = (
        "import sys, importlib, pkgutil\n"
        "from sidprep import solver\n"
        "for m in pkgutil.walk_packages(solver.__path__, 'sidprep.solver.'):\n"
        "    importlib.import_module(m.name)\n"
        f"print(','.join(m for m in {FE_MODULES!r} if m in sys.modules))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""


#: the most parameters a function of solver/ may take (named structures carry the rest)
MAX_PARAMETERS = 12


def test_no_solver_function_takes_more_than_twelve_parameters():
    wide = []
    for path in (ROOT / "solver").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                count = len(node.args.posonlyargs) + len(node.args.args) + len(node.args.kwonlyargs)
                if count > MAX_PARAMETERS:
                    wide.append(f"{path.relative_to(ROOT)}:{node.lineno} {node.name} ({count})")
    assert wide == []
