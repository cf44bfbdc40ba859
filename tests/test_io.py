"""app.io: output paths refused before any work, and a command's files written together or not at all."""

import pytest

from app.errors import UserError
from app.io import all_or_nothing, check_output, write_atomically


def test_outputs_appear_together_when_the_block_ends(tmp_path):
    a, b = tmp_path / "a.json", tmp_path / "b.html"
    with all_or_nothing():
        write_atomically(a, "A")
        write_atomically(b, b"B")
        assert not a.exists() and not b.exists()  # staged beside their targets, not yet in place
    assert a.read_text() == "A" and b.read_text() == "B"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json", "b.html"]


def test_a_failure_in_the_block_leaves_nothing_behind(tmp_path):
    a = tmp_path / "a.json"
    a.write_text("old")
    with pytest.raises(UserError, match="is a file, not a folder"):
        with all_or_nothing():
            write_atomically(a, "new")
            write_atomically(tmp_path / "a.json" / "b.html", "B")  # the second output cannot be written
    assert a.read_text() == "old"  # the first one was not replaced either
    assert [p.name for p in tmp_path.iterdir()] == ["a.json"]  # no temporary file left


@pytest.mark.parametrize(
    "path, words",
    [
        ("{tmp}", "it is a folder"),
        ("{tmp}/missing/x.json", "does not exist"),
        ("{tmp}/file/x.json", "is a file, not a folder"),
        ("/proc/self/x.json", "/proc is a system folder"),
        ("/dev/null", "/dev is a system folder"),
        ("/sys/x", "/sys is a system folder"),
    ],
)
def test_paths_that_cannot_take_a_file_are_refused(tmp_path, path, words):
    (tmp_path / "file").write_text("x")
    with pytest.raises(UserError, match=words):
        check_output(path.format(tmp=tmp_path))


def test_missing_folders_may_be_made_under_a_writable_one(tmp_path):
    assert check_output(tmp_path / "a" / "b" / "store.sqlite", make_folders=True).name == "store.sqlite"
    (tmp_path / "file").write_text("x")
    with pytest.raises(UserError, match="is a file, not a folder"):
        check_output(tmp_path / "file" / "b" / "store.sqlite", make_folders=True)
    assert not (tmp_path / "a").exists()  # checking makes nothing
