"""Read back what a Meshcat standalone page (Meshcat.StaticHtml) holds, for tests.

The page replays the scene as msgpack commands embedded as base64 `data:` URLs; this decodes them with a small
msgpack reader (msgpack is not a dependency of the project).
"""

import base64
import re
import struct

_COMMAND = re.compile(r'fetch\("data:application/octet-binary;base64,([A-Za-z0-9+/=]+)"\)')


def commands(html: str) -> list[dict]:
    return [unpack(base64.b64decode(blob)) for blob in _COMMAND.findall(html)]


def unpack(data: bytes):
    value, end = _read(memoryview(data), 0)
    assert end == len(data), "trailing bytes after a msgpack value"
    return value


def _read(b, i):  # noqa: C901 - one branch per msgpack type
    t = b[i]
    i += 1
    if t <= 0x7F:
        return t, i
    if 0x80 <= t <= 0x8F:
        return _map(b, i, t & 0x0F)
    if 0x90 <= t <= 0x9F:
        return _array(b, i, t & 0x0F)
    if 0xA0 <= t <= 0xBF:
        n = t & 0x1F
        return bytes(b[i : i + n]).decode(), i + n
    if t >= 0xE0:
        return t - 0x100, i
    simple = {0xC0: None, 0xC2: False, 0xC3: True}
    if t in simple:
        return simple[t], i
    sizes = {0xC4: 1, 0xC5: 2, 0xC6: 4, 0xD9: 1, 0xDA: 2, 0xDB: 4}  # bin and str with a length
    if t in sizes:
        n, i = _uint(b, i, sizes[t])
        raw = bytes(b[i : i + n])
        return (raw if t <= 0xC6 else raw.decode()), i + n
    numbers = {
        0xCA: ">f",
        0xCB: ">d",
        0xCC: ">B",
        0xCD: ">H",
        0xCE: ">I",
        0xCF: ">Q",
        0xD0: ">b",
        0xD1: ">h",
        0xD2: ">i",
        0xD3: ">q",
    }
    if t in numbers:
        size = struct.calcsize(numbers[t])
        return struct.unpack(numbers[t], b[i : i + size])[0], i + size
    if t in (0xDC, 0xDD):
        n, i = _uint(b, i, 2 if t == 0xDC else 4)
        return _array(b, i, n)
    if t in (0xDE, 0xDF):
        n, i = _uint(b, i, 2 if t == 0xDE else 4)
        return _map(b, i, n)
    fixext = {0xD4: 1, 0xD5: 2, 0xD6: 4, 0xD7: 8, 0xD8: 16}
    if t in fixext:
        n = fixext[t]
    elif t in (0xC7, 0xC8, 0xC9):
        n, i = _uint(b, i, {0xC7: 1, 0xC8: 2, 0xC9: 4}[t])
    else:
        raise ValueError(f"msgpack type byte {t:#x} not understood")
    ext_type = b[i]
    return ("ext", ext_type, bytes(b[i + 1 : i + 1 + n])), i + 1 + n


def _uint(b, i, size):
    return int.from_bytes(b[i : i + size], "big"), i + size


def _array(b, i, n):
    out = []
    for _ in range(n):
        value, i = _read(b, i)
        out.append(value)
    return out, i


def _map(b, i, n):
    out = {}
    for _ in range(n):
        key, i = _read(b, i)
        value, i = _read(b, i)
        out[key if not isinstance(key, list) else tuple(key)] = value
    return out, i
