"""Output files appear whole or not at all, with ordinary permissions."""

import os

import pytest

from sidprep.sid.io.atomic import atomic_path


def test_file_appears_only_when_complete_and_readable(tmp_path):
    target = tmp_path / "out.txt"
    with atomic_path(target) as tmp:
        tmp.write_text("done")
        assert not target.exists()
    assert target.read_text() == "done"
    assert os.stat(target).st_mode & 0o044  # group/other may read, as for any file a tool writes
    assert list(tmp_path.iterdir()) == [target]


def test_failure_leaves_nothing(tmp_path):
    target = tmp_path / "out.txt"
    with pytest.raises(RuntimeError):
        with atomic_path(target) as tmp:
            tmp.write_text("half")
            raise RuntimeError("interrupted")
    assert list(tmp_path.iterdir()) == []


def test_unwritable_folder_is_an_input_error(tmp_path):
    from sidprep.errors import InputError

    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(InputError, match="cannot write here"):
        with atomic_path(blocker / "out.txt"):
            pass
