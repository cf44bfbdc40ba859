"""The public API: what `import app` offers, and the Python tour of docs/getting-started.md run exactly as printed."""

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

import app

ROOT = Path(__file__).resolve().parent.parent
GETTING_STARTED = ROOT / "docs" / "getting-started.md"


def test_all_names_exist_and_nothing_else_is_promised():
    assert len(set(app.__all__)) == len(app.__all__)
    for name in app.__all__:
        assert getattr(app, name) is not None
    assert {
        "plan",
        "PlanSettings",
        "CollisionOracle",
        "load_scene",
        "Trajectory",
        "Budget",
        "make_sampler",
        "SAMPLERS",
        "NoPath",
        "certify_path",
    } <= set(app.__all__)


def test_getting_started_python_example_runs_as_printed(tmp_path):
    section = GETTING_STARTED.read_text().split("## From Python", 1)[1]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    env = {**os.environ, "PYTHONPATH": str(ROOT)}  # this checkout's app, whichever one is installed
    result = subprocess.run(
        [sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300
    )
    assert result.returncode == 0, result.stderr
    lines = result.stdout.strip().splitlines()
    assert re.fullmatch(r"\d+ waypoints, \d+ collision checks, \d+\.\d s of motion", lines[0]), lines
    assert re.fullmatch(r"\d+% of 30 lfbs samples are in the passage", lines[1]), lines
    assert [path.name for path in tmp_path.iterdir()] == ["out"]  # its file goes under out/, made if missing
    written = app.TrajectoryFile.read(tmp_path / "out" / "bar-motion.json", 9)
    assert written.scene == "bar" and len(written.trajectory.joint_names) == 9


def test_every_public_dataclass_field_is_described_in_its_docstring():
    """The API reference (docs/api.md) shows a dataclass's fields as its docstring's Attributes table, not as empty
    headings of their own: every field of every public dataclass, and of PlanResult's parts, has a line there."""
    import dataclasses
    import inspect

    from app.planning.result import Certificate, PlanStats, Smoothing

    public = [getattr(app, name) for name in app.__all__]
    classes = [c for c in public if dataclasses.is_dataclass(c)] + [PlanStats, Smoothing, Certificate]
    assert {app.PlanSettings, app.BuildSettings, app.Budget, app.PlanResult, app.Trajectory} <= set(classes)
    for cls in classes:
        section = inspect.getdoc(cls).partition("\nAttributes:\n")[2]
        described = set(re.findall(r"^    (\w+): ", section, re.M))
        assert {f.name for f in dataclasses.fields(cls)} <= described, cls.__name__


def test_settings_are_validated_once_when_built():
    for bad in [
        dict(sampler="nope"),
        dict(narrow=-1),
        dict(k=0),
        dict(dt=0.0),
        dict(step=float("inf")),
        dict(seed=1.5),
        dict(budget="30s"),
    ]:
        with pytest.raises(app.UserError):
            app.PlanSettings(**bad)


def test_a_users_polyline_is_certified_free_or_refused_through_an_obstacle(checkers):
    """app.certify_path proves a user's own path: a short move beside the wall of `bar` is free all along; the
    straight line from start to goal, through the wall, is refused at that edge."""
    import numpy as np

    scene = app.load_scene("bar")
    beside = scene.start + np.eye(len(scene.start))[0] * 5.0  # 5 units along x, the wall still far
    ok, stats = app.certify_path(checkers("bar"), np.array([scene.start, beside]))
    assert ok and stats["failed"] == []
    ok, stats = app.certify_path(checkers("bar"), np.array([scene.start, beside, scene.goal]))
    assert not ok and stats["failed"] == [1]
    # A path of the wrong shape is one clear refusal, not an IndexError from inside the proof.
    for bad in (
        np.zeros((2, len(scene.start) + 1)),
        [[np.nan] * len(scene.start)] * 2,
        np.zeros((0, len(scene.start))),
    ):
        with pytest.raises(app.UserError, match="certify_path"):
            app.certify_path(checkers("bar"), bad)
