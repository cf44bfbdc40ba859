"""Drake without a network: a download cache in which Drake starts with DRAKE_ALLOW_NETWORK=none.

Drake 1.51 registers the remote package `drake_models` in every PackageMap and, with networking off, refuses to
construct one unless the download cache already holds it. Nothing here uses drake_models, so an empty stand-in
serves: a stray package://drake_models/... then fails with "file not found", at once, instead of downloading. The
test session and `bench audit`'s bad-input cases (app.bench.bad_input.run_case) run Drake this way.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path


def offline_drake_cache(cache: Path) -> Path:
    """`cache` made a download cache (XDG_CACHE_HOME) in which Drake, with DRAKE_ALLOW_NETWORK=none, starts offline
    (module docstring); returns it."""
    import pydrake

    manifest = Path(pydrake.__file__).parent / "share/drake/multibody/parsing/drake_models.json"
    remote = json.loads(manifest.read_text())
    # Drake 1.51 names a cached package "<archive sha256>-<sha256 of strip_prefix>".
    key = f"{remote['sha256']}-{hashlib.sha256(remote['strip_prefix'].encode()).hexdigest()}"
    package = Path(cache) / "drake" / "package_map" / key
    package.mkdir(parents=True, exist_ok=True)
    (package / "package.xml").write_text(
        '<?xml version="1.0"?><package format="2"><name>drake_models</name><version>0</version>'
        "<description>offline stand-in</description><maintainer email='x@example.com'>x</maintainer>"
        "<license>none</license></package>"
    )
    return Path(cache)
