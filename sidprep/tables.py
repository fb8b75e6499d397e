"""One typed reader for the TOML tables of job, study and scene files.

Each table is checked against a frozen dataclass: unknown keys, missing required keys and values
of the wrong type give one-line InputErrors naming the file, the key and the expected type.
"""

from __future__ import annotations

import math
import types
import typing
from dataclasses import MISSING, fields
from pathlib import Path

from sidprep.errors import InputError

_NAMES = {float: "a number", int: "an integer", str: "a string", bool: "true or false",
          tuple: "a list", dict: "a table", type(None): "absent"}


def read_toml(path, what: str = "file") -> dict:
    """The TOML document at ``path``; "file not found" and syntax errors as one-line InputErrors."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: {what} not found; check the path")
    try:
        text = path.read_text()
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a text file; a {what} is TOML text") from None
    return parse_toml(text, path)


def parse_toml(text: str, source) -> dict:
    """The TOML document ``text`` (e.g. a scene kept in a results file); syntax errors as one-line
    InputErrors naming ``source``."""
    try:
        import tomllib
    except ImportError:  # Python 3.10
        import tomli as tomllib
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{source}: invalid TOML ({exc}); fix the syntax") from None


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
