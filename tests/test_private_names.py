"""No private name crosses a module boundary.  A name that starts with one underscore belongs to the
module that defines it; what another module needs is public, under a proper name in the module
that owns it.  Every module of sidprep/, sidprep/solver/ and sidprep/cli/ is parsed with ``ast`` (imports inside
functions count) and two things are refused:

* importing a private name: ``from m import _x``, ``import m._x`` (project modules and libraries);
* reading a private attribute of an imported name: ``m._x`` where ``m`` was bound by an import.

Dunder names (``__version__``) are public, and so are the underscore names a library documents as
its public API (``UNDERSCORE_API``).
"""

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = ("sidprep",)
#: underscore names that are documented public API: os._exit (the os module's reference) and the
#: methods and fields of a namedtuple (collections.namedtuple's reference)
UNDERSCORE_API = {"_exit", "_fields", "_asdict", "_replace", "_make"}
#: private names of other libraries still read, {(file, dotted name): why}; each one is a debt to pay
#: off, not a licence: the fix is a public API that does the same
KNOWN_PRIVATE = {
    ("sidprep/cli/main.py", "atexit._run_exitfuncs"):
        "the exit handlers run before os._exit skips the interpreter's teardown (docs/performance.md)",
}


def is_private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__") and name not in UNDERSCORE_API


def dotted(node) -> list[str] | None:
    """['a', 'b', 'c'] of the expression ``a.b.c``; None for anything else."""
    parts = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    return [node.id, *reversed(parts)] if isinstance(node, ast.Name) else None


def private_names(source: str) -> list[tuple[int, str]]:
    """(line, dotted name) of every private name ``source`` imports or reads off an imported name."""
    tree = ast.parse(source)
    found, bound = [], set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                bound.add(alias.asname or alias.name.split(".")[0])
                if any(is_private(p) for p in alias.name.split(".")):
                    found.append((node.lineno, alias.name))
        elif isinstance(node, ast.ImportFrom):
            module = "." * node.level + (node.module or "")
            for alias in node.names:
                bound.add(alias.asname or alias.name)
                if is_private(alias.name) or any(is_private(p) for p in (node.module or "").split(".")):
                    found.append((node.lineno, f"{module}.{alias.name}"))
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and is_private(node.attr):
            chain = dotted(node.value)
            if chain and chain[0] in bound:
                found.append((node.lineno, ".".join([*chain, node.attr])))
    return found


def crossings() -> dict[tuple[str, str], int]:
    """{(file, dotted name): line} of the private names the source folders import or read."""
    found = {}
    for folder in FOLDERS:
        for path in sorted((ROOT / folder).rglob("*.py")):
            for line, name in private_names(path.read_text()):
                found.setdefault((path.relative_to(ROOT).as_posix(), name), line)
    return found


def test_no_private_name_is_imported_across_modules():
    new = [f"{file}:{line} {name}" for (file, name), line in crossings().items()
           if (file, name) not in KNOWN_PRIVATE]
    assert new == [], "make the name public in the module that owns it:\n" + "\n".join(new)


def test_the_known_private_names_are_still_there():
    """An entry of KNOWN_PRIVATE whose use is gone is deleted, so the list only shrinks."""
    assert sorted(set(KNOWN_PRIVATE) - set(crossings())) == []


def test_the_check_sees_each_form():
    source = (
        "import os\n"
        "import numba.core._foo\n"
        "from sidprep.fe.mesh import FEMesh, _face_table\n"
        "from ._layout import curves\n"
        "from numba.core import caching\n"
        "def f():\n"
        "    from sidprep import __version__, _hidden\n"
        "    return caching._CacheImpl, caching.CacheImpl, os._exit, local._x\n"
    )
    assert [name for _, name in private_names(source)] == [
        "numba.core._foo", "sidprep.fe.mesh._face_table", "._layout.curves", "sidprep._hidden",
        "caching._CacheImpl"]
