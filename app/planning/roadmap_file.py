"""A cell roadmap's file: reading it, checking every field, what it holds (`summary`), and the fingerprint of the
cell its verdicts belong to. `CellRoadmap.save`, `load` and `info` (app.planning.cell) are the API; this module is
what they stand on.

The file is numpy's .npz, a zip of arrays read without pickle: nodes and edges are arrays, so a large roadmap loads
in milliseconds; loading a file from elsewhere cannot run code; and the zip's checksums reveal a damaged file. A
JSON header inside it holds the format version, the fingerprint, where the roadmap came from and its revision (a
random name each save gives it).

A file that is not whole or not sound is refused in one line (UserError), before anything is planned: `read` takes
only a regular file (a named pipe or a device is refused without blocking on it), looks at the zip's directory
before it unpacks anything (members and their sizes: a decompression bomb is refused unread), unpacks each array
through its npy header (shape and dtype kind must be the expected ones and agree with the member's size), stops at
the first byte more than a member declares, and checks every field (counts, ranges, edges ordered and unique, the
header's types); `check_cell` then checks what depends on the cell (coordinates per node, bounds, resolution, how
far an unfinished edge check got).

`fingerprint(oracle)` hashes everything a stored verdict depends on, in parts, so that `CellRoadmap.load` can refuse
a file built for another cell and say what differs.
"""

from __future__ import annotations

import contextlib
import hashlib
import importlib.metadata
import json
import math
import os
import stat
import struct
import warnings
import zipfile
import zlib
from pathlib import Path

import numpy as np

from app.errors import UserError
from app.scene.shapes import hull_vertices

FORMAT, FORMAT_VERSION = "narrow-passage-planner cell roadmap", 2
# The largest roadmap file read: far above any roadmap a cell needs (10^6 nodes of 9 coordinates are 70 MB).
MAX_FILE_BYTES = 2 << 30
# What a roadmap file may unpack to, looked at in the zip's directory before anything is unpacked (a 4 GB
# decompression bomb in a 4 MB file is refused unread): each member (npy header included), and all together. Far above
# any roadmap a cell needs -- `roadmap build --nodes` stops at 10^6 nodes, whose 9 coordinates are 72 MB and whose
# k-PRM* edges (k = 42) hold 1.1 GB of ends, flags and progress -- and below what would exhaust a machine's memory.
MAX_MEMBER_BYTES = 1 << 30
MAX_DATA_BYTES = 2 << 30
# Each member of the file: the dtype kinds its array may have (numpy's: f float, i/u whole numbers, b bool, U text;
# never an object), its number of dimensions, and the most bytes it may unpack to.
_MEMBERS = {
    "header": ("U", 0, 16 << 20),  # the JSON header: format, fingerprint, provenance, revision
    "Q": ("f", 2, MAX_MEMBER_BYTES),  # nodes: configurations
    "kind_names": ("U", 1, 1 << 16),
    "kinds": ("iu", 1, MAX_MEMBER_BYTES),  # per node, an index into kind_names
    "ends": ("iu", 2, MAX_MEMBER_BYTES),  # per edge, its nodes (smaller first)
    "alive": ("b", 1, MAX_MEMBER_BYTES),
    "checked": ("b", 1, MAX_MEMBER_BYTES),
    "proved": ("b", 1, MAX_MEMBER_BYTES),
    "progress": ("iu", 1, MAX_MEMBER_BYTES),
    "k": ("iu", 0, 1 << 12),
    "resolution": ("f", 0, 1 << 12),
    "counters": ("iu", 1, 1 << 12),
}
# The neighbours per node a roadmap may connect (0 in a file: k-PRM*'s, which grows with the roadmap): the command
# line's limit for -k. k-PRM*'s own k is 42 at 10^6 nodes in 9 dimensions; a build makes k candidate edges per node and
# checks every one, so a larger k never finishes, and a query's neighbour arrays (nodes x k) would take gigabytes.
MAX_K = 1000
# Bytes read from a member at a time.
_CHUNK = 4 << 20
# The modules whose code decides a verdict (a collision answer, an edge check, a certificate): a roadmap saved by
# other code is not trusted.
_VERDICT_MODULES = (
    "checking/oracle.py",
    "checking/context.py",
    "checking/certify.py",
    "checking/motion_bound.py",
    "checking/shape_gaps.py",
    "checking/kernels.py",
    "checking/end_distances.py",
    "checking/kinematics.py",
    "scene/cspace.py",
)
FINGERPRINT_PARTS = ("robot", "environment", "collision pairs", "configuration space", "checker code")


