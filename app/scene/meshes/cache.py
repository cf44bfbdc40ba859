"""The on-disk cache of decompositions (`decompose`: a mesh file's convex pieces, from the cache or built and
cached) and of converted .obj files (`converted_obj`), each entry sealed with an HMAC under a per-user key kept
outside the cache (see the package's docstring)."""

from __future__ import annotations

import hashlib
import hmac
import json
import os
import secrets
import shutil
import tempfile
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from app.errors import PlannerWarning, UserError
from app.io import check_input, write_atomically
from app.scene.files import MESH_METHODS
from app.scene.meshes import decomposition
from app.scene.meshes.coacd_process import coacd_version
from app.scene.meshes.decomposition import classify, default_tolerance, method_name
from app.scene.meshes.merging import MERGE_REACH
from app.scene.meshes.pieces import Piece, hull_piece
from app.scene.meshes.reading import file_sha256, load_mesh
from app.scene.meshes.validation import volume_report

# Bump when anything that changes the pieces (or the files of an entry) changes: old cache entries then go unused.
DECOMPOSER_VERSION = "9"
CACHE_ENV = "NPP_CACHE_DIR"
KEY_ENV = "NPP_KEY_FILE"
KEY_BYTES = 32


# ---- where the cache is -------------------------------------------------------------------------------------------
def writable_folder(folder: Path) -> Path:
    """`folder`, made if missing; one line naming the cache's variable where it cannot be."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        reason = exc.strerror or exc
        raise UserError(f"cannot write {folder}: {reason} (set {CACHE_ENV} to a writable folder)") from None
    return folder


def cache_root() -> Path:
    """$NPP_CACHE_DIR, else $XDG_CACHE_HOME/npp, else ~/.cache/npp; absolute (generated model files name the
    cached meshes by file:// URIs, which must not depend on the working directory)."""
    if os.environ.get(CACHE_ENV):
        return Path(os.environ[CACHE_ENV]).absolute()
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return (Path(base) / "npp").absolute()


# ---- the cache's key ----------------------------------------------------------------------------------------------
def key_path() -> Path:
    """The secret key that seals cache entries: $NPP_KEY_FILE, else $XDG_CONFIG_HOME/npp/cache.key, else
    ~/.config/npp/cache.key. Outside the cache on purpose: a cache folder is something one may be handed, copy or
    share, and a seal made with a key that travels with it would prove nothing."""
    if os.environ.get(KEY_ENV):
        return Path(os.environ[KEY_ENV]).expanduser().absolute()
    base = os.environ.get("XDG_CONFIG_HOME") or str(Path.home() / ".config")
    return (Path(base) / "npp" / "cache.key").absolute()


_keys: dict[Path, bytes | None] = {}  # per key file: its key, or None when it cannot be used (said once)


def cache_key() -> bytes | None:
    """This user's key (made on first use), or None when it cannot be read or made: then one line says so and no
    cached entry is reused in this process (entries are still written, unsealed, so they are never trusted)."""
    path = key_path()
    if path not in _keys:
        try:
            _keys[path] = _load_key(path)
        except OSError as exc:
            reason = exc.strerror or str(exc)
            _warn(
                f"cannot use the mesh cache key {path}: {reason}; cached meshes are not reused (set {KEY_ENV} to a "
                "file of yours)"
            )
            _keys[path] = None
    return _keys[path]


def _load_key(path: Path) -> bytes:
    """The key in `path`; made when missing: KEY_BYTES random bytes in a private temporary file, linked into place
    (mode 0600, whole or not at all; when two processes make it at once, both then read the one that was linked
    first). A key file that others may read or write, or not of the key's size, is refused (OSError)."""
    for _ in range(3):
        try:
            with open(path, "rb") as f:
                status = os.fstat(f.fileno())
                key = f.read(KEY_BYTES + 1)
        except FileNotFoundError:
            _make_key(path)
            continue
        if hasattr(os, "getuid") and status.st_uid != os.getuid():
            raise OSError(0, "it belongs to another user")
        if status.st_mode & 0o077:
            raise OSError(0, f"others may read or write it (mode {status.st_mode & 0o777:o}; chmod 600 it)")
        if len(key) != KEY_BYTES:
            raise OSError(0, f"it holds {len(key)} bytes, not a key of {KEY_BYTES}")
        return key
    raise OSError(0, "it vanished while being made")


def _make_key(path: Path) -> None:
    path.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)  # mode 0600
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(secrets.token_bytes(KEY_BYTES))
            f.flush()
            os.fsync(f.fileno())
        try:
            os.link(tmp, path)  # fails if another process made the key meanwhile: theirs is kept
        except FileExistsError:
            pass
        except OSError:  # a filesystem without hard links
            if not path.exists():
                os.rename(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def _seal(key: bytes, kind: str, payload: bytes) -> str:
    """HMAC-SHA256 of `payload` under `key`, for `kind` of record (so a seal of one kind is none of another)."""
    return hmac.new(key, kind.encode() + b"\0" + payload, hashlib.sha256).hexdigest()


def _canonical(record: dict) -> bytes:
    """The one byte string of a JSON record (as read back: lists, not tuples), which its seal covers."""
    return json.dumps(record, sort_keys=True, separators=(",", ":")).encode()


def _warn(message: str) -> None:
    """What this module reports without raising: a PlannerWarning (one line on the command line)."""
    warnings.warn(message, PlannerWarning, stacklevel=3)


# ---- decompositions -----------------------------------------------------------------------------------------------
@dataclass
class Decomposition:
    """A cache entry: convex pieces as .obj files (for Drake) plus the original as .obj (for visuals)."""

    directory: Path
    method: str
    pieces: list[Path]
    visual: Path
    facts: dict = field(default_factory=dict)
    validation: dict = field(default_factory=dict)
    parts: dict = field(default_factory=dict)  # connected parts per method
    volume: dict = field(default_factory=dict)  # what the pieces add (`volume_report`)
    seconds: float = 0.0
    from_cache: bool = False
    bounds: list = field(default_factory=list)  # the mesh's box [lo, hi], from the verified manifest
    build_seconds: float = 0.0  # what building the entry took

    def extent(self) -> tuple[np.ndarray, np.ndarray]:
        return np.array(self.bounds[0]), np.array(self.bounds[1])


def obj_bytes(vertices: np.ndarray, faces: np.ndarray) -> bytes:
    """A Wavefront .obj of the triangles, exactly as `_write_obj` writes it."""
    lines = [f"v {x:.17g} {y:.17g} {z:.17g}" for x, y, z in vertices]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    return ("\n".join(lines) + "\n").encode()


def _write_obj(path: Path, vertices: np.ndarray, faces: np.ndarray) -> str:
    """Write a Wavefront .obj; returns the sha256 of what was written."""
    data = obj_bytes(vertices, faces)
    path.write_bytes(data)
    return hashlib.sha256(data).hexdigest()


def decompose(
    path: str | Path,
    method: str = "auto",
    tolerance: float | None = None,
    coacd_threshold: float = 0.03,
    coacd_timeout: float = 120.0,
    cache_dir: Path | None = None,
    progress: bool = True,
    conservative: bool = False,
    scale: float = 1.0,
) -> Decomposition:
    """Convex pieces for the mesh at `path`, from the cache when a valid entry exists, else built and cached. A mesh
    with no valid decomposition is cached too: asking again raises the same UserError at once. `conservative`: a robot's
    link, bounded by hulls that reach at most MERGE_REACH beyond the mesh (see `decompose_parts`); `scale`:
    metres per unit of the mesh file (its largest factor where a model scales it), which sets that reach in the
    file's units."""
    path = Path(path)
    started = time.perf_counter()
    root, key, digest, params = _entry_key(path, method, tolerance, coacd_threshold, cache_dir, conservative, scale)
    entry = root / key
    secret = cache_key()
    found = _read_entry(entry, key, secret)
    if found is not None:
        found.seconds = time.perf_counter() - started
        return found
    if entry.exists():
        if secret is not None:  # (without a key nothing is reused, and cache_key has said so)
            _warn(f"mesh cache entry {entry} is damaged; rebuilding it")
        shutil.rmtree(entry, ignore_errors=True)

    manifest = {"key": key, "source": str(path.resolve()), "source_sha256": digest, "params": params}
    request = _Request(
        path, method, tolerance, coacd_threshold, coacd_timeout, progress, conservative, params["merge_reach"]
    )

    def store_failure(failed: dict) -> None:
        if secret is not None:  # (unsealed, it would never be read back)
            _store(root, entry, failed, lambda staging: None, secret)

    mesh, pieces = _build(request, manifest, store_failure)

    def write(staging: Path) -> None:
        (staging / "pieces").mkdir()
        files = {name: _write_obj(staging / name, p.vertices, p.faces) for name, p in zip(manifest["pieces"], pieces)}
        files["visual.obj"] = _write_obj(staging / "visual.obj", mesh.vertices, mesh.faces)
        manifest.update(files=files, build_seconds=time.perf_counter() - started)

    _store(root, entry, manifest, write, secret)
    result = _read_entry(entry, key, secret, written=manifest)
    if result is None:
        raise UserError(f"cannot write the mesh cache at {entry}")
    result.seconds = time.perf_counter() - started
    result.from_cache = False
    return result


def _entry_key(path: Path, method, tolerance, coacd_threshold, cache_dir, conservative, scale) -> tuple:
    """Where `decompose`'s entry for these arguments lives: the cache's meshes folder, the key, the file's hash and
    the parameters the key covers."""
    if method not in MESH_METHODS:
        raise UserError(f"unknown decomposition method '{method}' (known: {', '.join(MESH_METHODS)})")
    digest = file_sha256(check_input(path, "mesh file"))
    params = {
        "method": method,
        "tolerance": tolerance,
        "coacd_threshold": coacd_threshold,
        "version": DECOMPOSER_VERSION,
        "coacd": coacd_version() if method == "coacd" else None,
        "conservative": conservative,
        "merge_reach": MERGE_REACH / scale if conservative and scale > 0 else None,
    }
    key = hashlib.sha256((digest + json.dumps(params, sort_keys=True)).encode()).hexdigest()[:32]
    return (cache_dir or cache_root()) / "meshes", key, digest, params


def is_cached(
    path: str | Path,
    method: str = "auto",
    tolerance: float | None = None,
    coacd_threshold: float = 0.03,
    cache_dir: Path | None = None,
    conservative: bool = False,
    scale: float = 1.0,
) -> bool:
    """Whether `decompose` with these arguments would read a valid entry (or a stored failure) from the cache."""
    root, key, _, _ = _entry_key(Path(path), method, tolerance, coacd_threshold, cache_dir, conservative, scale)
    try:
        return _read_entry(root / key, key, cache_key()) is not None
    except UserError:
        return True  # a stored failure


def decompose_each(requests: str) -> None:
    """`decompose` for each of a JSON list of keyword dicts, each stored in the cache (failures too, as `decompose`
    stores them): a child interpreter's work, see app.scene.prepare_meshes.MeshOptions.warm."""
    for request in json.loads(requests):
        try:
            decompose(**{**request, "cache_dir": request["cache_dir"] and Path(request["cache_dir"])})
        except UserError:
            pass  # (stored: the parent, asking again, reads and raises it)


@dataclass
class _Request:
    """What `decompose` was asked for."""

    path: Path
    method: str
    tolerance: float | None
    coacd_threshold: float
    coacd_timeout: float
    progress: bool
    conservative: bool
    merge_reach: float | None  # in the mesh's units (None: no merging)


def _build(request: _Request, manifest: dict, store_failure) -> tuple:
    """The mesh and its pieces, with what the entry's manifest records of them (method, parts, volume, every round
    of validation, facts, box, piece files). A decomposition that fails is stored by `store_failure(manifest)`
    (sealed, so asking again fails at once) and raised; a mesh that cannot be read is only raised."""
    path = request.path
    mesh = load_mesh(path)
    tolerance = float(request.tolerance) if request.tolerance else default_tolerance(mesh)
    if not tolerance > 0:
        raise UserError("mesh tolerance must be positive")
    facts = classify(mesh)
    try:
        pieces, components, tried, methods, parts = decomposition.decompose_parts(
            mesh,
            request.method,
            tolerance,
            request.coacd_threshold,
            request.coacd_timeout,
            request.progress,
            path.name,
            request.conservative,
            request.merge_reach,
        )
        if not pieces:
            raise UserError(f"no valid convex decomposition for {path.name}: no piece has any volume")
    except UserError as exc:
        store_failure({**manifest, "error": str(exc), "files": {}})
        raise
    facts["components"] = components
    manifest.update(
        tolerance=tolerance,
        method=method_name(methods),
        methods=methods,
        parts=parts,
        volume=volume_report(mesh, pieces, facts["closed"]),
        tried=tried,
        facts=facts,
        bounds=mesh.bounds.tolist(),
        pieces=[f"pieces/{i:05d}.obj" for i in range(len(pieces))],
    )
    return mesh, pieces


def _store(root: Path, entry: Path, manifest: dict, write, secret: bytes | None) -> None:
    """A cache entry: `write(staging)` fills a staging folder, then manifest.json and its seal manifest.mac (none
    without a key: such an entry is never trusted), then the folder is renamed into place (atomic: a reader sees no
    entry or a whole one)."""
    try:
        root.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(prefix=f".{entry.name}-", dir=root))
        write(staging)
        text = json.dumps(manifest, indent=1)
        (staging / "manifest.json").write_text(text)
        if secret is not None:
            (staging / "manifest.mac").write_text(_seal(secret, "mesh-cache-entry", _canonical(json.loads(text))))
        try:
            os.replace(staging, entry)
        except OSError:  # another process won the race; use theirs if it is whole
            shutil.rmtree(staging, ignore_errors=True)
    except OSError as exc:
        raise UserError(
            f"cannot write the mesh cache under {root}: {exc.strerror or exc} (set {CACHE_ENV} to a writable folder)"
        ) from None


