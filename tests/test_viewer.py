"""The Meshcat viewer: the standalone page, what it holds, the `view` command's errors, atomic writes.

Tests run with DRAKE_ALLOW_NETWORK=none (conftest), which also disables Meshcat. Drake reads the variable each time a
Meshcat is made, so tests that need one allow it with monkeypatch (in-process) or in a subprocess's environment.
"""

import json
import os
import queue
import re
import signal
import subprocess
import sys
import threading
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest

from app.errors import UserError
from meshcat_page import commands

FPS = 64  # MeshcatVisualizer's default publish period is 1/64 s: one recorded frame per period


@pytest.fixture
def meshcat_allowed(monkeypatch):
    monkeypatch.setenv("DRAKE_ALLOW_NETWORK", "meshcat")


def straight_trajectory(oracle, duration=2.0):
    """start -> goal in a straight line (through the wall: the viewer does not care), times evenly spread."""
    Q = oracle.space.interpolate(oracle.scene.start, oracle.scene.goal, resolution=2.0)
    return np.linspace(0.0, duration, len(Q)), Q


def trajectory_doc(times, positions, narrow=None, on_path=None, path=None, scene=None) -> dict:
    """A trajectory file's object (app/motion/trajectory.py's schema) for a motion through `positions`; of `scene`
    (a Scene: its name and coordinate names), which `view` asks for, else of a made-up one."""
    from app.motion.trajectory import SCHEMA

    times, positions = np.asarray(times, float), np.asarray(positions, float)
    waypoints = positions[[0, -1]] if path is None else np.asarray(path, float)
    doc = {
        "schema": SCHEMA,
        "scene": scene.name if scene else "test",
        "joint_names": list(scene.coordinate_names) if scene else [f"j{i}" for i in range(positions.shape[1])],
        "time_from_start": times.tolist(),
        "positions": positions.tolist(),
        "velocities": np.zeros_like(positions).tolist(),
        "accelerations": np.zeros_like(positions).tolist(),
        "waypoints": waypoints.tolist(),
        "waypoint_times": np.linspace(0, times[-1], len(waypoints)).tolist(),
        "certified": False,
    }
    if narrow is not None:
        doc["narrow_samples"], doc["narrow_on_path"] = np.asarray(narrow).tolist(), list(on_path)
    return doc


def write_trajectory(file, times, positions, **extra):
    file.write_text(json.dumps(trajectory_doc(times, positions, **extra)))
    return file


def test_view_writes_a_standalone_page_with_the_recorded_animation(tmp_path, oracles, meshcat_allowed, cli):
    oracle = oracles("bar")
    times, Q = straight_trajectory(oracle, duration=2.0)
    narrow = Q[::3]
    on_path = [bool(i % 2) for i in range(len(narrow))]
    trajectory = write_trajectory(
        tmp_path / "t.json", times, Q, narrow=narrow, on_path=on_path, path=Q[[0, -1]], scene=oracle.scene
    )
    page = tmp_path / "bar.html"

    result = cli("view", "bar", "--trajectory", trajectory, "--html", page)
    assert result.returncode == 0, result.stderr
    assert result.stdout == "" and result.stderr.splitlines() == [f"wrote {page}"]  # files named on stderr
    html = page.read_text()
    assert html.lstrip().lower().startswith("<!doctype html") or html.lstrip().startswith("<html")
    # Standalone: no script or stylesheet fetched from anywhere (the JavaScript is inlined).
    assert not re.search(r"<script[^>]*\bsrc\s*=", html, re.I)
    assert not re.search(r"<link[^>]*\bhref\s*=\s*[\"']?https?:", html, re.I)
    assert [p.name for p in tmp_path.iterdir() if p.name.endswith(".tmp")] == []

    cmds = commands(html)
    objects = {c["path"] for c in cmds if c["type"] == "set_object"}
    assert {"/samples/narrow", "/samples/on_path", "/path", "/passage/box0"} <= objects
    assert any(p.startswith("/drake/illustration/arm/link7") for p in objects)
    # The samples: yellow off the path, red on it, each point at the passage frame's world position.
    clouds = {c["path"]: c["object"] for c in cmds if c["type"] == "set_object" and c["path"].startswith("/samples/")}
    frame_xyz = oracle.workspace.frame_positions(narrow)
    flags = np.array(on_path)
    yellow = lambda r, g, b: r > 200 and g > 180 and b < 60  # noqa: E731
    red = lambda r, g, b: r > 200 and g < 60 and b < 60  # noqa: E731
    for path, is_colour, expected in [
        ("/samples/narrow", yellow, frame_xyz[~flags]),
        ("/samples/on_path", red, frame_xyz[flags]),
    ]:
        cloud = clouds[path]
        (material,) = cloud["materials"]
        rgb = material["color"]
        assert material["type"] == "PointsMaterial" and is_colour(rgb >> 16, (rgb >> 8) & 255, rgb & 255), hex(rgb)
        kind, code, raw = cloud["geometries"][0]["data"]["attributes"]["position"]["array"]
        xyz = np.frombuffer(raw, "<f4").reshape(-1, 3)
        np.testing.assert_allclose(xyz, expected, atol=1e-3)
    # The animation: every moving robot body has a track whose last key is the last frame (2 s at 64 fps).
    (animation,) = [c for c in cmds if c["type"] == "set_animation"]
    tracks = {a["path"]: a["clip"] for a in animation["animations"]}
    assert "/drake/illustration/arm/link7" in tracks
    clip = tracks["/drake/illustration/arm/link7"]
    assert clip["fps"] == FPS
    position = next(t for t in clip["tracks"] if t["name"] == ".position")
    assert len(position["keys"]) == len(times)
    assert position["keys"][-1]["time"] == round(times[-1] * FPS)
    # The recorded base positions follow the trajectory (x goes from start to goal).
    base = next(t for t in tracks["/drake/illustration/arm/base"]["tracks"] if t["name"] == ".position")
    xs = [k["value"][0] for k in base["keys"]]
    assert xs[0] == pytest.approx(oracle.scene.start[0]) and xs[-1] == pytest.approx(oracle.scene.goal[0])