def read(path) -> tuple[dict, dict]:
    """(header, arrays) of a roadmap file, checked to be whole and sound in every field that does not depend on the
    cell (module docstring); one UserError naming the fault otherwise."""
    path = Path(path)
    arrays = _unpack(path)
    header = _header(path, arrays.pop("header"))
    _check_arrays(path, arrays)
    return header, arrays


def read_header(path) -> dict:
    """The header of the roadmap file at `path` alone, checked as `read` checks it (its scene, its provenance)."""
    return _header(Path(path), _unpack(Path(path), only=("header",))["header"])


def stored_revision(path) -> str | None | object:
    """The revision in the header of the roadmap file at `path` (None: saved before revisions were written); a
    new object, equal to nothing, when there is no whole roadmap file there."""
    try:
        return read_header(path).get("revision")
    except UserError:
        return object()


class _Refused(Exception):
    """A fault in a roadmap file, as the end of one line: `_unpack` names the file and what is wrong with it (`what`:
    a key of _REFUSED) before it."""

    def __init__(self, message: str, what: str = "foreign"):
        super().__init__(message)
        self.what = what


_REFUSED = {
    "foreign": "is not a roadmap file of this planner",
    "damaged": "is not a whole roadmap file (truncated or corrupt?)",
    "large": "is too large to load",
}


def _unpack(path: Path, only=None) -> dict[str, np.ndarray]:
    """The file's arrays (those named in `only`, else all), each checked against `_MEMBERS` before and while it is
    unpacked; UserError naming the fault."""
    try:
        with _open(path) as file:
            return _members(file, only)
    except _Refused as exc:
        if exc.what == "zip":
            raise UserError(f"{path} is not a roadmap file of this planner (not an .npz archive)") from None
        raise UserError(f"roadmap {path} {_REFUSED[exc.what]}: {exc}") from None
    except MemoryError:
        raise UserError(f"roadmap {path} does not fit in the memory free here") from None
    except _DAMAGE as exc:  # what zipfile, zlib and numpy's npy header reader raise on a damaged file
        raise UserError(f"roadmap {path} is not a whole roadmap file (truncated or corrupt?): {_line(exc)}") from None


_DAMAGE = (
    zlib.error,  # a bit flipped in a member's compressed data
    zipfile.BadZipFile,  # a checksum that does not match, a damaged directory or member header
    EOFError,  # compressed data that ends early
    OSError,
    ValueError,  # (zipfile on a damaged directory: an offset out of the file, a name that does not decode)
    KeyError,
    struct.error,
    NotImplementedError,  # (a compression method zipfile does not know)
    RuntimeError,  # (an encrypted member, RecursionError)
    TypeError,
    SyntaxError,
)


_FILE_KINDS = (
    (stat.S_ISDIR, "a folder"),
    (stat.S_ISFIFO, "a named pipe (FIFO)"),
    (stat.S_ISCHR, "a device"),
    (stat.S_ISBLK, "a device"),
    (stat.S_ISSOCK, "a socket"),
)


def _not_a_file(path: Path, mode: int) -> UserError:
    kind = next((name for test, name in _FILE_KINDS if test(mode)), "not a regular file")
    return UserError(f"roadmap {path} is {kind}, not a file")


@contextlib.contextmanager
def _open(path: Path):
    """The roadmap file, open for reading: a regular file no larger than MAX_FILE_BYTES, else UserError. Opened
    without blocking (O_NONBLOCK: opening a named pipe waits for a writer otherwise, and reading it forever) and
    tested on the open descriptor, so nothing put at `path` between the look and the open can hang the read."""
    try:
        mode = os.stat(path).st_mode
    except OSError as exc:
        raise UserError(f"cannot read roadmap {path}: {exc.strerror or exc}") from None
    if not stat.S_ISREG(mode):  # not opened at all: opening a device may do something
        raise _not_a_file(path, mode)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY | getattr(os, "O_CLOEXEC", 0))
    except OSError as exc:
        raise UserError(f"cannot read roadmap {path}: {exc.strerror or exc}") from None
    try:
        opened = os.fstat(fd)
        if not stat.S_ISREG(opened.st_mode):
            raise _not_a_file(path, opened.st_mode)
        if opened.st_size > MAX_FILE_BYTES:
            raise UserError(
                f"roadmap {path} is {opened.st_size / 2**20:.0f} MiB, over the {MAX_FILE_BYTES >> 20} MiB limit"
            )
        file = os.fdopen(fd, "rb")  # (O_NONBLOCK changes nothing for a regular file)
    except BaseException:
        os.close(fd)
        raise
    with file:
        yield file