def _read_entry(entry: Path, key: str, secret: bytes | None, written: dict | None = None) -> Decomposition | None:
    """The entry if it is one this code made for this key: its manifest parses, its seal (manifest.mac, an HMAC under
    this user's key) matches the manifest, and every file matches its checksum in it; else None. Without a key, only
    the entry just `written` (the same manifest, build time aside) is taken. An entry that records a failed
    decomposition raises its UserError again."""
    try:
        manifest = json.loads((entry / "manifest.json").read_text())
        if secret is not None:
            seal = (entry / "manifest.mac").read_text().strip()
            if not hmac.compare_digest(seal.encode(), _seal(secret, "mesh-cache-entry", _canonical(manifest)).encode()):
                return None
        elif written is None or {**manifest, "build_seconds": 0} != {
            **json.loads(json.dumps(written)),
            "build_seconds": 0,
        }:
            return None
        if manifest.get("key") != key:
            return None
        if "error" in manifest:
            raise UserError(f"{manifest['error']} (cached; delete {entry} to try again)")
        for name, digest in manifest["files"].items():
            if hashlib.sha256((entry / name).read_bytes()).hexdigest() != digest:
                return None
        pieces = [entry / name for name in manifest["pieces"]]
        if not pieces or any(name not in manifest["files"] for name in manifest["pieces"]):
            return None
        return Decomposition(
            directory=entry,
            method=manifest["method"],
            pieces=pieces,
            visual=entry / "visual.obj",
            facts=manifest["facts"],
            validation=manifest["tried"][-1],
            parts=manifest["parts"],
            volume=manifest["volume"],
            from_cache=True,
            bounds=manifest["bounds"],
            build_seconds=float(manifest.get("build_seconds", 0.0)),
        )
    except (OSError, ValueError, KeyError, TypeError, IndexError, AttributeError):
        return None


