"""Modules reachable on first use: after ``import sidprep`` every documented module is an attribute
(``sidprep.jobs.batch.read_study``, ``sidprep.sid.surface``, ``sidprep.solver.linear``) without the
package importing its modules up front, so ``import sidprep`` and ``sidprep --help`` stay cheap.
Each package's ``__getattr__`` (PEP 562) calls ``submodule``."""

from __future__ import annotations

import importlib
import importlib.util


def submodule(package: str, name: str):
    """The module ``package.name``, imported now; AttributeError when there is none."""
    if not name.startswith("_") and importlib.util.find_spec(f"{package}.{name}") is not None:
        return importlib.import_module(f"{package}.{name}")
    raise AttributeError(f"module {package!r} has no attribute {name!r}")