def _members(file, only=None) -> dict[str, np.ndarray]:
    """The arrays of an open .npz file (see `_unpack`): the zip's directory first (members, methods, sizes), then
    each wanted member through its npy header."""
    if file.read(4) != b"PK\x03\x04":  # numpy would take any other file for a pickle and say so
        raise _Refused("not an .npz archive", what="zip")
    size = os.fstat(file.fileno()).st_size
    # The zip's end record says how many members its directory lists and how large it is, before zipfile reads it
    # (a directory of millions of entries would take it minutes).
    tail = min(size, 22 + 0xFFFF)
    file.seek(size - tail)
    end = file.read(tail)
    at = end.rfind(b"PK\x05\x06")
    if at < 0 or len(end) - at < 22:
        raise _Refused("its zip directory's end record is missing", what="damaged")
    entries, directory = struct.unpack("<4s4H2LH", end[at : at + 22])[4:6]
    if entries > len(_MEMBERS) or directory > 1 << 16 or end[max(at - 20, 0) : at - 16] == b"PK\x06\x07":
        # (the last: a zip64 end record, whose counts zipfile would take instead; no roadmap file needs one)
        raise _Refused(f"its zip directory lists {entries} members in {directory:,} bytes, not a roadmap's")
    file.seek(0)
    archive = zipfile.ZipFile(file)
    infos = archive.infolist()
    names = [info.filename for info in infos]
    if len(set(names)) != len(names):
        raise _Refused("a member is in its zip twice")
    total = 0
    for info in infos:
        name = info.filename.removesuffix(".npy")
        if not info.filename.endswith(".npy") or name not in _MEMBERS:
            raise _Refused(f"it holds a member {_short(info.filename)} that a roadmap file does not")
        if info.flag_bits & 0x1 or info.compress_type not in (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED):
            raise _Refused(f"its member {info.filename} is encrypted or compressed by a method numpy does not use")
        limit = _MEMBERS[name][2]
        if info.file_size > limit:
            raise _Refused(
                f"its member {info.filename} would unpack to {_bytes(info.file_size)}, over the {_bytes(limit)} "
                "limit (not unpacked)",
                what="large",
            )
        total += info.file_size
    if total > MAX_DATA_BYTES:
        raise _Refused(
            f"it would unpack to {_bytes(total)}, over the {_bytes(MAX_DATA_BYTES)} limit (not unpacked)", what="large"
        )
    missing = set(_MEMBERS if only is None else only) - {name.removesuffix(".npy") for name in names}
    if missing:
        raise _Refused(f"it lacks {', '.join(sorted(missing))}")
    return {
        info.filename.removesuffix(".npy"): _member(archive, info)
        for info in infos
        if only is None or info.filename.removesuffix(".npy") in only
    }