def converted_obj(path: str | Path, cache_dir: Path | None = None) -> Path:
    """A mesh Drake cannot read (.stl, .dae, ...) as an .obj in the cache (keyed by content): the shape unchanged,
    so as a collision shape Drake uses its convex hull (conservative, as usual for robot links). Sealed as decomposition
    entries are (`<key>.obj.mac` beside it: an HMAC of the key and the file's sha256 under this user's key): a
    converted file that does not verify is converted again, since a forged one would be another shape."""
    path = check_input(path, "mesh file")
    key = hashlib.sha256((file_sha256(path) + "convert" + DECOMPOSER_VERSION).encode()).hexdigest()[:32]
    target = (cache_dir or cache_root()) / "converted" / f"{key}.obj"
    seal_file = target.with_name(f"{target.name}.mac")
    secret = cache_key()
    if secret is not None and target.is_file():
        if _converted_seal_holds(secret, key, target, seal_file):
            return target
        _warn(f"mesh cache entry {target} is damaged; rebuilding it")
    mesh = load_mesh(path)
    data = obj_bytes(mesh.vertices, mesh.faces)
    target.parent.mkdir(parents=True, exist_ok=True)
    write_atomically(target, data)
    if secret is not None:
        write_atomically(seal_file, _converted_seal(secret, key, hashlib.sha256(data).hexdigest()))
    return target


def _converted_seal(secret: bytes, key: str, digest: str) -> str:
    return _seal(secret, "converted-obj", f"{key}\0{digest}".encode())


def _converted_seal_holds(secret: bytes, key: str, target: Path, seal_file: Path) -> bool:
    try:
        seal = seal_file.read_text().strip()
        digest = file_sha256(target)
    except (OSError, ValueError):
        return False
    return hmac.compare_digest(seal.encode(), _converted_seal(secret, key, digest).encode())


def load_pieces(found: Decomposition) -> list[Piece]:
    """The pieces back as half-space form (for tests and checks)."""
    out = []
    for p in found.pieces:
        verts = [list(map(float, line.split()[1:4])) for line in p.read_text().splitlines() if line.startswith("v ")]
        out.append(hull_piece(np.array(verts)))
    return out
