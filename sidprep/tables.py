"""One typed reader for the TOML tables of job, study and scene files.

A table is checked against a frozen dataclass (``read_table``: job and study files) or read key by
key with typed getters (``TomlTable``: scene files, whose tables hold arrays, paths and named
entries): unknown keys, missing required keys and values of the wrong type give one-line
InputErrors naming the file, the table, the key and the fix.
"""

from __future__ import annotations

import difflib
import math
import re
import sys
import types
import typing
from dataclasses import MISSING, fields
from pathlib import Path

import numpy as np

from sidprep.errors import InputError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

_REQUIRED = object()

_NAMES = {float: "a number", int: "an integer", str: "a string", bool: "true or false",
          tuple: "a list", dict: "a table", type(None): "absent"}


def read_toml_text(path, what: str = "file") -> tuple[dict, str]:
    """The TOML document at ``path`` and its text; "file not found" and syntax errors as
    one-line InputErrors."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: {what} not found; check the path")
    size = path.stat().st_size
    if size > MAX_TOML_BYTES:
        raise InputError(f"{path}: {size / 2**20:.0f} MiB, more than the {MAX_TOML_BYTES >> 20} MiB of a {what}; "
                         "check the path (sidprep reads TOML scene, job and study files of a few MiB)")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a text file; a {what} is TOML text") from None
    return parse_toml(text, path), text


#: deepest nesting of a TOML document (arrays, inline tables, dotted keys and table headers together);
#: sidprep's files nest 3-4 levels, and the parser and the readers after it recurse once per level
MAX_TOML_DEPTH = 64
#: largest TOML file read, bytes (a scene with long tables is a few MB)
MAX_TOML_BYTES = 64 << 20
#: TOML strings and comments, whose brackets and dots do not nest anything
_TOML_OPAQUE = re.compile(r'"""[\s\S]*?"""|\'\'\'[\s\S]*?\'\'\'|"(?:[^"\\\n]|\\.)*"|\'[^\'\n]*\'|#[^\n]*')
#: MAX_TOML_DEPTH dots in a row, with nothing between them that ends a key (a dotted key that deep)
_DEEP_DOTTED_KEY = re.compile(r"(?:\.[^\n=\[\]{},.]*){%d}" % MAX_TOML_DEPTH)


def toml_depth_problem(text: str) -> str | None:
    """Why ``text`` nests deeper than MAX_TOML_DEPTH (bracket depth of arrays, inline tables and
    table headers, or a dotted key with that many parts), or None; linear in the text, before the
    parser sees it (the parser recurses per level, and 200k dotted parts take it minutes)."""
    plain = _TOML_OPAQUE.sub('""', text)
    codes = np.frombuffer(plain.encode("utf-8", "replace"), dtype=np.uint8)
    step = np.zeros(len(codes), dtype=np.int64)
    step[(codes == ord("[")) | (codes == ord("{"))] = 1
    step[(codes == ord("]")) | (codes == ord("}"))] = -1
    depth = int(np.cumsum(step).max(initial=0))
    if depth > MAX_TOML_DEPTH:
        return f"arrays or tables nested {depth} levels deep"
    if _DEEP_DOTTED_KEY.search(plain):
        return f"a dotted key of more than {MAX_TOML_DEPTH} parts"
    return None


def parse_toml(text: str, source) -> dict:
    """The TOML document ``text`` (e.g. a scene kept in a results file); syntax errors and nesting
    deeper than MAX_TOML_DEPTH as one-line InputErrors naming ``source``."""
    deep = toml_depth_problem(text)
    if deep:
        raise InputError(f"{source}: {deep}, more than the {MAX_TOML_DEPTH} levels sidprep reads; a scene, job or "
                         "study file nests a few levels: fix the file")
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{source}: invalid TOML (TOML syntax error: {exc}); fix the syntax") from None


def read_toml(path, what: str = "file") -> dict:
    """The TOML document at ``path`` (read_toml_text without the text)."""
    return read_toml_text(path, what)[0]


def _matches(value, hint) -> bool:
    origin = typing.get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        return any(_matches(value, h) for h in typing.get_args(hint))
    if hint is type(None):
        return value is None
    if hint is float:
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    if hint is int:
        return isinstance(value, int) and not isinstance(value, bool)
    if hint in (tuple, list) or origin in (tuple, list):
        if not isinstance(value, (list, tuple)):
            return False
        args = [a for a in typing.get_args(hint) if a is not Ellipsis]
        return not args or all(_matches(v, args[0]) for v in value)
    if hint is dict or origin is dict:
        return isinstance(value, dict)
    return isinstance(value, hint)


def _finite(value) -> bool:
    """No nan / inf anywhere in ``value`` (numbers, lists and tables of them)."""
    if isinstance(value, float):
        return math.isfinite(value)
    if isinstance(value, (list, tuple)):
        return all(_finite(v) for v in value)
    if isinstance(value, dict):
        return all(_finite(v) for v in value.values())
    return True


def _describe(hint) -> str:
    origin = typing.get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        return " or ".join(_describe(h) for h in typing.get_args(hint) if h is not type(None))
    if origin in (tuple, list):
        args = [a for a in typing.get_args(hint) if a is not Ellipsis]
        return f"a list of {_describe(args[0]).split(' ', 1)[1]}s" if args else "a list"
    return _NAMES.get(hint, getattr(hint, "__name__", str(hint)))


def _frozen(value):
    """Lists -> tuples (recursively) so that the dataclass stays hashable and frozen."""
    if isinstance(value, list):
        return tuple(_frozen(v) for v in value)
    return value


def checked_table(table: dict, cls, source, *, context: str = "") -> dict:
    """``table`` checked against the fields of dataclass ``cls``: keys known, types right.

    Returns the table with lists turned into tuples, ready for ``cls(**table)``; ``source`` (the
    file) and ``context`` (e.g. "[job]") are named in every error.
    """
    hints = typing.get_type_hints(cls)
    where = f"{source}: {context + ' ' if context else ''}"
    unknown = sorted(set(table) - set(hints))
    if unknown:
        raise InputError(f"{where}unknown key(s) {', '.join(unknown)}; valid: {', '.join(sorted(hints))}")
    required = [f.name for f in fields(cls) if f.default is MISSING and f.default_factory is MISSING]
    missing = [k for k in required if k not in table]
    if missing:
        raise InputError(f"{where}missing key(s) {', '.join(missing)}")
    for key, value in table.items():
        if not _matches(value, hints[key]):
            raise InputError(f"{where}{key} = {value!r}: expected {_describe(hints[key])}")
        if not _finite(value):
            raise InputError(f"{where}{key} = {value!r}: numbers must be finite (TOML nan / inf are not)")
    return {k: _frozen(v) for k, v in table.items()}


def read_table(table: dict, cls, source, *, context: str = ""):
    """``cls(**checked_table(...))``: a typed frozen settings object from a TOML table."""
    return cls(**checked_table(table, cls, source, context=context))


def require_toml(path, what: str = "scene file", hint: str = "") -> Path:
    """Reject, before reading, a file that is not a TOML ``what`` (e.g. a mesh passed to ``simulate``)."""
    path = Path(path)
    if path.suffix.lower() != ".toml":
        raise InputError(f"{path}: not a {what} (a .toml file){'; ' + hint if hint else ''}")
    if not path.is_file():
        raise InputError(f"{path}: {what} not found; check the path")
    return path


class TomlTable:
    """One TOML table with typed getters; every error names the file, the table and the key."""

    def __init__(self, file: Path, where: str, data):
        self.file, self.where = file, where
        if not isinstance(data, dict):
            self.fail("", f"must be a table, got {type(data).__name__}", f"write it as [{where}] with key = value lines")
        self.data = data
        self.used: set[str] = set()

    def fail(self, key: str, problem: str, fix: str):
        at = f"[{self.where}] {key}: " if key else f"[{self.where}]: "
        raise InputError(f"{self.file}: {at}{problem}; {fix}")

    def has(self, key: str) -> bool:
        return key in self.data

    def raw(self, key: str, default=_REQUIRED, fix: str = ""):
        self.used.add(key)
        if key in self.data:
            return self.data[key]
        if default is _REQUIRED:
            self.fail(key, "missing", fix or f"add `{key} = ...` to [{self.where}]")
        return default

    def number(self, key: str, default=_REQUIRED, *, positive=False, nonnegative=False) -> float:
        v = self.raw(key, default)
        if v is None:
            return None
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
            self.fail(key, f"must be a number, got {v!r}", f"write e.g. `{key} = 1.0`")
        if positive and v <= 0:
            self.fail(key, f"must be > 0, got {v!r}", "give a positive value (SI units)")
        if nonnegative and v < 0:
            self.fail(key, f"must be >= 0, got {v!r}", "give a non-negative value (SI units)")
        return float(v)

    def integer(self, key: str, default=_REQUIRED) -> int:
        v = self.raw(key, default)
        if v is None:
            return None
        if isinstance(v, bool) or not isinstance(v, int):
            self.fail(key, f"must be an integer, got {v!r}", f"write e.g. `{key} = 1`")
        return v

    def string(self, key: str, default=_REQUIRED, choices=None) -> str:
        v = self.raw(key, default)
        if v is None:
            return None
        if not isinstance(v, str):
            self.fail(key, f"must be a string, got {v!r}", f'write e.g. `{key} = "..."`')
        if choices is not None and v not in choices:
            self.fail(key, f"unknown value {v!r}", f"use one of: {', '.join(choices)}")
        return v

    def boolean(self, key: str, default=False) -> bool:
        v = self.raw(key, default)
        if not isinstance(v, bool):
            self.fail(key, f"must be true or false, got {v!r}", f"write `{key} = true` or `{key} = false`")
        return v

    def array(self, key: str, default=_REQUIRED, shape=None) -> np.ndarray:
        """A numeric array; ``shape`` (tuple, -1 = any length) is checked."""
        v = self.raw(key, default)
        if v is None:
            return None
        try:
            a = np.asarray(v, dtype=float)
        except (TypeError, ValueError):
            a = None
        if a is None or a.dtype == object or not np.all(np.isfinite(a)) or any(isinstance(x, bool) for x in np.ravel(v)):
            self.fail(key, f"must be numbers, got {v!r}", f"write e.g. `{key} = [0.0, 0.0, 1.0]`")
        if shape is not None and (a.ndim != len(shape) or any(s not in (-1, n) for s, n in zip(shape, a.shape))):
            want = " x ".join("n" if s == -1 else str(s) for s in shape)
            self.fail(key, f"must have shape {want}, got {a.shape}", f"give {want} numbers")
        return a

    def vector(self, key: str, default=_REQUIRED) -> np.ndarray:
        return self.array(key, default, shape=(3,))

    def strings(self, key: str, default=_REQUIRED) -> tuple[str, ...]:
        v = self.raw(key, default)
        if not isinstance(v, list) or not all(isinstance(x, str) for x in v):
            self.fail(key, f"must be a list of strings, got {v!r}", f'write e.g. `{key} = ["a", "b"]`')
        return tuple(v)

    def path(self, key: str, default=_REQUIRED) -> Path | None:
        v = self.string(key, default)
        return None if v is None else (self.file.parent / v)

    def finish(self) -> None:
        """Reject keys nobody asked for (typos), suggesting the closest known key."""
        for key in self.data:
            if key not in self.used:
                close = difflib.get_close_matches(key, sorted(self.used), n=1)
                hint = f"did you mean `{close[0]}`?" if close else f"known keys here: {', '.join(sorted(self.used))}"
                self.fail(key, "unknown key", hint)


def subtables(file: Path, root: dict, name: str):
    """(name, TomlTable) for every [<name>.<entry>] table."""
    group = root.get(name, {})
    if not isinstance(group, dict):
        raise InputError(f"{file}: `{name}` must be a table of named entries; write [{name}.<entry name>] tables")
    return [(entry, TomlTable(file, f"{name}.{entry}", data)) for entry, data in group.items()]
