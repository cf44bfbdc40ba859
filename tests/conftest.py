"""Tests run offline: DRAKE_ALLOW_NETWORK=none makes any download fail at once.

Drake 1.51 registers the remote package `drake_models` in every PackageMap and, with networking off, refuses to
construct one unless the download cache already holds it. We never use drake_models, so the tests give Drake a
private cache with an empty stand-in (app.scene.offline.offline_drake_cache, which `bench audit` also uses): a
stray package://drake_models/... then fails with "file not found", immediately and offline, instead of downloading.

Collecting the tests imports the core only: the command line (which loads every command and experiment) is imported
by the `cli` fixture when a test uses it.
"""

import atexit
import os
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

import app  # noqa: F401  (before pydrake: it sets OpenMP's wait policy, see app/__init__.py)
from app.scene.offline import offline_drake_cache

os.environ["DRAKE_ALLOW_NETWORK"] = "none"
os.environ["XDG_CACHE_HOME"] = str(offline_drake_cache(Path(tempfile.mkdtemp(prefix="npp-drake-cache-"))))
# The mesh cache's secret key (app.scene.meshes.cache.key_path): the session's own, never the user's ~/.config/npp.
os.environ["NPP_KEY_FILE"] = str(Path(tempfile.mkdtemp(prefix="npp-key-")) / "cache.key")
os.environ.setdefault("MPLBACKEND", "Agg")
# The Ctrl-C tests need Ctrl-C to raise KeyboardInterrupt, as in a terminal; a run started in the background by a
# script (`make test &`) inherits SIGINT ignored, in this process and in the commands it starts.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


_CPU_COUNT = os.cpu_count() or 1


@pytest.fixture
def two_cores(monkeypatch):
    """At least two cores as an oracle made in the test sees them, so that its helper processes are tested on any
    machine (an oracle starts no more of them than there are cores)."""
    monkeypatch.setattr(os, "cpu_count", lambda: max(2, _CPU_COUNT))


@pytest.fixture(scope="session")
def oracles():
    """One oracle per scene, built once per test session (building is the slow part)."""
    from app.checking.oracle import CollisionOracle
    from app.scene.model import Scene

    cache = {}

    def get(name: str) -> CollisionOracle:
        if name not in cache:
            cache[name] = CollisionOracle(Scene(name))
        return cache[name]

    return get


@pytest.fixture(scope="session")
def checkers(oracles):
    """`checkers(name)`: a fresh QueryContext (its own counters, no budget) on the session's oracle of the scene."""
    return lambda name: oracles(name).context()


# ---- the command line ---------------------------------------------------------------------------------------------
# `cli` runs a command in this process (app.cli.main), `run_app` as `python -m app` in a child process (for what
# only the entry point does). Both answer a subprocess.CompletedProcess, which `one_line_error` checks.
@pytest.fixture
def cli(capsys):
    """`cli("plan", "bar", ...)`: app.cli.main on these arguments; returncode, stdout and stderr of that call."""

    from app.cli import main

    def run(*args) -> subprocess.CompletedProcess:
        capsys.readouterr()  # what earlier calls printed is not this call's output
        code = main([str(a) for a in args])
        out, err = capsys.readouterr()
        return subprocess.CompletedProcess(["python", "-m", "app", *args], code, out, err)

    return run


@pytest.fixture
def run_app():
    """`run_app("plan", "bar", ..., env=None)`: `python -m app ...` in a child process."""

    def run(*args, env=None, timeout=300) -> subprocess.CompletedProcess:
        return subprocess.run(
            [sys.executable, "-m", "app", *map(str, args)],
            capture_output=True,
            text=True,
            env=os.environ.copy() if env is None else env,
            stdin=subprocess.DEVNULL,
            timeout=timeout,
        )

    return run


@pytest.fixture
def one_line_error():
    """`one_line_error(result, code)`: the command failed with exit code `code` and said so in one line on stderr,
    "error: ...", without a traceback; returns that line."""

    def check(result: subprocess.CompletedProcess, code: int) -> str:
        assert result.returncode == code, (result.returncode, result.stderr)
        lines = result.stderr.strip().splitlines()
        assert len(lines) == 1, result.stderr
        assert lines[0].startswith("error:"), result.stderr
        assert "Traceback" not in result.stderr
        return lines[0]

    return check


def pytest_terminal_summary(terminalreporter):
    """The browser tests skipped for want of Chromium (tests/chromium.py), in one line naming what runs them."""
    from chromium import MISSING

    skipped = [r for r in terminalreporter.stats.get("skipped", []) if MISSING in str(r.longrepr)]
    if skipped:
        terminalreporter.write_line(f"{len(skipped)} browser test(s) skipped: {MISSING}")


# OMPL's nanobind bindings report "leaked" objects while the interpreter shuts down (harmless: the process is ending).
# When OMPL was loaded, end the process right after pytest is done, so the test summary stays the last thing printed.
_exit_status = None


def pytest_sessionfinish(session, exitstatus):
    global _exit_status
    _exit_status = int(exitstatus)


@atexit.register
def _end_before_ompl_reports_leaks():
    if "ompl" in sys.modules and _exit_status is not None:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(_exit_status)