def _member(archive: zipfile.ZipFile, info: zipfile.ZipInfo) -> np.ndarray:
    """One member's array: its npy header read from the zip stream and checked (dtype kind, dimensions, and shape x
    item size equal to the bytes that follow the header) before its data is read, and never a byte more than the
    zip's directory declares."""
    from numpy.lib import format as npy

    kinds, ndim, _ = _MEMBERS[info.filename.removesuffix(".npy")]
    with archive.open(info) as raw:
        stream = _Bounded(raw, info.file_size, info.filename)
        try:
            version = npy.read_magic(stream)
            if version not in ((1, 0), (2, 0)):
                raise _Refused(f"its member {info.filename} has npy format {version}, not 1.0 or 2.0")
            read_header = npy.read_array_header_1_0 if version == (1, 0) else npy.read_array_header_2_0
            with warnings.catch_warnings():  # (ast warns on stderr of what it parses in a damaged header)
                warnings.simplefilter("ignore")
                shape, fortran, dtype = read_header(stream)
        except (_Refused, zlib.error, zipfile.BadZipFile, EOFError):
            raise
        except Exception as exc:  # numpy parses a header with ast, and on failing with tokenize: whatever they raise
            raise _Refused(
                f"its member {info.filename} has an npy header that does not parse: {_line(exc)}", what="damaged"
            ) from None
        if (
            dtype.hasobject
            or dtype.kind not in kinds
            or dtype.itemsize == 0
            or dtype.subdtype is not None
            or len(shape) != ndim
            or any(d < 0 for d in shape)
        ):
            raise _Refused(f"its member {info.filename} holds {dtype.str} values of shape {shape}")
        nbytes = math.prod(shape) * dtype.itemsize
        if nbytes != info.file_size - stream.count:
            raise _Refused(
                f"its member {info.filename} claims shape {_short(shape)} of {dtype.str} ({_bytes(nbytes)}) but "
                f"holds {_bytes(info.file_size - stream.count)}",
                what="damaged",
            )
        data = bytearray(nbytes)
        view, done = memoryview(data), 0
        while done < nbytes:
            chunk = stream.read(min(_CHUNK, nbytes - done))
            if not chunk:
                raise _Refused(f"its member {info.filename} ends early", what="damaged")
            view[done : done + len(chunk)] = chunk
            done += len(chunk)
        stream.read(1)  # nothing more, and the zip's checksum of the member is checked at its end
    array = np.frombuffer(data, dtype)
    return array.reshape(shape[::-1]).T if fortran else array.reshape(shape)


class _Bounded:
    """A member's stream that gives no more bytes than the zip's directory declares for it (`_Refused` at the first
    byte more), and counts what it gave."""

    def __init__(self, raw, size: int, name: str):
        self.raw, self.left, self.name, self.count = raw, size, name, 0

    def read(self, n: int = -1) -> bytes:
        n = self.left + 1 if n is None or n < 0 else min(n, self.left + 1)
        data = self.raw.read(n)
        if len(data) > self.left:
            raise _Refused(f"its member {self.name} holds more bytes than its zip entry declares", what="damaged")
        self.left -= len(data)
        self.count += len(data)
        return data


def _line(exc: BaseException) -> str:
    """An exception's message on one short line (numpy's and zipfile's may span several or quote a whole header)."""
    return _short(" ".join(str(exc).split()) or type(exc).__name__, 160)


def _short(value, width: int = 60) -> str:
    text = value if isinstance(value, str) else repr(value)
    text = repr(text)[1:-1] if isinstance(value, str) else text  # a name with a line break stays on one line
    return text if len(text) <= width else text[: width - 3] + "..."


def _bytes(n: int) -> str:
    return f"{n / 2**30:.3g} GiB" if n >= 2**30 else f"{n / 2**20:.3g} MiB" if n >= 2**20 else f"{n:,} bytes"


