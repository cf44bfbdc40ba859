"""The front door: the README stays short and its Python example is examples/own_robot.py, which runs; the docs'
table of scene-file keys names every key CustomSpec has. (`make test` also builds the site with --strict.)"""

import dataclasses
import os
import re
import subprocess
import sys

from app.scene.custom import CustomSpec
from app.scene.model import ROOT

README = ROOT / "README.md"
EXAMPLE = ROOT / "examples" / "own_robot.py"


def test_readme_is_short():
    assert len(README.read_text().splitlines()) <= 150


def test_readme_python_example_is_examples_own_robot():
    code = re.search(r"```python\n(.*?)```", README.read_text(), re.S).group(1)
    assert EXAMPLE.read_text().split('"""\n\n', 1)[1] == code


def test_own_robot_example_plans_the_shipped_planar_arm_and_writes_its_trajectory(tmp_path):
    for folder in ("robots", "scenes"):  # the example's paths are relative to the repository's root
        (tmp_path / folder).symlink_to(ROOT / folder)
    env = {**os.environ, "PYTHONPATH": str(ROOT), "NPP_CACHE_DIR": str(tmp_path / "cache")}
    result = subprocess.run(
        [sys.executable, str(EXAMPLE)], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300
    )
    assert result.returncode == 0, result.stderr
    assert re.search(r"^\d+ waypoints, \d+\.\d s of motion$", result.stdout, re.M), result.stdout
    from app.motion.trajectory import TrajectoryFile

    written = TrajectoryFile.read(tmp_path / "motion.json", 5)
    assert written.trajectory.joint_names == ["base_x", "base_y", "joint1", "joint2", "joint3"]
    assert written.trajectory.certified


def test_the_scene_file_keys_are_all_documented():
    page = (ROOT / "docs" / "own-robot.md").read_text()
    for field in dataclasses.fields(CustomSpec):
        assert f"`{field.name}`" in page, field.name
