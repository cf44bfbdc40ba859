"""The one way the project writes a file, and the one check on a file it reads.

Writing: checked before any work, written through a temporary file beside it and renamed into place, so a reader
(or a failed run) never leaves half a file. Inside `all_or_nothing()` the renames wait for the end of the block, so a
command's outputs appear together, or none of them when it fails.

Reading: `check_input` refuses a file larger than its kind's limit (INPUT_LIMITS) before any parser sees it, so a
huge file is one line at once instead of minutes of parsing and gigabytes of memory.

Reading, adding to and writing back one file from several processes (`plan --roadmap FILE --update`): `exclusive`
holds a lock for the whole of it, so that they take turns and none writes over another's update.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import shutil
import stat
import tempfile
import threading
from collections.abc import Callable, Iterator
from contextvars import ContextVar
from pathlib import Path

from app.errors import UserError

# Kernel pseudo-filesystems: a write there is never a file a user gets back (and may change the running system).
_SYSTEM_FOLDERS = (Path("/proc"), Path("/sys"), Path("/dev"))

# The largest file of each kind a reader takes (bytes): far above any real one (the shipped scene and robot files are
# a few kB, the committed paper trials 3.6 MB, a 60 s trajectory of 9 joints sampled every 4 ms about 8 MB), far
# below what would take minutes and gigabytes to parse.
INPUT_LIMITS = {
    "scene file": 1 << 20,  # problem files and custom scene files (YAML)
    "change file": 1 << 20,  # a work cell's change (YAML)
    "payload file": 1 << 20,  # an object the robot carries (YAML)
    "OMPL.app problem file": 1 << 20,
    "model directives": 1 << 20,
    "SRDF file": 16 << 20,
    "model file": 64 << 20,  # URDF, SDF
    "mesh file": 64 << 20,
    "trajectory file": 64 << 20,
    "ROS 2 bag file": 256 << 20,  # each file of a bag folder (view --trajectory BAG)
    "results store": 8 << 30,  # SQLite: read row by row, never whole
    "trials file": 256 << 20,  # trials.csv.gz (compressed)
}

# The exclusive locks this process holds (`exclusive`): lock file path -> [a lock for this process's threads, the lock
# file's descriptor while held, how many blocks hold it].
_locks: dict[str, list] = {}
_locks_guard = threading.Lock()

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
    _check_name_length(path, absolute)
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


def _check_name_length(path, absolute: Path) -> None:
    """A path the filesystem cannot name (ENAMETOOLONG), refused up front: a folder name longer than NAME_MAX, a
    file name whose temporary name (write_atomically's) would be, or the whole longer than PATH_MAX (as the nearest
    existing folder's filesystem says)."""
    existing = absolute
    while not os.path.exists(existing) and existing != existing.parent:  # (os.path.exists: False on ENAMETOOLONG)
        existing = existing.parent
    name_max, path_max = 255, 4096
    with contextlib.suppress(OSError, ValueError):
        name_max = os.pathconf(existing, "PC_NAME_MAX")
        path_max = os.pathconf(existing, "PC_PATH_MAX")
    # mkstemp puts 8 random characters between the temporary name's prefix and suffix.
    file_max = name_max - 8 - len(os.fsencode("".join(_temporary_affixes(absolute)))) + len(os.fsencode(absolute.name))
    folders = max((len(os.fsencode(part)) for part in absolute.parent.parts), default=0)
    if folders > name_max or len(os.fsencode(absolute.name)) > file_max or len(os.fsencode(str(absolute))) >= path_max:
        raise UserError(
            f"cannot write {_shortened(path)}: {os.strerror(errno.ENAMETOOLONG)} (here at most {name_max} bytes per "
            f"folder name, {file_max} for the file name, {path_max - 1} in all)"
        )


def _temporary_affixes(target: Path) -> tuple[str, str]:
    """The prefix and suffix of write_atomically's temporary file for `target` (hidden, beside it)."""
    return f".{target.name}.", f".tmp{target.suffix}"


def _shortened(path) -> str:
    text = str(path)
    return text if len(text) <= 80 else f"{text[:40]}...{text[-30:]}"


def check_input(path: str | os.PathLike, kind: str) -> Path:
    """An input file of `kind` (a key of INPUT_LIMITS), before it is parsed: it exists, is a file and is no larger
    than its kind's limit; else one UserError naming the file and the limit."""
    file = Path(path)
    try:
        size = file.stat().st_size
    except (FileNotFoundError, NotADirectoryError):
        raise UserError(f"{kind} not found: {_shortened(path)}") from None
    except OSError as exc:  # a name too long, no permission, ...
        raise UserError(f"cannot read {kind} {_shortened(path)}: {exc.strerror or exc}") from None
    if not file.is_file():
        raise UserError(f"{kind} {path} is not a file")
    limit = INPUT_LIMITS[kind]
    if size > limit:
        said = _size(size) if _size(size) != _size(limit) else f"{size:,} bytes"  # (just over: the bytes tell)
        raise UserError(f"{kind} {file.name} is too large: {said}; the limit is {_size(limit)}")
    return file


def _size(n: int) -> str:
    for unit, scale in (("GB", 1 << 30), ("MB", 1 << 20), ("kB", 1 << 10)):
        if n >= scale:
            return f"{n / scale:.3g} {unit}"
    return f"{n} bytes"


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
        prefix, suffix = _temporary_affixes(target)
        fd, tmp = tempfile.mkstemp(prefix=prefix, suffix=suffix, dir=target.parent)
    except OSError as exc:
        raise UserError(f"cannot write {path}: {exc.strerror or exc}") from None
    with _filling(path, tmp):
        if callable(content):
            os.close(fd)
            content(Path(tmp))
        else:
            with os.fdopen(fd, "wb") as f:
                f.write(content.encode("utf-8") if isinstance(content, str) else content)
        os.chmod(tmp, 0o666 & ~_umask())
        _place(tmp, target)
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
    with _filling(path, tmp):
        fill(tmp)
        _place(tmp, target)
    return target


@contextlib.contextmanager
def _filling(path, tmp) -> Iterator[None]:
    """While `tmp` is filled and placed: on any failure it is discarded, and an OSError becomes one line naming
    `path`."""
    try:
        yield
    except BaseException as exc:
        _discard([tmp])
        if isinstance(exc, OSError):
            raise UserError(f"cannot write {path}: {exc.strerror or exc}") from None
        raise


def _place(tmp, target: Path) -> None:
    """The finished `tmp` renamed onto `target` now, or when the enclosing all_or_nothing() block ends."""
    pending = _pending.get()
    if pending is None:
        os.replace(tmp, target)
        _discard_work(tmp)
    else:
        pending.append((str(tmp), target))


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


@contextlib.contextmanager
def exclusive(path: str | os.PathLike, waiting: Callable[[], None] | None = None) -> Iterator[None]:
    """Hold the exclusive lock of `path` for the block: another process (or thread) asking for it waits until the
    block ends. For a read-modify-write of `path`, taken before it is read and held until it is written (its
    replacement by write_atomically included: inside all_or_nothing(), hold the lock around that block).
    `waiting()`, if given, is called once when the lock is held elsewhere as it is asked for, before waiting.
    Reentrant: a block inside another of the same process for the same path shares the outer one's lock.

    The lock is an flock(2) on `path`.lock beside it, made for the purpose and removed when the block ends.
    fcntl.flock rather than a package such as filelock: the planner runs only where Drake does (Linux, macOS), the
    kernel drops a lock with its process however that process ends (no stale lock to clean up, no timeout to
    guess), and a dozen lines need no dependency. A lock file is removed while it is held, so a process that waited
    on it finds it no longer at its path once it gets it and locks the new one instead: two holders never overlap."""
    name = os.path.abspath(os.fspath(path)) + ".lock"
    with _locks_guard:
        entry = _locks.setdefault(name, [threading.RLock(), None, 0])
    with entry[0]:
        if entry[2] == 0:
            entry[1] = _lock(name, path, waiting)
        entry[2] += 1
        try:
            yield
        finally:
            entry[2] -= 1
            if entry[2] == 0:
                fd, entry[1] = entry[1], None
                with contextlib.suppress(OSError):
                    os.unlink(name)  # while held: see above
                os.close(fd)  # (releases the lock)


def _lock(name: str, path, waiting) -> int:
    """The descriptor of the lock file `name`, exclusively locked (see `exclusive`); UserError if it cannot be."""
    told = False
    while True:
        try:
            # Not following a link, not blocking on a named pipe someone put there, not a terminal.
            flags = os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_NOCTTY | os.O_CLOEXEC
            fd = os.open(name, flags, 0o666)
        except OSError as exc:
            raise UserError(f"cannot lock {path} for updating ({name}): {exc.strerror or exc}") from None
        try:
            if not stat.S_ISREG(os.fstat(fd).st_mode):
                raise UserError(f"cannot lock {path} for updating: {name} is not a lock file")
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                if waiting is not None and not told:
                    waiting()
                    told = True
                fcntl.flock(fd, fcntl.LOCK_EX)
            if _names(fd, name):
                return fd
        except OSError as exc:
            os.close(fd)
            raise UserError(f"cannot lock {path} for updating ({name}): {exc.strerror or exc}") from None
        except BaseException:
            os.close(fd)
            raise
        os.close(fd)  # the holder before removed it: lock the file at the path now


def _names(fd: int, name: str) -> bool:
    """Whether the open file `fd` is the one at path `name` (not one removed from it since it was opened)."""
    try:
        there = os.stat(name, follow_symlinks=False)
    except FileNotFoundError:
        return False
    mine = os.fstat(fd)
    return (there.st_dev, there.st_ino) == (mine.st_dev, mine.st_ino)