def _header(path: Path, array: np.ndarray) -> dict:
    """The file's JSON header, each field of the type it must have; UserError naming the first that is not."""
    try:
        header = json.loads(str(array[()]))
    except (ValueError, RecursionError):
        header = None
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        raise UserError(f"{path} is not a roadmap file of this planner")
    if header.get("version") != FORMAT_VERSION or isinstance(header.get("version"), bool):
        raise UserError(
            f"roadmap {path} has format version {_short(repr(header.get('version')))}, this planner reads "
            f"{FORMAT_VERSION}"
        )
    provenance, fingerprint_ = header.get("provenance"), header.get("fingerprint")
    if not isinstance(fingerprint_, dict) or not isinstance(provenance, dict) or "builds" not in provenance:
        raise UserError(f"roadmap {path} lacks its fingerprint or provenance: not a whole roadmap file")

    def malformed(what: str, value) -> UserError:
        return UserError(f"roadmap {path} has a malformed header: {what}, got {_short(repr(value))}")

    if not all(isinstance(key, str) and isinstance(value, str) for key, value in fingerprint_.items()):
        raise malformed("its fingerprint must name each part's hash as text", fingerprint_)
    if not isinstance(header.get("scene"), str):
        raise malformed("its scene must be a name", header.get("scene"))
    if "revision" in header and not (isinstance(header["revision"], str) and len(header["revision"]) <= 64):
        raise malformed("its revision must be a short text", header["revision"])
    if not _whole(provenance.get("queries")):
        raise malformed("provenance queries must be a whole number of at least 0", provenance.get("queries"))
    # The build records, and what each build's cover answered on the roadmap (app.jobs.cover; none in older files).
    records = {
        "builds": (
            "build records",
            lambda r: (
                isinstance(r.get("settings"), dict)
                and isinstance(r.get("ended"), str)
                and all(_whole(r.get(key)) for key in ("nodes", "collision_checks", "workers"))
                and _number(r.get("seconds"))
            ),
            "build record {i} must hold settings, ended, whole numbers nodes, collision_checks and workers, and "
            "seconds",
        ),
        "covered": (
            "what the build answered on the roadmap",
            lambda r: (
                isinstance(r.get("what"), str)
                and len(r["what"]) <= 200
                and isinstance(r.get("solved"), bool)
                and _whole(r.get("collision_checks"))
            ),
            "covered record {i} must hold what (text), solved (true or false) and collision_checks",
        ),
        "changes": (
            "cell changes repaired for",
            lambda r: (
                isinstance(r.get("change"), list)
                and all(_is_change(c) for c in r["change"])
                and isinstance(r.get("described"), str)
                and all(_whole(r.get(key)) for key in _REPAIR_COUNTS)
                and _number(r.get("seconds"))
            ),
            "change record {i} must hold change (a list of cell changes), described, whole numbers "
            + ", ".join(_REPAIR_COUNTS)
            + ", and seconds",
        ),
    }
    for key, (noun, sound, needs) in records.items():
        listed = provenance.get(key, [])
        if not isinstance(listed, list):
            raise malformed(f"provenance {key} must be a list of {noun}", listed)
        for i, record in enumerate(listed):
            if not (isinstance(record, dict) and sound(record)):
                raise malformed(needs.format(i=i), record)
    return header


_REPAIR_COUNTS = (
    "edges_reset",
    "colliding_reset",
    "nodes_checked",
    "nodes_dropped",
    "collision_checks",
)


def _is_change(value) -> bool:
    """Whether `value` reads as a cell change (app.scene.changes.CellChange as data)."""
    from app.scene.changes import change_from_dict

    if not isinstance(value, dict):
        return False
    try:
        change_from_dict(value)
    except UserError:
        return False
    return True


def _whole(value) -> bool:
    """A whole number from 0 to 2^53 (JSON's exact integers), not a bool."""
    return isinstance(value, int) and not isinstance(value, bool) and 0 <= value <= 2**53


