"""The one way the project writes a file: checked before any work, written through a temporary file beside it and
renamed into place, so a reader (or a failed run) never leaves half a file. Inside `all_or_nothing()` the renames
wait for the end of the block, so a command's outputs appear together, or none of them when it fails."""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from collections.abc import Callable, Iterator
from contextvars import ContextVar
from pathlib import Path

from app.errors import UserError

# Kernel pseudo-filesystems: a write there is never a file a user gets back (and may change the running system).
_SYSTEM_FOLDERS = (Path("/proc"), Path("/sys"), Path("/dev"))

# A folder is written inside a temporary folder of its own, named with this ending, under its own name (a ROS 2 bag
# names its files after its folder).
_FOLDER_WORK = ".folder.tmp"
# The (temporary file, target) renames of the innermost all_or_nothing() block; None outside one.
_pending: ContextVar[list[tuple[str, Path]] | None] = ContextVar("pending_writes", default=None)


def check_output(path: str | os.PathLike, *, make_folders: bool = False) -> Path:
    """An output file's path, refused early (before any work) if it cannot be written there. With `make_folders`
    its missing folders may be created (the nearest existing one must then be a writable folder)."""
    target = Path(path)
    absolute = Path(os.path.abspath(target))
    for system in _SYSTEM_FOLDERS:
        if absolute == system or system in absolute.parents:
            raise UserError(f"cannot write {path}: {system} is a system folder, not a place for output files")
    if target.is_dir():
        raise UserError(f"cannot write {path}: it is a folder")
    folder = target.parent
    if make_folders:
        while not folder.exists() and folder != folder.parent:
            folder = folder.parent
    if folder.exists() and not folder.is_dir():
        raise UserError(f"cannot write {path}: {folder} is a file, not a folder")
    if not folder.is_dir():
        raise UserError(f"cannot write {path}: folder {folder} does not exist")
    if not os.access(folder, os.W_OK) or (target.exists() and not os.access(target, os.W_OK)):
        raise UserError(f"cannot write {path}: permission denied")
    return target


@contextlib.contextmanager
def all_or_nothing() -> Iterator[None]:
    """Files written by write_atomically inside the block appear together when it ends; if it raises, none do."""
    pending: list[tuple[str, Path]] = []
    token = _pending.set(pending)
    try:
        yield
    except BaseException:
        _discard(tmp for tmp, _ in pending)
        raise
    finally:
        _pending.reset(token)
    for done, (tmp, target) in enumerate(pending):
        try:
            os.replace(tmp, target)
            _discard_work(tmp)
        except OSError as exc:
            _discard(tmp for tmp, _ in pending[done:])
            raise UserError(f"cannot write {target}: {exc.strerror or exc}") from None


def write_atomically(path: str | os.PathLike, content: str | bytes | Callable[[Path], None]) -> Path:
    """Write `content` to `path`: text, bytes, or a function that writes a given temporary path (e.g. savefig).
    The file appears whole or not at all, with ordinary permissions (mkstemp's are private); inside
    all_or_nothing() it appears when the block ends."""
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
        pending = _pending.get()
        if pending is None:
            os.replace(tmp, target)
        else:
            pending.append((tmp, target))
    except BaseException as exc:
        _discard([tmp])
        if isinstance(exc, OSError):
            raise UserError(f"cannot write {path}: {exc.strerror or exc}") from None
        raise
    return target


def write_folder_atomically(path: str | os.PathLike, fill: Callable[[Path], None]) -> Path:
    """A folder (e.g. a ROS 2 bag) written whole or not at all: `fill` creates it at a fresh path beside `path`,
    which is then renamed to `path` (inside all_or_nothing(): when the block ends). A `path` that exists is refused,
    so nothing of the user's is merged into or replaced."""
    target = Path(path)
    if target.exists() or target.is_symlink():
        raise UserError(f"cannot write {path}: it exists already; give a new folder name")
    check_output(target)
    try:
        tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=_FOLDER_WORK, dir=target.parent)) / target.name
    except OSError as exc:
        raise UserError(f"cannot write {path}: {exc.strerror or exc}") from None
    try:
        fill(tmp)
        pending = _pending.get()
        if pending is None:
            os.rename(tmp, target)
            _discard_work(tmp)
        else:
            pending.append((str(tmp), target))
    except BaseException as exc:
        _discard([tmp])
        if isinstance(exc, OSError):
            raise UserError(f"cannot write {path}: {exc.strerror or exc}") from None
        raise
    return target


def _discard(paths) -> None:
    for tmp in paths:
        if not _discard_work(tmp):
            with contextlib.suppress(OSError):
                os.unlink(tmp)


def _discard_work(tmp) -> bool:
    """Remove the temporary folder a folder `tmp` was written in (with whatever is left in it); False for a file."""
    work = Path(tmp).parent
    if not work.name.endswith(_FOLDER_WORK):
        return False
    shutil.rmtree(work, ignore_errors=True)
    return True


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask
