"""Local sweep workers: they end with the sweep's process, even when it is killed with SIGKILL."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads the process table in /proc")


def _live_children(pid: int) -> set[int]:
    """Processes whose parent is `pid` and that are not zombies (a zombie has ended; only its entry is left)."""
    out = set()
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:  # ended while we looked
            continue
        state, ppid = stat[stat.rindex(")") + 2 :].split()[:2]
        if int(ppid) == pid and state != "Z":
            out.add(int(entry.name))
    return out


def _alive(pids: set[int]) -> set[int]:
    alive = set()
    for pid in pids:
        try:
            state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except OSError:
            continue
        if state != "Z":
            alive.add(pid)
    return alive


def test_workers_end_when_the_sweep_is_killed(tmp_path):
    parent = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "app",
            "bench",
            "plan",
            "--scenes",
            "bar-3link",
            "--samplers",
            "uniform",
            "--narrow",
            "5",
            "--uniform",
            "20",
            "--seeds",
            "500",  # far more than it can run before the kill
            "--workers",
            "2",
            "--store",
            tmp_path / "r.sqlite",
        ],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env=os.environ.copy(),
    )
    children = set()
    try:
        deadline = time.monotonic() + 120
        # Two pool workers and multiprocessing's resource tracker.
        while len(children) < 3 and parent.poll() is None and time.monotonic() < deadline:
            children |= _live_children(parent.pid)
            time.sleep(0.2)
        assert len(children) >= 3, children
        parent.send_signal(signal.SIGKILL)
        parent.wait()
        deadline = time.monotonic() + 10
        while _alive(children) and time.monotonic() < deadline:
            time.sleep(0.2)
        assert not _alive(children)
    finally:
        parent.kill()
        for pid in _alive(children):  # only if the test failed: do not leave them behind either
            os.kill(pid, signal.SIGKILL)
