"""The one way the project writes a file: checked before any work, written through a temporary file beside it and
renamed into place, so a reader (or a failed run) never leaves half a file."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path

from app.errors import UserError


def check_output(path: str | os.PathLike) -> Path:
    """An output file's path, refused early (before any work) if it cannot be written there."""
    target = Path(path)
    if not target.parent.is_dir():
        raise UserError(f"cannot write {path}: folder {target.parent} does not exist")
    if target.is_dir():
        raise UserError(f"cannot write {path}: it is a folder")
    if not os.access(target.parent, os.W_OK) or (target.exists() and not os.access(target, os.W_OK)):
        raise UserError(f"cannot write {path}: permission denied")
    return target


def write_atomically(path: str | os.PathLike, content: str | bytes | Callable[[Path], None]) -> Path:
    """Write `content` to `path`: text, bytes, or a function that writes a given temporary path (e.g. savefig).
    The file appears whole or not at all, with ordinary permissions (mkstemp's are private)."""
    target = check_output(path)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=f".tmp{target.suffix}", dir=target.parent)
    except OSError as exc:
        raise UserError(f"cannot write {path}: {exc.strerror or exc}") from None
    try:
        if callable(content):
            os.close(fd)
            content(Path(tmp))
        else:
            with os.fdopen(fd, "wb") as f:
                f.write(content.encode("utf-8") if isinstance(content, str) else content)
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, target)
    except BaseException as exc:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        if isinstance(exc, OSError):
            raise UserError(f"cannot write {path}: {exc.strerror or exc}") from None
        raise
    return target


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask
