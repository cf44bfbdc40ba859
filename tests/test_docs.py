"""The front door: the README stays short and its Python example is examples/own_robot.py, which runs; the docs'
table of scene-file keys names every key CustomSpec has. (`make test` also builds the site with --strict.)"""

import dataclasses
import os
import re
import shutil
import subprocess
import sys

import pytest

from app.scene.files import ROOT
from app.scene.spec import CustomSpec

README = ROOT / "README.md"
EXAMPLE = ROOT / "examples" / "own_robot.py"


def test_readme_is_short():
    assert len(README.read_text().splitlines()) <= 150


def test_readme_python_example_is_examples_own_robot():
    code = re.search(r"```python\n(.*?)```", README.read_text(), re.S).group(1)
    assert EXAMPLE.read_text().split('"""\n\n', 1)[1] == code


def test_own_robot_page_includes_the_example_from_its_first_line_of_code():
    """docs/own-robot.md includes examples/own_robot.py from a line number: the one after the docstring."""
    start = int(re.search(r'--8<-- "examples/own_robot.py:(\d+):"', (ROOT / "docs" / "own-robot.md").read_text())[1])
    lines = EXAMPLE.read_text().splitlines(keepends=True)
    assert "".join(lines[start - 1 :]) == EXAMPLE.read_text().split('"""\n\n', 1)[1]


def test_own_robot_example_plans_the_shipped_planar_arm_and_writes_its_trajectory(tmp_path):
    for folder in ("robots", "scenes"):  # the example's paths are relative to the repository's root
        (tmp_path / folder).symlink_to(ROOT / folder)
    env = {**os.environ, "PYTHONPATH": str(ROOT), "NPP_CACHE_DIR": str(tmp_path / "cache")}
    result = subprocess.run(
        [sys.executable, str(EXAMPLE)], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300
    )
    assert result.returncode == 0, result.stderr
    # it writes under out/ (ignored by git, made if missing), nothing else in the folder it is run from
    assert sorted(path.name for path in tmp_path.iterdir()) == ["cache", "out", "robots", "scenes"]
    assert re.search(r"^\d+ waypoints, \d+\.\d s of motion$", result.stdout, re.M), result.stdout
    from app.motion.trajectory import TrajectoryFile

    written = TrajectoryFile.read(tmp_path / "out" / "motion.json", 5)
    assert written.trajectory.joint_names == ["base_x", "base_y", "joint1", "joint2", "joint3"]
    assert written.trajectory.certified


def test_the_scene_file_keys_are_all_documented():
    page = (ROOT / "docs" / "own-robot.md").read_text()
    for field in dataclasses.fields(CustomSpec):
        assert f"`{field.name}`" in page, field.name


def _make_dry_run(target: str) -> str:
    """What `make TARGET` would run (make -n: printed, not run)."""
    if shutil.which("make") is None:
        pytest.skip("make is not installed")
    result = subprocess.run(["make", "-n", "-C", str(ROOT), target], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    return result.stdout


def test_make_test_installs_nothing_outside_the_project_and_browser_test_says_it_does():
    assert "apt-get" not in _make_dry_run("test")
    browser = _make_dry_run("browser-test")
    assert "apt-get install" in browser and "installing Debian's chromium" in browser


def test_make_plan_and_the_readme_say_how_to_run_the_command_line():
    """After `make plan` the package is in .venv only: both say so (a plain `python -m app` cannot import it)."""
    assert "source .venv/bin/activate" in _make_dry_run("plan")
    set_up = README.read_text().split("## Set up", 1)[1].split("\n## ", 1)[0]
    assert "source .venv/bin/activate" in set_up and ".venv/bin/python -m app" in set_up