def _number(value) -> bool:
    """A finite number of at least 0, not a bool (JSON as Python reads it takes NaN and Infinity)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool) and 0 <= value < math.inf


def _check_arrays(path, arrays: dict) -> None:
    """Every array's fields that do not depend on the cell (their dtype kinds and dimensions are `_unpack`'s): the
    node and edge counts agree, kinds and edge ends are in range, edges are stored (smaller, larger) and once, counts
    are not negative, k and the resolution are ones a roadmap can have. A file altered by hand or by a bug is refused
    here rather than failing somewhere in a query."""
    from app.planning.roadmap import GOAL, NARROW, START, UNIFORM, WORKSPACE

    def inconsistent(what: str) -> UserError:
        return UserError(f"roadmap {path} is inconsistent: {what}")

    Q, ends, names, kinds = arrays["Q"], arrays["ends"], arrays["kind_names"], arrays["kinds"]
    n, m = len(Q), len(ends)
    if not np.isfinite(Q).all():
        raise inconsistent("a node has a coordinate that is not a finite number")
    known = {START, GOAL, UNIFORM, NARROW, WORKSPACE}
    if not len(names) or len(set(names.tolist())) != len(names) or not set(names.tolist()) <= known:
        raise inconsistent(f"its node kinds {_short(names.tolist())} are not distinct names among {sorted(known)}")
    if kinds.shape != (n,):
        raise inconsistent(f"{len(kinds)} node kinds for {n} nodes")
    if n and not (0 <= kinds.min() and kinds.max() < len(names)):
        raise inconsistent(f"a node's kind is not one of the {len(names)} kinds named")
    if ends.shape[1:] != (2,):
        raise inconsistent(f"its edges are not pairs of nodes (shape {ends.shape})")
    for key in ("alive", "checked", "proved", "progress"):
        if arrays[key].shape != (m,):
            raise inconsistent(f"{len(arrays[key])} values of {key} for {m} edges")
    if m:
        if ends.min() < 0 or ends.max() >= n:
            raise inconsistent(f"an edge ends at a node that is not there (nodes 0 to {n - 1})")
        if (ends[:, 0] >= ends[:, 1]).any():
            raise inconsistent("an edge is not stored as (smaller node, larger node)")
        keys = ends[:, 0].astype(np.int64) << 32 | ends[:, 1].astype(np.int64)
        if len(np.unique(keys)) != m:
            raise inconsistent("an edge is stored twice")
        if arrays["progress"].min() < 0:
            raise inconsistent("an edge's progress (points of it checked) is negative")
    k = int(arrays["k"])
    if not (k == 0 or 1 <= k <= MAX_K):
        raise inconsistent(f"its k is {k}; k is 0 (k-PRM*'s) or from 1 to {MAX_K}")
    resolution = float(arrays["resolution"])
    if not (math.isfinite(resolution) and resolution > 0):
        raise inconsistent(f"its resolution {resolution:g} is not a positive finite number")
    if arrays["counters"].shape != (2,) or arrays["counters"].min() < 0:
        raise inconsistent("its edge counters are not two numbers of at least 0")


def check_cell(path, arrays: dict, space) -> dict:
    """`arrays` checked against the cell's configuration space (a file whose fingerprint matches can still hold
    what no roadmap of the cell has): every node of the robot's coordinates and within the bounds (continuous
    angles wrap; a node outside by at most 1e-9 of the bound's size, as the fingerprint rounds bounds, is put back
    on it), the resolution the cell's own (the only one a roadmap is built at), and no edge's progress past the
    points the edge has. Returns the arrays to build the graph from."""
    Q = np.asarray(arrays["Q"], float)
    if Q.shape[1] != space.dim:
        raise UserError(f"roadmap {path} holds nodes of {Q.shape[1]} coordinates; this cell's robot has {space.dim}")
    fixed = ~space.continuous
    slack = 1e-9 * np.maximum(1.0, np.maximum(np.abs(space.lower), np.abs(space.upper)))
    outside = ((Q < space.lower - slack) | (Q > space.upper + slack)) & fixed
    if outside.any():
        node = int(np.flatnonzero(outside.any(axis=1))[0])
        where = "; ".join(space.out_of_bounds(Q[node])[:2])
        raise UserError(f"roadmap {path} holds node {node} outside this cell's bounds: {where}")
    Q = np.where(fixed, np.clip(Q, space.lower, space.upper), Q)
    resolution = float(arrays["resolution"])
    if abs(resolution - space.resolution) > 1e-9 * space.resolution:
        raise UserError(
            f"roadmap {path} says its edges were checked at resolution {resolution:g}; this cell checks at "
            f"{space.resolution:g}"
        )
    # An undecided edge's progress counts the points of it a check found free (app.checking.context, edges_status):
    # at most the edge's points between its ends, pieces - 1 (a larger count would skip every point unchecked).
    progress, ends = arrays["progress"], arrays["ends"]
    rows = np.flatnonzero(progress > 0)
    if len(rows):
        pieces = space.segments(Q[ends[rows, 0]], Q[ends[rows, 1]], space.resolution)
        if (progress[rows] > pieces - 1).any():
            raise UserError(f"roadmap {path} is inconsistent: an edge's progress counts more points than it has")
    return {**arrays, "Q": Q, "resolution": np.array(space.resolution)}


def summary(arrays: dict, header: dict) -> dict:
    """What a roadmap holds: nodes by kind, edges by verdict, and where it came from."""
    names = [str(n) for n in arrays["kind_names"]]
    kinds = np.bincount(arrays["kinds"], minlength=len(names)) if len(arrays["kinds"]) else np.zeros(len(names), int)
    alive, checked, proved = arrays["alive"], arrays["checked"], arrays["proved"]
    return {
        "scene": header.get("scene"),
        "nodes": int(len(arrays["Q"])),
        "dimension": int(arrays["Q"].shape[1]) if arrays["Q"].ndim == 2 else 0,
        "nodes_by_kind": {name: int(count) for name, count in zip(names, kinds)},
        "edges": {
            "certified": int((alive & proved).sum()),
            "free": int((alive & checked & ~proved).sum()),
            "unchecked": int((alive & ~checked).sum()),
            "colliding_or_unprovable": int((~alive).sum()),
        },
        "k": int(arrays["k"]) or None,
        "resolution": float(arrays["resolution"]),
        "fingerprint": header.get("fingerprint"),
        "provenance": header.get("provenance"),
    }


# ---- the fingerprint ----------------------------------------------------------------------------------------------
def fingerprint(oracle) -> dict[str, str]:
    """Hashes (hex) of everything a stored verdict depends on, in parts, so that a refusal can say what changed:
    the robot's and the environment's collision geometry (shapes and their placement in the world at a fixed set of
    configurations: joint kinematics included), the pairs that are checked (self-collision, SRDF), the configuration
    space (bounds, metric, resolution), and the code that answers collision and certificate questions."""
    from pydrake.geometry import Role

    space = oracle.space
    inspector = oracle.model.scene_graph().model_inspector()
    geometries = sorted(
        inspector.GetAllGeometryIds(Role.kProximity),
        key=lambda g: (inspector.GetName(inspector.GetFrameId(g)), inspector.GetName(g)),
    )
    probes = np.vstack(
        [space.lower, space.upper, (space.lower + space.upper) / 2, space.uniform(np.random.default_rng(0), 5)]
    )
    placed = [[oracle.query_object(q).GetPoseInWorld(g).GetAsMatrix34() for g in geometries] for q in probes]
    parts = {}
    for part, robot in (("robot", True), ("environment", False)):
        digest = hashlib.sha256()
        for j, g in enumerate(geometries):
            if oracle.is_robot_geometry(g) != robot:
                continue
            digest.update(repr((inspector.GetName(inspector.GetFrameId(g)), inspector.GetName(g))).encode())
            digest.update(shape_bytes(inspector.GetShape(g)))
            for poses in placed:
                digest.update(rounded(poses[j]))
        parts[part] = digest.hexdigest()
    pairs = np.asarray(oracle.checker.GetFilteredCollisionMatrix())
    parts["collision pairs"] = _hash(pairs.astype(np.int64).tobytes(), repr(oracle.scene.self_collisions).encode())
    parts["configuration space"] = _hash(
        *(rounded(a) for a in (space.lower, space.upper, space.weights, np.array([space.resolution]))),
        space.angular.tobytes(),
        space.continuous.tobytes(),
    )
    root = Path(__file__).resolve().parents[1]
    parts["checker code"] = _hash(
        *((root / module).read_bytes() for module in _VERDICT_MODULES),
        importlib.metadata.version("drake").encode(),
    )
    return parts


def _hash(*chunks: bytes) -> str:
    digest = hashlib.sha256()
    for chunk in chunks:
        digest.update(len(chunk).to_bytes(8, "little"))
        digest.update(chunk)
    return digest.hexdigest()


def rounded(a) -> bytes:
    """Numbers to 1e-9 (-0 as 0), so that the same cell hashes alike however its numbers were computed."""
    return (np.round(np.asarray(a, float), 9) + 0.0).tobytes()


def shape_bytes(shape) -> bytes:
    """A shape's kind and size; a mesh by the vertices of the convex hull Drake checks it as."""
    from pydrake.geometry import Box, Capsule, Convex, Cylinder, Ellipsoid, HalfSpace, Mesh, Sphere

    kind = type(shape).__name__.encode()
    if isinstance(shape, Box):
        size = [shape.width(), shape.depth(), shape.height()]
    elif isinstance(shape, Sphere):
        size = [shape.radius()]
    elif isinstance(shape, (Cylinder, Capsule)):
        size = [shape.radius(), shape.length()]
    elif isinstance(shape, Ellipsoid):
        size = [shape.a(), shape.b(), shape.c()]
    elif isinstance(shape, HalfSpace):
        size = []
    elif isinstance(shape, (Convex, Mesh)):
        size = hull_vertices(shape)
    else:  # a shape this list does not know: its description, which names its kind and size
        return kind + repr(shape).encode()
    return kind + rounded(size)
