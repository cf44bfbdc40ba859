"""app.io: output paths refused before any work, and a command's files written together or not at all."""

import re

import pytest

from app.errors import UserError
from app.io import INPUT_LIMITS, all_or_nothing, check_input, check_output, write_atomically


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


def test_the_longest_file_name_that_fits_is_written_and_one_more_byte_is_refused(tmp_path):
    """The name limit leaves room for the temporary file write_atomically renames into place: the longest name
    allowed is written (so its temporary name fit too), one byte more is refused before anything is written."""
    with pytest.raises(UserError, match=r"File name too long \(here at most 255 bytes per folder name") as refused:
        check_output(tmp_path / ("a" * 250 + ".json"))
    allowed = int(re.search(r", (\d+) for the file name", str(refused.value))[1])
    longest = tmp_path / ("b" * (allowed - len(".json")) + ".json")
    assert write_atomically(longest, "x").read_text() == "x"
    with pytest.raises(UserError, match="File name too long"):
        write_atomically(tmp_path / ("c" * (allowed + 1 - len(".json")) + ".json"), "x")
    assert [p.name for p in tmp_path.iterdir()] == [longest.name]


def test_an_input_over_its_limit_is_refused_before_it_is_read(tmp_path):
    scene = tmp_path / "big.yaml"
    scene.write_bytes(b"#" * (INPUT_LIMITS["scene file"] + 1))
    with pytest.raises(UserError, match=r"scene file big.yaml is too large: 1,048,577 bytes; the limit is 1 MB"):
        check_input(scene, "scene file")
    scene.write_bytes(b"#" * INPUT_LIMITS["scene file"])
    assert check_input(scene, "scene file") == scene
    with pytest.raises(UserError, match="trajectory file not found"):
        check_input(tmp_path / "none.json", "trajectory file")
    with pytest.raises(UserError, match="is not a file"):
        check_input(tmp_path, "trajectory file")
