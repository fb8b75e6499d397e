"""Shared fixtures: the validation meshes shipped (compressed) with the tests."""

import lzma
import shutil
from pathlib import Path

import pytest

DATA = Path(__file__).resolve().parent / "data" / "validation"


@pytest.fixture(scope="session")
def validation_dir(tmp_path_factory) -> Path:
    """A folder laid out as ../shared/validation (meshes/, decks/) with the shipped meshes
    decompressed (tests/data/validation/README.md)."""
    root = tmp_path_factory.mktemp("validation")
    for folder in ("meshes", "decks"):
        (root / folder).mkdir()
        for path in (DATA / folder).iterdir():
            if path.suffix == ".xz":
                (root / folder / path.stem).write_bytes(lzma.decompress(path.read_bytes()))
            else:
                shutil.copy(path, root / folder / path.name)
    return root