def test_viewer_frame_positions_agree_with_the_oracle(oracles, meshcat_allowed):
    """The viewer's second diagram must read a configuration exactly as the oracle's does."""
    from app.viewer import Viewer

    oracle = oracles("joint3d")
    viewer = Viewer(oracle.scene)
    Q = oracle.space.uniform(np.random.default_rng(1), 20)
    np.testing.assert_allclose(viewer.frame_positions(Q), oracle.workspace.frame_positions(Q), atol=1e-9)
    with pytest.raises(UserError):
        viewer.show_samples(Q[:4], [True, False])
    with pytest.raises(UserError):
        viewer.show_path(Q[:, :3])
    with pytest.raises(UserError):
        Viewer(oracle.scene, frame="no_such_frame", meshcat=viewer.meshcat)
    assert viewer.url().startswith("http://localhost:")
    # A 3D scene's obstacles are see-through, so the robot shows behind walls; the robot stays opaque.
    opacity = {
        c["path"]: c["value"]
        for c in commands(viewer.html())
        if c["type"] == "set_property" and c["property"] == "modulated_opacity"
    }
    obstacles = [v for p, v in opacity.items() if p.startswith("/drake/illustration/obstacles/")]
    robot = [v for p, v in opacity.items() if p.startswith("/drake/illustration/lbody/")]
    assert obstacles and all(v < 1 for v in obstacles)
    assert robot and all(v == 1 for v in robot)


def test_wrong_dimension_is_exit_2_and_writes_nothing(tmp_path, oracles, meshcat_allowed, cli, one_line_error):
    times, Q = straight_trajectory(oracles("bar"))
    trajectory = write_trajectory(tmp_path / "t.json", times, Q[:, :6])
    page = tmp_path / "out.html"
    line = one_line_error(cli("view", "bar", "--trajectory", trajectory, "--html", page), 2)
    assert "9" in line and "6" in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.json"]


def _bad(**change):
    """A valid 9-coordinate, two-sample trajectory file with `change` applied (a None value removes the key)."""
    doc = trajectory_doc([0.0, 1.0], np.zeros((2, 9)))
    for key, value in change.items():
        if value is None:
            doc.pop(key)
        else:
            doc[key] = value
    return json.dumps(doc)


@pytest.mark.parametrize(
    "content, needle",
    [
        (None, "not found"),
        ('{"time_from_start": [0, 1], "positions": ', "cannot read"),
        ("[1, 2]", "JSON object"),
        (_bad(schema="other/9"), "schema"),
        (_bad(speed=3), "unknown key"),
        (_bad(velocities=None), "missing key"),
        (_bad(time_from_start=[0.0]), "rows of 'positions' for 1 times"),
        (_bad(time_from_start=[1.0, 0.0]), "non-decreasing"),
        (_bad(positions=[[0] * 8 + ["x"]] * 2), "numbers"),
        (_bad(joint_names=["a"]), "joint_names"),
        (_bad(narrow_samples=[[1, 2]], narrow_on_path=[True]), "narrow_samples"),
        (_bad(narrow_samples=[[0] * 9], narrow_on_path=[True, False]), "narrow_on_path"),
        (_bad(narrow_samples=[[0] * 9]), "go together"),
        (_bad(certified="yes"), "certified"),
    ],
)
def test_bad_trajectory_files_are_one_line_exit_2(tmp_path, cli, one_line_error, content, needle):
    trajectory = tmp_path / "t.json"
    if content is not None:
        trajectory.write_text(content)
    page = tmp_path / "out.html"
    line = one_line_error(cli("view", "bar", "--trajectory", trajectory, "--html", page), 2)
    assert needle in line
    assert not page.exists()


def test_meshcat_disabled_by_the_environment_is_a_clear_error(tmp_path, oracles, cli, one_line_error):
    """conftest sets DRAKE_ALLOW_NETWORK=none: the viewer says how to allow Meshcat rather than overriding it."""
    assert os.environ["DRAKE_ALLOW_NETWORK"] == "none"
    times, Q = straight_trajectory(oracles("bar"))
    trajectory = write_trajectory(tmp_path / "t.json", times, Q, scene=oracles("bar").scene)
    page = tmp_path / "out.html"
    line = one_line_error(cli("view", "bar", "--trajectory", trajectory, "--html", page), 2)
    assert "DRAKE_ALLOW_NETWORK" in line and "meshcat" in line
    assert not page.exists()


def test_html_into_a_missing_folder_is_exit_2(tmp_path, oracles, meshcat_allowed, cli, one_line_error):
    times, Q = straight_trajectory(oracles("bar"))
    trajectory = write_trajectory(tmp_path / "t.json", times, Q)
    page = tmp_path / "missing" / "out.html"
    line = one_line_error(cli("view", "bar", "--trajectory", trajectory, "--html", page), 2)
    assert "does not exist" in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.json"]


def test_a_failed_write_leaves_the_old_file_and_no_temporary(tmp_path):
    from app.io import write_atomically

    target = tmp_path / "page.html"
    target.write_text("old")

    with pytest.raises(TypeError):
        write_atomically(target, object())  # f.write refuses it after the temporary file exists
    assert target.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["page.html"]
    write_atomically(target, "new")
    assert target.read_text() == "new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["page.html"]


def _served_plan(stdout: Path, *flags) -> tuple[subprocess.Popen, queue.Queue]:
    """`plan bar-3link --json --meshcat *flags` in a child process without a terminal (stdin /dev/null, as in Docker
    without -t), its answer into the file `stdout` (a pipe would fill up unread); its stderr lines arrive on the queue
    (None at its end)."""
    with stdout.open("w") as answer:  # the child has its own copy of the file
        child = subprocess.Popen(
            [sys.executable, "-m", "app", "plan", "bar-3link", "--json", "--meshcat", *flags],
            stdin=subprocess.DEVNULL,
            stdout=answer,
            stderr=subprocess.PIPE,
            text=True,
            env=dict(os.environ, DRAKE_ALLOW_NETWORK="meshcat"),
        )
    lines = queue.Queue()

    def forward():
        with child.stderr:
            for line in child.stderr:
                lines.put(line)
        lines.put(None)

    threading.Thread(target=forward, daemon=True).start()
    return child, lines


def _wait_for_serving(lines: queue.Queue) -> tuple[str, str]:
    """The Meshcat URL and the line saying how the wait ends, once both are printed."""
    seen = []
    while not (seen and seen[-1].startswith("meshcat: serving")):
        line = lines.get(timeout=120)
        assert line is not None, "".join(seen)
        seen.append(line)
    url = next(m[1] for line in seen if (m := re.match(r"^meshcat: (http://localhost:\d+)$", line)))
    return url, seen[-1]


def _one_json_answer(stdout: Path) -> dict:
    (answer,) = stdout.read_text().splitlines()  # exactly one line on stdout: the command's JSON object
    return json.loads(answer)


