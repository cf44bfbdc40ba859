"""The command line: listing, drawing, and one-line errors with the agreed exit codes."""
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from app.errors import UserError
from app.scene import SCENES_DIR, Scene


def run_app(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "app", *args], capture_output=True, text=True, cwd=cwd,
                          env=os.environ.copy(), timeout=300)


def assert_one_line_error(result, code):
    assert result.returncode == code, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("error:")
    assert "Traceback" not in result.stderr


def test_scenes_json_lists_every_scene_with_its_facts():
    result = run_app("scenes", "--json")
    assert result.returncode == 0, result.stderr
    scenes = {s["name"]: s for s in json.loads(result.stdout)["scenes"]}
    assert {"bar", "bar-3link", "bar-5link", "joint", "joint3d", "teeth3d"} <= set(scenes)
    assert scenes["bar"]["dof"] == 9 and scenes["bar-3link"]["dof"] == 5 and scenes["teeth3d"]["dof"] == 6
    assert len(scenes["bar"]["start"]) == 9


def test_show_writes_a_png(tmp_path):
    target = tmp_path / "bar.png"
    result = run_app("show", "bar", "--png", str(target))
    assert result.returncode == 0, result.stderr
    assert target.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_unknown_scene_is_one_line_exit_2(tmp_path):
    target = tmp_path / "x.png"
    result = run_app("show", "no-such-scene", "--png", str(target))
    assert_one_line_error(result, 2)
    assert "no-such-scene" in result.stderr
    assert not target.exists()


def test_unknown_command_is_one_line_exit_2():
    assert_one_line_error(run_app("fly"), 2)


def test_show_into_a_missing_folder_writes_nothing(tmp_path):
    result = run_app("show", "bar", "--png", str(tmp_path / "missing" / "x.png"))
    assert_one_line_error(result, 2)
    assert list(tmp_path.iterdir()) == []


def write_scene(tmp_path: Path, text: str) -> Path:
    """A problem file next to copies of bar's directives, so relative paths resolve."""
    (tmp_path / "bar.dmd.yaml").write_text((SCENES_DIR / "bar.dmd.yaml").read_text())
    path = tmp_path / "custom.yaml"
    path.write_text(text)
    return path


BAR = (SCENES_DIR / "bar.yaml").read_text()


@pytest.mark.parametrize("text, expected", [
    (BAR + "colour: red\n", "colour"),  # unknown key
    (re.sub(r"(?m)^start: .*$", "start: [10, 50, 0]", BAR), "'start' needs 9"),
    (BAR.replace("resolution: 0.5", "resolution: [0.5"), "bad scene file"),  # malformed YAML
    (BAR.replace("resolution: 0.5", "resolution: fast"), "bad scene file"),  # wrong type
    (BAR.replace("collisions: environment", "collisions: some"), "collisions must be"),
    (BAR.replace("frame: base", "frame: nose"), "passage frame 'nose'"),
    (BAR.replace("robot: [arm]", "robot: [rover]"), "no model instance named 'rover'"),
])
def test_bad_scene_files_are_rejected_with_a_reason(tmp_path, text, expected):
    path = write_scene(tmp_path, text)
    with pytest.raises(UserError, match=expected):
        Scene(str(path))
    result = run_app("show", str(path), "--png", str(tmp_path / "x.png"))
    assert_one_line_error(result, 2)
    assert not (tmp_path / "x.png").exists()


def test_a_good_custom_scene_file_loads(tmp_path):
    scene = Scene(str(write_scene(tmp_path, BAR)))
    assert scene.dim == 9 and scene.name == "custom"


def test_wrong_length_or_non_finite_configuration_is_a_user_error(oracles):
    oracle = oracles("bar")
    with pytest.raises(UserError, match="has 3 values"):
        oracle.check_configuration([1, 2, 3], "start")
    with pytest.raises(UserError, match="finite"):
        oracle.check_configuration([np.nan] * 9, "goal")
    assert oracle.check_configuration(list(range(9))).shape == (9,)
