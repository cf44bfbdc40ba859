"""CoACD's approximate convex decomposition, run in a child process with a time limit: it can crash (segfault on
non-manifold input) or run for minutes, and the next method is then tried."""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from app.errors import UserError
from app.scene.meshes.pieces import Piece, hull_piece, progress_bar

# coacd (optional, slow to import) is imported inside the functions that use it.

_COACD_CHILD = """
import sys, numpy as np, coacd
data = np.load(sys.argv[1])
coacd.set_log_level("error")
out = {}
for m in range(int(data["count"])):
    parts = coacd.run_coacd(coacd.Mesh(data[f"vertices{m}"], data[f"faces{m}"]), threshold=float(data["threshold"]),
                            preprocess_mode="off", seed=0)
    out.update({f"m{m}_{i}": np.asarray(v, float) for i, (v, _) in enumerate(parts)})
    print(m, flush=True)
np.savez(sys.argv[2], **out)
"""


class MethodFailed(Exception):
    """A decomposition method could not produce pieces (crash, time-out); the next method is tried."""


def coacd_pieces(meshes: list, threshold: float, timeout: float = 120.0, progress: bool = True) -> list[list[Piece]]:
    """CoACD on each closed mesh, in one child process: CoACD can crash (segfault on non-manifold input) or run for
    minutes, so it runs apart, with a time limit (`timeout` seconds per mesh)."""
    try:
        import coacd  # noqa: F401  (only to fail early with a clear message)
    except ImportError:
        raise UserError("CoACD is not installed: pip install -e '.[meshes]'") from None
    with tempfile.TemporaryDirectory(prefix="npp-coacd-") as tmp:
        source, target = Path(tmp) / "in.npz", Path(tmp) / "out.npz"
        arrays = {"count": len(meshes), "threshold": threshold}
        for m, mesh in enumerate(meshes):
            arrays[f"vertices{m}"] = np.asarray(mesh.vertices, float)
            arrays[f"faces{m}"] = np.asarray(mesh.faces, np.int64)
        np.savez(source, **arrays)
        child = subprocess.Popen(
            [sys.executable, "-c", _COACD_CHILD, str(source), str(target)],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        faces = sum(len(m.faces) for m in meshes)
        bar = progress_bar(
            desc=f"CoACD ({len(meshes)} part(s), {faces} faces)",
            bar_format="{desc}: {elapsed}",
            mininterval=0.5,
            disable=not progress,
        )
        started = time.perf_counter()
        limit = timeout * len(meshes)
        try:
            while child.poll() is None:
                if time.perf_counter() - started > limit:
                    child.kill()
                    child.wait()
                    raise MethodFailed(f"CoACD did not finish in {limit:.0f} s")
                time.sleep(0.1)
                bar.update(1)
        finally:
            bar.close()
        if child.returncode != 0 or not target.is_file():
            raise MethodFailed(f"CoACD failed (exit code {child.returncode})")
        result = [[] for _ in meshes]
        with np.load(target) as out:
            for k in sorted(out.files, key=lambda k: tuple(int(x) for x in k[1:].split("_"))):
                v = out[k]
                if len(v) >= 4:
                    result[int(k[1:].split("_")[0])].append(hull_piece(v))
    return result


def coacd_version() -> str | None:
    try:
        from importlib.metadata import version

        return version("coacd")
    except Exception:
        return None
