"""A stored cell roadmap (app.planning.roadmap_file.read, `CellRoadmap.load`) against damaged and hostile files, and two
processes updating one roadmap file (`plan --roadmap F --update`).

Every fault is one UserError line (from the command line: `error: ...`, exit code 2, nothing written), at once: no
traceback, no hang, no gigabytes unpacked. The files are copies of one small bar-3link roadmap, built once for the
module, each damaged one way; app.bench.damaged_roadmaps holds the helpers that make and damage zip members (the
bad-input table runs a few of these cases for `bench audit` too).
"""

import json
import os
import queue
import re
import subprocess
import sys
import threading
import time
import zipfile

import numpy as np
import pytest

from app.bench.damaged_roadmaps import (
    deflate_bomb,
    invalid_deflate,
    npy,
    npy_claiming,
    patch_member,
    zip_entries,
    zipped,
)
from app.errors import UserError
from app.planning.cell import BuildSettings, CellRoadmap
from app.planning.roadmap_file import read

SCENE = "bar-3link"  # 5 coordinates: base x, y in [0, 100], three continuous joint angles


@pytest.fixture(scope="module")
def roadmap(oracles, tmp_path_factory):
    """(path, header, arrays) of a small bar-3link roadmap, saved once for the module."""
    path = tmp_path_factory.mktemp("roadmap") / "cell.npz"
    CellRoadmap.build(oracles(SCENE), BuildSettings(nodes=60, seed=0)).save(path)
    with np.load(path) as data:  # the file as written, trusted here
        arrays = {name: data[name] for name in data.files}
    return path, json.loads(str(arrays.pop("header"))), arrays


def _members(roadmap, changes=None, **arrays) -> dict[str, bytes]:
    """The roadmap's members as npy bytes, with header entries `changes` and `arrays` (arrays or npy bytes; `header`
    too) replaced."""
    _, made, stored = roadmap
    members = {"header": np.array(json.dumps({**made, **(changes or {})})), **stored, **arrays}
    return {f"{name}.npy": m if isinstance(m, bytes) else npy(m) for name, m in members.items()}


def _file(tmp_path, roadmap, changes=None, name="damaged.npz", **arrays):
    """A copy of the roadmap with header entries `changes` and arrays replaced (the stored fingerprint kept)."""
    path = tmp_path / name
    path.write_bytes(zipped(_members(roadmap, changes, **arrays)))
    return path


@pytest.fixture
def unpacked(monkeypatch):
    """Bytes unpacked from zip members while the test runs (zipfile's member reads): what a test counts instead of
    timing a read, so that no verdict depends on the machine's speed."""
    count = [0]
    read_member = zipfile.ZipExtFile.read

    def counted(self, n=-1):
        data = read_member(self, n)
        count[0] += len(data)
        return data

    monkeypatch.setattr(zipfile.ZipExtFile, "read", counted)
    return count


def _refused(match: str, call, *args) -> str:
    """`call(*args)` raises one UserError line holding `match` (a regular expression); returns the line."""
    with pytest.raises(UserError, match=match) as refused:
        call(*args)
    message = str(refused.value)
    assert "\n" not in message and len(message) < 400, message
    return message


def _load(oracles):
    return lambda path: CellRoadmap.load(path, oracles(SCENE))


# ---- the zip and its compression ----------------------------------------------------------------------------------
def test_the_file_as_saved_reads_back_array_for_array(roadmap):
    path, header, arrays = roadmap
    theirs, mine = read(path)
    assert theirs["fingerprint"] == header["fingerprint"] and isinstance(theirs["revision"], str)
    assert mine.keys() == arrays.keys()
    for key in arrays:
        assert np.array_equal(mine[key], arrays[key]) and mine[key].dtype == arrays[key].dtype, key


def test_damaged_compressed_data_a_checksum_or_a_member_header_are_one_line(roadmap, tmp_path):
    data = roadmap[0].read_bytes()
    cases = {
        "Error -3 while decompressing data: invalid block type": invalid_deflate(data, "Q.npy"),  # zlib.error
        "Bad CRC-32 for file 'ends.npy'": patch_member(data, "ends.npy", crc=12345),
        "Bad magic number for file header": _local_header_broken(data, "kinds.npy"),  # zipfile.BadZipFile
        "claims shape .* but holds": patch_member(data, "Q.npy", file_size=zip_info(data, "Q.npy").file_size + 8),
    }
    for match, damaged in cases.items():
        path = tmp_path / "damaged.npz"
        path.write_bytes(damaged)
        _refused(f"not a whole roadmap file \\(truncated or corrupt\\?\\): .*{match}", read, path)


def test_compressed_data_that_ends_early_is_one_line(roadmap, tmp_path):
    """A member's compressed size cut in the zip's directory: its deflate stream ends before its data."""
    data = roadmap[0].read_bytes()
    info = zip_info(data, "Q.npy")
    path = tmp_path / "short.npz"
    path.write_bytes(patch_member(data, "Q.npy", compress_size=info.compress_size // 2))
    _refused("not a whole roadmap file", read, path)


def test_a_missing_member_is_named(roadmap, tmp_path):
    members = _members(roadmap)
    del members["progress.npy"]
    path = tmp_path / "missing.npz"
    path.write_bytes(zipped(members))
    _refused("is not a roadmap file of this planner: it lacks progress$", read, path)


def test_a_member_the_format_does_not_have_or_holds_twice_is_refused(roadmap, tmp_path):
    members = _members(roadmap)
    path = tmp_path / "more.npz"
    path.write_bytes(zipped({**members, "payload.npy": npy(np.zeros(3))}))
    _refused("its zip directory lists 13 members in .* bytes, not a roadmap's", read, path)
    del members["counters.npy"]
    path.write_bytes(zipped({**members, "payload.npy": npy(np.zeros(3))}))
    _refused("holds a member payload.npy that a roadmap file does not", read, path)
    twice = tmp_path / "twice.npz"
    with zipfile.ZipFile(twice, "w") as archive, pytest.warns(UserWarning, match="Duplicate name"):
        for name, data in [*members.items(), ("k.npy", npy(np.array(5)))]:
            archive.writestr(name, data)
    _refused("a member is in its zip twice", read, twice)


def test_a_truncated_file_is_one_line_wherever_it_is_cut(roadmap, tmp_path):
    data = roadmap[0].read_bytes()
    path = tmp_path / "cut.npz"
    for length in (0, 3, 4, 30, 200, len(data) // 3, len(data) // 2, len(data) - 22, len(data) - 1):
        path.write_bytes(data[:length])
        _refused("not a whole roadmap file|not a roadmap file|not an .npz archive", read, path)


def test_any_bit_flipped_is_read_as_it_was_or_refused_in_one_line(roadmap, tmp_path, recwarn):
    """A bit flipped anywhere (compressed data, member headers, the zip's directory): the file is refused in one
    line, or reads back as it was (a flip in a field nothing reads, such as a member's time stamp); and nothing
    else is said (Python's parser warns of what it finds in a damaged npy header)."""
    path, _, arrays = roadmap
    data = path.read_bytes()
    damaged = tmp_path / "flipped.npz"
    refused = 0
    for position in np.linspace(0, len(data) - 1, 160).astype(int):
        flipped = bytearray(data)
        flipped[position] ^= 1 << (position % 8)
        damaged.write_bytes(bytes(flipped))
        try:
            _, mine = read(damaged)
        except UserError as exc:
            assert "\n" not in str(exc)
            refused += 1
            continue
        assert all(np.array_equal(mine[key], arrays[key]) for key in arrays), position
    assert refused > 100 and not recwarn.list


# ---- sizes: refused before anything is unpacked ---------------------------------------------------------------------
def test_a_decompression_bomb_is_refused_unread(roadmap, tmp_path, unpacked):
    """Q.npy inflating to 4 GB (a real deflate stream, 4 MB in the file, under an npy header numpy would take):
    refused from the zip's directory at once, not unpacked."""
    head = npy_claiming((500_000_000,), "<f8", b"")
    size = len(head) + 4_000_000_000
    members = _members(roadmap)
    del members["Q.npy"]
    path = tmp_path / "bomb.npz"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, data in members.items():
            archive.writestr(name, data)
        archive.writestr(zipfile.ZipInfo("Q.npy"), deflate_bomb(head, size), zipfile.ZIP_STORED)
    data = patch_member(path.read_bytes(), "Q.npy", method=zipfile.ZIP_DEFLATED, file_size=size)
    path.write_bytes(data)
    assert len(data) < 5 << 20 and zip_info(data, "Q.npy").file_size == size
    _refused(r"is too large to load: its member Q.npy would unpack to 3.73 GiB, over the 1 GiB limit", read, path)
    assert unpacked[0] < 1 << 20  # nothing of the 4 GB


def test_members_each_within_the_limit_but_too_large_together_are_refused_unread(roadmap, tmp_path):
    data = roadmap[0].read_bytes()
    for name in ("ends.npy", "alive.npy", "checked.npy"):
        data = patch_member(data, name, file_size=(1 << 30) - 1)
    path = tmp_path / "large.npz"
    path.write_bytes(data)
    _refused("is too large to load: it would unpack to 3 GiB, over the 2 GiB limit", read, path)


def test_an_npy_header_claiming_more_rows_than_its_member_holds_is_refused(roadmap, tmp_path):
    Q = roadmap[2]["Q"]
    path = _file(tmp_path, roadmap, Q=npy_claiming((10**12, 5), "<f8", Q.tobytes()))
    _refused(r"its member Q.npy claims shape \(1000000000000, 5\) of <f8 .* but holds 2,400 bytes", read, path)
    fewer = _file(tmp_path, roadmap, Q=npy_claiming((10, 5), "<f8", Q.tobytes()))
    _refused(r"claims shape \(10, 5\) of <f8 \(400 bytes\) but holds 2,400 bytes", read, fewer)


def test_a_member_that_inflates_past_its_declared_size_is_read_no_further(roadmap, tmp_path, unpacked):
    """Compressed data longer than the zip's directory says the member is: what is declared is read, never a byte
    more (the rest is not unpacked), and a member header that then disagrees with the array is refused."""
    data = npy(roadmap[2]["Q"])
    members = _members(roadmap)
    members["Q.npy"] = data + b"\0" * 50_000_000  # 50 MB more, a few kB compressed
    zipped_more = zipped(members)
    path = tmp_path / "more.npz"
    path.write_bytes(patch_member(zipped_more, "Q.npy", file_size=len(data), crc=zipfile.crc32(data)))
    _, arrays = read(path)
    assert np.array_equal(arrays["Q"], roadmap[2]["Q"])
    declared = sum(info.file_size for info in zipfile.ZipFile(path).infolist())
    assert unpacked[0] <= declared + len(members)  # (a byte past each member's end: there is none) not the 50 MB


@pytest.mark.parametrize(
    "member, content, match",
    [
        ("Q", npy_claiming((60, 5), "|O", b"\0" * 2400), r"Q.npy holds \|O values"),  # objects: never unpickled
        ("Q", np.zeros((60, 5), np.int64), r"Q.npy holds <i8 values of shape \(60, 5\)"),
        ("Q", np.zeros(300), r"Q.npy holds <f8 values of shape \(300,\)"),
        ("Q", npy_claiming((-60, 5), "<f8", b""), r"Q.npy holds <f8 values of shape \(-60, 5\)"),
        ("alive", np.ones(10, np.int8), "alive.npy holds |i1 values"),
        ("k", np.array(2.5), "k.npy holds <f8 values"),
        ("k", np.array([10]), r"k.npy holds <i8 values of shape \(1,\)"),
        ("kind_names", np.array([1, 2]), "kind_names.npy holds <i8 values"),
        ("header", np.array(b"{}"), "header.npy holds |S2 values"),
        ("ends", npy_claiming((3, 2), [("a", "<i8"), ("b", "<i8")], b"\0" * 96), "ends.npy holds |V16 values"),
    ],
)
def test_a_member_of_the_wrong_kind_or_shape_is_refused_before_its_data_is_read(
    roadmap, tmp_path, member, content, match
):
    _refused(
        "is not a roadmap file of this planner: its member " + match,
        read,
        _file(tmp_path, roadmap, **{member: content}),
    )


# ---- every field ----------------------------------------------------------------------------------------------------
def _changed(roadmap, key, change):
    array = roadmap[2][key].copy()
    change(array)
    return array


@pytest.mark.parametrize(
    "key, change, match",
    [
        ("Q", lambda Q: Q.__setitem__((3, 2), np.nan), "a node has a coordinate that is not a finite number"),
        ("k", lambda k: k.fill(-5), r"its k is -5; k is 0 \(k-PRM\*'s\) or from 1 to 1000"),
        ("k", lambda k: k.fill(10**9), "its k is 1000000000"),
        ("resolution", lambda r: r.fill(np.nan), "its resolution nan is not a positive finite number"),
        ("resolution", lambda r: r.fill(-1), "its resolution -1 is not a positive finite number"),
        ("counters", lambda c: c.fill(-1), "its edge counters are not two numbers of at least 0"),
        ("progress", lambda p: p.__setitem__(4, -3), r"an edge's progress \(points of it checked\) is negative"),
        ("kinds", lambda kinds: kinds.__setitem__(7, 3), "a node's kind is not one of the 3 kinds named"),
        ("kinds", lambda kinds: kinds.__setitem__(7, -1), "a node's kind is not one of the 3 kinds named"),
        (
            "ends",
            lambda ends: ends.__setitem__((5, 1), 60),
            r"an edge ends at a node that is not there \(nodes 0 to 59\)",
        ),
        ("ends", lambda ends: ends.__setitem__((5, 0), -1), "an edge ends at a node that is not there"),
        (
            "ends",
            lambda ends: ends.__setitem__(5, ends[5, ::-1].copy()),
            r"an edge is not stored as \(smaller node, larger node\)",
        ),
        (
            "ends",
            lambda ends: ends.__setitem__((5, 1), ends[5, 0]),
            r"an edge is not stored as \(smaller node, larger node\)",
        ),
        ("ends", lambda ends: ends.__setitem__(5, ends[6]), "an edge is stored twice"),
    ],
)
def test_a_field_out_of_range_is_refused(roadmap, tmp_path, key, change, match):
    path = _file(tmp_path, roadmap, **{key: _changed(roadmap, key, change)})
    _refused(f"roadmap {path} is inconsistent: {match}", read, path)


@pytest.mark.parametrize(
    "arrays, match",
    [
        ({"kinds": np.zeros(59, np.int16)}, "59 node kinds for 60 nodes"),
        ({"alive": np.ones(3, bool)}, "3 values of alive for"),
        ({"progress": np.zeros(2, np.int64)}, "2 values of progress for"),
        ({"ends": np.zeros((4, 3), np.int64)}, r"its edges are not pairs of nodes \(shape \(4, 3\)\)"),
        ({"counters": np.zeros(3, np.int64)}, "its edge counters are not two numbers"),
        ({"kind_names": np.array(["uniform", "magic", "goal"])}, "its node kinds .* are not distinct names among"),
        ({"kind_names": np.array(["uniform", "uniform", "goal"])}, "its node kinds .* are not distinct names among"),
    ],
)
def test_arrays_that_disagree_are_refused(roadmap, tmp_path, arrays, match):
    _refused(f"is inconsistent: {match}", read, _file(tmp_path, roadmap, **arrays))


@pytest.mark.parametrize(
    "header, match",
    [
        (
            {"provenance": {"builds": [], "queries": -1}},
            "provenance queries must be a whole number of at least 0, got -1",
        ),
        ({"provenance": {"builds": [], "queries": "many"}}, "provenance queries must be .*, got 'many'"),
        ({"provenance": {"builds": [], "queries": True}}, "provenance queries must be .*, got True"),
        ({"provenance": {"builds": [], "queries": 1.5}}, "provenance queries must be .*, got 1.5"),
        ({"provenance": {"builds": {}, "queries": 0}}, "provenance builds must be a list of build records, got {}"),
        ({"provenance": {"builds": [1], "queries": 0}}, "build record 0 must hold"),
        ({"provenance": {"builds": [{"nodes": "x"}], "queries": 0}}, "build record 0 must hold"),
        ({"provenance": {"builds": [], "queries": 0, "covered": "all"}}, "provenance covered must be a list"),
        ({"provenance": {"builds": [], "queries": 0, "covered": [{"what": "query"}]}}, "covered record 0 must hold"),
        (
            {"provenance": {"builds": [], "queries": 0, "covered": [{"what": 1, "solved": 1, "collision_checks": 5}]}},
            "covered record 0 must hold",
        ),
        ({"fingerprint": {"robot": 5}}, "its fingerprint must name each part's hash as text"),
        ({"scene": ["bar"]}, "its scene must be a name"),
        ({"revision": 7}, "its revision must be a short text"),
    ],
)
def test_a_header_field_of_the_wrong_type_is_refused(roadmap, tmp_path, header, match):
    _refused(f"has a malformed header: {match}", read, _file(tmp_path, roadmap, header))


def test_a_build_record_with_seconds_that_are_not_a_number_is_refused(roadmap, tmp_path):
    build = dict(roadmap[1]["provenance"]["builds"][0])
    for seconds in ("3 s", float("nan"), float("inf"), -1.0, None):
        header = {"provenance": {"builds": [{**build, "seconds": seconds}], "queries": 0}}
        _refused("build record 0 must hold", read, _file(tmp_path, roadmap, header))


@pytest.mark.parametrize(
    "header, match",
    [
        ({"version": "2"}, "has format version '2', this planner reads 2"),
        ({"version": 3}, "has format version 3, this planner reads 2"),
        ({"format": "something else"}, "is not a roadmap file of this planner"),
        ({"fingerprint": ["robot"]}, "lacks its fingerprint or provenance"),
        ({"provenance": None}, "lacks its fingerprint or provenance"),
    ],
)
def test_a_header_of_another_format_is_refused(roadmap, tmp_path, header, match):
    _refused(match, read, _file(tmp_path, roadmap, header))


def test_a_header_that_is_not_json_or_nested_past_any_parser_is_refused(roadmap, tmp_path):
    for text in ("{", "[" * 200_000 + "]" * 200_000, "null"):
        path = _file(tmp_path, roadmap, header=np.array(text))
        _refused("is not a roadmap file of this planner", read, path)


# ---- what depends on the cell (load) --------------------------------------------------------------------------------
@pytest.mark.parametrize("columns", [4, 6])
def test_nodes_of_another_dimension_are_refused(roadmap, tmp_path, oracles, columns):
    Q = roadmap[2]["Q"]
    Q = Q[:, :columns] if columns < 5 else np.hstack([Q, np.zeros((len(Q), columns - 5))])
    path = _file(tmp_path, roadmap, Q=Q)
    _refused(f"holds nodes of {columns} coordinates; this cell's robot has 5", _load(oracles), path)


def test_nodes_outside_the_bounds_are_refused_and_continuous_angles_wrap(roadmap, tmp_path, oracles):
    space = oracles(SCENE).space
    outside = _changed(roadmap, "Q", lambda Q: Q.__setitem__((9, 0), 150.0))
    path = _file(tmp_path, roadmap, Q=outside)
    _refused(rf"holds node 9 outside this cell's bounds: {space.names[0]}=150 not in \[0, 100\]", _load(oracles), path)
    # A whole turn more on a continuous joint is the same configuration; 1e-12 past a bound is on it.
    turned = _changed(
        roadmap, "Q", lambda Q: (Q.__setitem__((9, 2), Q[9, 2] + 2 * np.pi), Q.__setitem__((8, 0), 100 + 1e-12))
    )
    cell = _load(oracles)(_file(tmp_path, roadmap, Q=turned))
    assert np.allclose(cell.graph.Q[9], roadmap[2]["Q"][9]) and cell.graph.Q[8, 0] == 100.0


@pytest.mark.parametrize("resolution", [1e9, 0.25, 0.5000001])
def test_a_resolution_other_than_the_cells_is_refused(roadmap, tmp_path, oracles, resolution):
    path = _file(tmp_path, roadmap, resolution=np.array(resolution))
    message = f"says its edges were checked at resolution {resolution:g}; this cell checks at 0.5"
    _refused(re.escape(message), _load(oracles), path)


def test_an_edge_progress_past_its_points_is_refused(roadmap, tmp_path, oracles):
    """An undecided edge's progress counts its points a check found free: a larger count would skip them all."""
    _, _, arrays = roadmap
    space = oracles(SCENE).space
    a, b = arrays["ends"][0]
    inside = int(space.segments(arrays["Q"][a], arrays["Q"][b])[0]) - 1
    at_most = _changed(roadmap, "progress", lambda p: p.__setitem__(0, inside))
    assert len(_load(oracles)(_file(tmp_path, roadmap, progress=at_most))) == 60
    past = _changed(roadmap, "progress", lambda p: p.__setitem__(0, inside + 1))
    _refused(
        "an edge's progress counts more points than it has", _load(oracles), _file(tmp_path, roadmap, progress=past)
    )


# ---- not a file -----------------------------------------------------------------------------------------------------
def _within(seconds: float, call, *args):
    """call(*args) in a thread that may not take longer than `seconds` (a read blocked on a pipe would hang the test
    run otherwise); what it raised."""
    raised = []
    thread = threading.Thread(target=lambda: raised.append(_catch(call, *args)), daemon=True)
    thread.start()
    thread.join(seconds)
    assert not thread.is_alive(), f"{call.__name__} blocked"
    return raised[0]


def _catch(call, *args):
    try:
        call(*args)
    except Exception as exc:  # noqa: BLE001 (the test asks what it was)
        return exc
    return None


def test_a_named_pipe_a_folder_or_a_device_is_refused_without_blocking(tmp_path, oracles):
    pipe = tmp_path / "pipe.npz"
    os.mkfifo(pipe)
    for path, kind in ((pipe, "a named pipe \\(FIFO\\)"), (tmp_path, "a folder"), ("/dev/null", "a device")):
        for call in (read, _load(oracles)):
            raised = _within(10, call, path)
            assert isinstance(raised, UserError) and "\n" not in str(raised)
            assert re.fullmatch(f"roadmap {path} is {kind}, not a file", str(raised)), raised


# ---- the command line -----------------------------------------------------------------------------------------------
def _damaged_files(roadmap, tmp_path) -> dict[str, str]:
    data = roadmap[0].read_bytes()
    folder = tmp_path / "files"
    folder.mkdir()
    files = {
        "flipped.npz": invalid_deflate(data, "Q.npy"),
        "six.npz": zipped(_members(roadmap, Q=np.zeros((60, 6)))),
        "k.npz": zipped(_members(roadmap, k=np.array(-5))),
        "queries.npz": zipped(_members(roadmap, {"provenance": {"builds": [], "queries": "many"}})),
    }
    for name, content in files.items():
        (folder / name).write_bytes(content)
    return {
        "flipped.npz": "Error -3 while decompressing data",
        "six.npz": "holds nodes of 6 coordinates; this cell's robot has 5",
        "k.npz": "its k is -5",
        "queries.npz": "provenance queries must be a whole number",
    }, folder


def _snapshot(folder):
    return {p.name: (p.stat().st_size, p.stat().st_mtime_ns) for p in sorted(folder.iterdir())}


@pytest.mark.parametrize("update", [False, True])
def test_a_damaged_roadmap_is_one_line_from_the_command_line_and_nothing_is_written(
    cli, one_line_error, roadmap, tmp_path, update
):
    fragments, folder = _damaged_files(roadmap, tmp_path)
    before = _snapshot(folder)
    for name, fragment in fragments.items():
        argv = ["plan", SCENE, "--roadmap", folder / name, *(["--update"] if update else [])]
        line = one_line_error(cli(*argv), 2)
        assert fragment in line, line
        answer = cli(*argv, "--json")
        assert answer.returncode == 2 and answer.stderr.count("\n") == 1 and "Traceback" not in answer.stderr
        [obj] = [json.loads(text) for text in answer.stdout.splitlines()]
        assert obj["success"] is False and obj["exit_code"] == 2 and fragment in obj["error"]["message"]
    assert _snapshot(folder) == before  # nothing written, no lock file left


def test_a_named_pipe_given_as_the_roadmap_is_refused_by_the_command(run_app, one_line_error, tmp_path):
    pipe = tmp_path / "pipe.npz"
    os.mkfifo(pipe)
    result = run_app("plan", SCENE, "--roadmap", pipe, "--json", timeout=120)
    line = one_line_error(result, 2)
    assert "is a named pipe (FIFO), not a file" in line
    [obj] = [json.loads(text) for text in result.stdout.splitlines()]
    assert obj["exit_code"] == 2


# ---- a forged edge --------------------------------------------------------------------------------------------------
def test_a_forged_edge_through_the_wall_marked_checked_and_proved_is_never_a_path(oracles, tmp_path, cli):
    """One edge row added to a whole roadmap file, joining a node on either side of the wall by a straight edge that
    collides, marked alive, checked and proved, the stored fingerprint kept: the answer fails, or is a path that does
    not use that edge and whose trajectory is collision-free at every sample and along the path."""
    oracle = oracles(SCENE)
    space, checker = oracle.space, oracle.context()
    path = tmp_path / "forged.npz"
    CellRoadmap.build(oracle, BuildSettings(nodes=400, seed=0)).save(path)
    with np.load(path) as data:
        arrays = {name: data[name] for name in data.files}
    Q, ends = arrays["Q"], arrays["ends"]
    scene = oracle.scene
    left = np.argsort(space.distance(Q, scene.start))[:20]
    right = np.argsort(space.distance(Q, scene.goal))[:20]
    known = {tuple(e) for e in ends.tolist()}
    pairs = [(min(a, b), max(a, b)) for a in left for b in right if (min(a, b), max(a, b)) not in known]
    A, B = Q[[p[0] for p in pairs]], Q[[p[1] for p in pairs]]
    colliding = np.flatnonzero(~checker.edges_free(A, B, space.resolution, ends_free=True))
    assert len(colliding), "no straight edge from start's side to goal's side collides"
    a, b = pairs[colliding[0]]
    arrays["ends"] = np.vstack([ends, [[a, b]]])
    for key in ("alive", "checked", "proved"):
        arrays[key] = np.append(arrays[key], True)
    arrays["progress"] = np.append(arrays["progress"], 0)
    path.write_bytes(zipped({f"{name}.npy": npy(array) for name, array in arrays.items()}))

    cell = CellRoadmap.load(path, oracle)  # the file is whole and sound: only its verdict is a lie
    row = cell.graph._rows[int(a) << 32 | int(b)]
    assert cell.graph._alive[row] and cell.graph._checked[row] and not cell.graph.proved
    try:
        result = cell.solve()
    except UserError:
        result = None
    assert not cell.graph._alive[row]  # the search took the short cut, and the certificate found it out
    if result is not None:
        assert (a, b) not in {(min(u, v), max(u, v)) for u, v in zip(result.path_nodes, result.path_nodes[1:])}
        _assert_free(oracle, result)
    answer = cli("plan", SCENE, "--roadmap", path, "--json")
    assert answer.returncode in (0, 1), answer.stderr
    if answer.returncode == 0:
        assert json.loads(answer.stdout)["success"]


def _assert_free(oracle, result):
    space = oracle.space
    trajectory = result.trajectory
    assert oracle.context().are_free(space.wrap(trajectory.positions)).all()
    fine = np.vstack([space.interpolate(p, q, space.resolution / 8) for p, q in zip(result.path, result.path[1:])])
    assert oracle.context().are_free(fine).all()


# ---- two processes updating one roadmap -----------------------------------------------------------------------------
def test_a_save_over_a_file_written_since_it_was_loaded_is_refused(roadmap, tmp_path, oracles):
    path = tmp_path / "shared.npz"
    path.write_bytes(roadmap[0].read_bytes())
    first, second = _load(oracles)(path), _load(oracles)(path)
    first.solve()
    first.save(path)
    second.solve()
    before = path.read_bytes()
    _refused("has been written .* since this roadmap was loaded from it: not written over", second.save, path)
    assert path.read_bytes() == before and sorted(p.name for p in tmp_path.iterdir()) == ["shared.npz"]
    first.save(path)  # its own write was the last: it may write again
    assert CellRoadmap.load(path, oracles(SCENE)).provenance["queries"] == roadmap[1]["provenance"]["queries"] + 1


def _plan_update(path, seed: int, *extra) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "app", "plan", SCENE, "--roadmap", str(path), "--update", "--seed", str(seed), *extra],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        stdin=subprocess.DEVNULL,
        text=True,
    )


def test_an_update_waits_while_another_holds_the_roadmap_then_adds_to_it(roadmap, tmp_path):
    """The test holds the roadmap's lock as a process updating it would: `plan --update` says once that it waits,
    and once the lock is free loads what is there and writes its update back."""
    from app.io import exclusive

    path = tmp_path / "shared.npz"
    path.write_bytes(roadmap[0].read_bytes())
    with exclusive(path):
        process = _plan_update(path, 1)
        lines = queue.Queue()
        reader = threading.Thread(target=lambda: [lines.put(line) for line in process.stderr], daemon=True)
        reader.start()
        said = []
        while not said or "waiting for roadmap" not in said[-1]:
            said.append(lines.get(timeout=120))  # (the process's lines on stderr, until it says it waits)
        assert said[-1] == f"waiting for roadmap {path}: another process is updating it\n"
        time.sleep(0.5)
        assert process.poll() is None  # still waiting
        queries = read(path)[0]["provenance"]["queries"]
    process.wait(timeout=120)
    reader.join(10)
    err = "".join(said) + "".join(lines.queue)
    assert process.returncode == 0, err
    assert err.count("waiting for roadmap") == 1 and f"wrote {path}" in err
    assert read(path)[0]["provenance"]["queries"] == queries + 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["shared.npz"]  # the lock file is gone


def test_two_updates_at_once_both_reach_the_file(roadmap, tmp_path):
    path = tmp_path / "shared.npz"
    path.write_bytes(roadmap[0].read_bytes())
    queries = read(path)[0]["provenance"]["queries"]
    processes = [_plan_update(path, seed) for seed in (1, 2)]
    answers = [process.communicate(timeout=180) for process in processes]
    for process, (_, err) in zip(processes, answers):
        assert process.returncode == 0, err
        assert f"wrote {path}" in err and "Traceback" not in err
    assert read(path)[0]["provenance"]["queries"] == queries + 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["shared.npz"]


# ---- helpers --------------------------------------------------------------------------------------------------------
def zip_info(data: bytes, name: str) -> zipfile.ZipInfo:
    import io

    return zipfile.ZipFile(io.BytesIO(data)).getinfo(name)


def _local_header_broken(data: bytes, name: str) -> bytes:
    local = zip_entries(data)[name][1]
    return data[:local] + b"XX" + data[local + 2 :]
