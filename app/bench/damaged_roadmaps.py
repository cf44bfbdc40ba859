"""Roadmap files made and damaged without a scene, byte by byte: a small whole roadmap file (`roadmap_file`), npy
members (one claiming what it does not hold), zips of them, and a zip's declared fields, checksums or compressed data
changed after the fact. The bad-input table's roadmap rows (app.bench.bad_input) and tests/test_roadmap_file.py
damage files with these.
"""

from __future__ import annotations

import io
import json
import struct
import zipfile
import zlib


def roadmap_file(header: dict | None = None, dim: int = 9, **arrays) -> bytes:
    """The bytes of a roadmap file (app.planning.roadmap_file) of 40 nodes of `dim` coordinates in a line, joined in
    order, with a made-up fingerprint: whole and sound as far as `read` can tell without a scene (`load` refuses it
    as built for another cell). `header` entries and `arrays` (numpy arrays, or npy bytes as from `npy_claiming`)
    replace the made ones."""
    import numpy as np

    from app.planning.roadmap_file import FINGERPRINT_PARTS, FORMAT, FORMAT_VERSION

    n = 40
    made = {
        "format": FORMAT,
        "version": FORMAT_VERSION,
        "scene": "bar",
        "fingerprint": {part: "0" * 64 for part in FINGERPRINT_PARTS},
        "provenance": {"builds": [], "queries": 0},
        **(header or {}),
    }
    ends = np.stack([np.arange(n - 1), np.arange(1, n)], axis=1)
    members = {
        "header": np.array(json.dumps(made)),
        "Q": np.linspace(10.0, 90.0, n)[:, None] * np.ones(dim),
        "kind_names": np.array(["uniform"]),
        "kinds": np.zeros(n, np.int16),
        "ends": ends,
        "alive": np.ones(n - 1, bool),
        "checked": np.zeros(n - 1, bool),
        "proved": np.zeros(n - 1, bool),
        "progress": np.zeros(n - 1, np.int64),
        "k": np.array(10),
        "resolution": np.array(0.5),
        "counters": np.array([0, n - 1], np.int64),
        **arrays,
    }
    return zipped(
        {f"{name}.npy": member if isinstance(member, bytes) else npy(member) for name, member in members.items()}
    )


def npy(array) -> bytes:
    """An array as an .npy file's bytes (numpy's format 1.0, no pickle)."""
    import numpy as np

    buffer = io.BytesIO()
    np.lib.format.write_array(buffer, np.asarray(array), allow_pickle=False)
    return buffer.getvalue()


def npy_claiming(shape: tuple, descr: str, data: bytes) -> bytes:
    """An .npy file whose header claims `shape` and dtype `descr` ("<f8", "|O") whatever `data` holds."""
    import numpy as np

    buffer = io.BytesIO()
    np.lib.format.write_array_header_1_0(buffer, {"descr": descr, "fortran_order": False, "shape": shape})
    return buffer.getvalue() + data


def zipped(members: dict[str, bytes]) -> bytes:
    """A zip (deflated, as numpy's savez_compressed writes) of the given members' bytes."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, data in members.items():
            archive.writestr(name, data)
    return buffer.getvalue()


# Fields of a zip member, as offsets in its central directory entry and its local header, with their struct formats.
_ENTRY_FIELDS = {
    "method": (10, 8, "<H"),
    "crc": (16, 14, "<L"),
    "compress_size": (20, 18, "<L"),
    "file_size": (24, 22, "<L"),
}


def zip_entries(data: bytes) -> dict[str, tuple[int, int]]:
    """Each member of the zip `data`: name -> (offset of its central directory entry, offset of its local header)."""
    end = data.rindex(b"PK\x05\x06")
    count, _, at = struct.unpack("<HLL", data[end + 10 : end + 20])
    entries = {}
    for _ in range(count):
        lengths = struct.unpack("<3H", data[at + 28 : at + 34])
        name = data[at + 46 : at + 46 + lengths[0]].decode()
        entries[name] = (at, struct.unpack("<L", data[at + 42 : at + 46])[0])
        at += 46 + sum(lengths)
    return entries


def patch_member(data: bytes, name: str, **fields) -> bytes:
    """The zip `data` with fields of member `name` (method, crc, compress_size, file_size) changed in its central
    directory entry and its local header alike: what the zip declares, not what it holds."""
    data = bytearray(data)
    directory, local = zip_entries(bytes(data))[name]
    for field, value in fields.items():
        in_directory, in_header, form = _ENTRY_FIELDS[field]
        struct.pack_into(form, data, directory + in_directory, value)
        struct.pack_into(form, data, local + in_header, value)
    return bytes(data)


def compressed_at(data: bytes, name: str) -> int:
    """Where member `name`'s compressed data starts in the zip `data`."""
    local = zip_entries(data)[name][1]
    return local + 30 + sum(struct.unpack("<2H", data[local + 26 : local + 30]))


def invalid_deflate(data: bytes, name: str) -> bytes:
    """The zip `data` with member `name`'s first deflate block given the reserved block type 3: inflating it fails
    ("invalid block type"), as a bit flipped in compressed data makes it fail."""
    at = compressed_at(data, name)
    return data[:at] + bytes([data[at] | 0b110]) + data[at + 1 :]


def deflate_bomb(head: bytes, size: int) -> bytes:
    """A raw deflate stream that inflates to `head` and then zeros, `size` bytes in all: about a thousandth of that
    (a 4 GB bomb is 4 MB). Made from one compressed MiB of zeros repeated (each ends in a full flush, so copies of it
    follow one another in a valid stream), not by compressing `size` bytes."""
    mib = 1 << 20
    chunk = zlib.compressobj(9, zlib.DEFLATED, -15)
    block = chunk.compress(b"\0" * mib) + chunk.flush(zlib.Z_FULL_FLUSH)
    start = zlib.compressobj(9, zlib.DEFLATED, -15)
    first = start.compress(head) + start.flush(zlib.Z_FULL_FLUSH)
    zeros, rest = divmod(size - len(head), mib)
    tail = zlib.compressobj(9, zlib.DEFLATED, -15)
    last = tail.compress(b"\0" * rest) + tail.flush(zlib.Z_FINISH)
    return first + block * zeros + last
