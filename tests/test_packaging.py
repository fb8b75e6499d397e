"""One import namespace: every package folder under sidprep/ is listed in pyproject.toml under the
name its path gives, so a wheel holds all of it."""

import ast
import os
from pathlib import Path

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[1]
#: the package's folder
PACKAGE = ROOT / "sidprep"


def test_every_package_folder_is_installed_under_sidprep():
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    found = {".".join(init.relative_to(ROOT).parts[:-1]) for init in PACKAGE.rglob("__init__.py")}
    assert found == set(config["packages"])
    assert "package-dir" not in config


def test_no_generic_top_level_names_in_the_source():
    """Code imports the solver and the CLI as sidprep.solver / sidprep.cli only."""
    offenders = []
    for path in [*ROOT.glob("*/**/*.py")]:
        if ".venv" in path.parts or "data" in path.parts:
            continue
        for n, line in enumerate(path.read_text().splitlines(), 1):
            stripped = line.strip()
            if stripped.split(" ")[:2] in (["from", "solver"], ["import", "solver"], ["from", "cli"], ["import", "cli"]) \
                    or stripped.startswith(("from solver.", "import solver.", "from cli.", "import cli.")):
                offenders.append(f"{path.relative_to(ROOT)}:{n}: {stripped}")
    assert not offenders, "\n".join(offenders)


def setup_listing(name: str):
    """The value of setup.py's assignment ``name``, evaluated in the checkout's folder with the
    names setup.py imports from pathlib (read, not run: running it would start a build)."""
    tree = ast.parse((ROOT / "setup.py").read_text())
    values = [node.value for node in tree.body
              if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == name for t in node.targets)]
    assert len(values) == 1, f"setup.py assigns {name} {len(values)} times"
    here = os.getcwd()
    try:
        os.chdir(ROOT)
        return eval(compile(ast.Expression(values[0]), "setup.py", "eval"), {"Path": Path})
    finally:
        os.chdir(here)


def setup_constant(name: str):
    """A literal constant of setup.py (read, not run: running it would start a build)."""
    tree = ast.parse((ROOT / "setup.py").read_text())
    values = [ast.literal_eval(node.value) for node in tree.body
              if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == name for t in node.targets)]
    assert len(values) == 1, f"setup.py assigns {name} {len(values)} times"
    return values[0]


def test_every_cython_module_is_built_and_portable():
    """setup.py builds every .pyx file of the package (it lists them itself), each in an installed
    package, and no flag ties the build to the machine that compiles it (-march=native)."""
    packages = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"]
    modules = {".".join(p.relative_to(ROOT).with_suffix("").parts) for p in PACKAGE.rglob("*.pyx")}
    assert {m.rpartition(".")[0] for m in modules} <= set(packages)
    assert set(setup_listing("CYTHON_MODULES")) == modules
    assert not [a for a in setup_constant("COMPILE_ARGS") if a.startswith(("-march", "-mtune", "-mcpu"))]