def test_meshcat_wait_serves_for_its_seconds_without_a_terminal_then_exits_0(tmp_path):
    # The page is fetched while the command waits: 10 s, far longer than a fetch takes on a loaded machine (with 2 s
    # a busy machine could fetch after the wait).
    child, lines = _served_plan(tmp_path / "answer.json", "--wait", "10")
    try:
        url, how = _wait_for_serving(lines)
        assert "10 s" in how
        with urllib.request.urlopen(url, timeout=10) as page:  # served while the command waits
            assert page.status == 200 and b"<html" in page.read().lower()
        assert child.wait(timeout=60) == 0
        assert _one_json_answer(tmp_path / "answer.json")["success"] is True
    finally:
        child.kill()
        child.wait()


def test_meshcat_without_a_terminal_serves_until_ctrl_c_which_exits_0(tmp_path):
    """No --wait and no terminal: the viewer stays up (it used to exit at once); Ctrl-C is the expected way to stop
    it, so it ends with exit code 0 and the one JSON answer already printed, not PREEMPTED."""
    child, lines = _served_plan(tmp_path / "answer.json")
    try:
        url, how = _wait_for_serving(lines)
        assert "Ctrl-C" in how
        time.sleep(3)
        assert child.poll() is None
        with urllib.request.urlopen(url, timeout=10) as page:
            assert page.status == 200
        child.send_signal(signal.SIGINT)
        assert child.wait(timeout=60) == 0
        assert _one_json_answer(tmp_path / "answer.json")["success"] is True
        rest = []
        while (line := lines.get(timeout=10)) is not None:
            rest.append(line)
        assert not rest, rest  # no traceback, no error line
    finally:
        child.kill()
        child.wait()


@pytest.mark.parametrize("flags", [["--wait", "2"], ["--meshcat", "--wait", "-1"], ["--meshcat", "--wait", "x"]])
def test_bad_wait_is_exit_2_before_planning(cli, one_line_error, flags):
    line = one_line_error(cli("plan", "bar-3link", *flags), 2)
    assert "--wait" in line


@pytest.mark.parametrize("command", [["plan", "bar", "--seed", "0"], ["run", "welding"]])
def test_out_files_of_plan_and_run_are_what_view_reads(tmp_path, meshcat_allowed, cli, command):
    """One trajectory format: the file `plan --out` / `run --out` writes opens in `view --trajectory`, with the
    same motion and samples."""
    from app.motion.trajectory import TrajectoryFile

    out, page = tmp_path / "motion.json", tmp_path / "motion.html"
    assert cli(*command, "--out", out).returncode == 0
    scene = command[1]
    assert cli("view", scene, "--trajectory", out, "--html", page).returncode == 0
    assert page.stat().st_size > 100_000
    written = TrajectoryFile.read(out, {"bar": 9, "welding": 6}[scene])
    assert written.scene == scene and written.trajectory.duration > 0
    assert np.allclose(written.trajectory.positions[0], written.trajectory.waypoints[0])


def _camera(html: str) -> tuple[np.ndarray, np.ndarray]:
    """The page's last camera position and target, in world coordinates (Meshcat's are three.js' y-up: x, z, -y)."""
    cmds = commands(html)
    position = [c["value"] for c in cmds if c["type"] == "set_property" and c["property"] == "position"
                and c["path"] == "/Cameras/default/rotated/<object>"][-1]  # fmt: skip
    target = [c["value"] for c in cmds if c["type"] == "set_target"][-1]
    world = lambda v: np.array([v[0], -v[2], v[1]])  # noqa: E731
    return world(position), world(target)


@pytest.mark.usefixtures("meshcat_allowed")
@pytest.mark.parametrize("scene", ["maze", "tunnel"])
def test_a_small_robots_whole_motion_is_in_the_cameras_view(oracles, scene):
    """The quadrotor is small in its scene: every place it flies through on its way from start to goal lies within
    the camera's field of view (a view over its shoulder at the start lost it)."""
    from app.viewer import CAMERA_FOV, ViewData, show

    oracle = oracles(scene)
    Q = oracle.space.interpolate(oracle.scene.start, oracle.scene.goal, resolution=0.5)
    viewer = show(oracle.scene, ViewData(times=np.linspace(0, 10, len(Q)), positions=Q))
    position, target = _camera(viewer.html())
    rays = viewer.frame_positions(Q) - position
    axis = (target - position) / np.linalg.norm(target - position)
    angles = np.degrees(np.arccos(rays @ axis / np.linalg.norm(rays, axis=1)))
    assert angles.max() < CAMERA_FOV / 2
