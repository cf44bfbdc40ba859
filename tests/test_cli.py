"""The command line: listing, drawing, one-line errors with the agreed exit codes, the argument types, and the
entry point itself (start-up without Drake, the exit code of the process)."""

import argparse
import json
import re
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

from app import errors
from app.checking.budget import SAFETY_NET_SECONDS, Budget
from app.cli import EXIT_CODES, build_parser, exit_code
from app.commands.common import comma_list, names_from, parse_budget, parse_build_budget, sampler_names
from app.errors import UserError
from app.planning.settings import DEFAULT_BUDGET, PlanSettings
from app.scene.files import ROOT, SCENES_DIR
from app.scene.model import Scene


def test_scenes_json_lists_every_scene_with_its_facts(cli):
    result = cli("scenes", "--json")
    assert result.returncode == 0, result.stderr
    scenes = {s["name"]: s for s in json.loads(result.stdout)["scenes"]}
    assert {"bar", "bar-3link", "bar-5link", "joint", "joint3d", "teeth3d"} <= set(scenes)
    assert scenes["bar"]["dof"] == 9 and scenes["bar-3link"]["dof"] == 5 and scenes["teeth3d"]["dof"] == 6
    assert len(scenes["bar"]["start"]) == 9


def test_show_writes_a_png_and_says_so_on_stderr(tmp_path, cli):
    target = tmp_path / "bar.png"
    result = cli("show", "bar", "--png", target, "--json")
    assert result.returncode == 0, result.stderr
    assert target.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert result.stderr.splitlines() == [f"wrote {target}"] and str(target) in json.loads(result.stdout)["png"]


@pytest.mark.parametrize("json_flag", [["--json"], []])
def test_a_closed_pipe_ends_quietly(json_flag):
    """`python -m app scenes --json | head -1`: the reader goes away before the answer is written."""
    import subprocess
    import sys

    child = subprocess.Popen(
        [sys.executable, "-m", "app", "scenes", *json_flag], stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )
    child.stdout.close()  # before the child has imported anything: its every write to stdout meets a closed pipe
    stderr = child.stderr.read().decode()
    assert child.wait(timeout=120) in (0, 141) and stderr == ""


def test_unknown_scene_is_one_line_exit_2(tmp_path, cli, one_line_error):
    target = tmp_path / "x.png"
    result = cli("show", "no-such-scene", "--png", target)
    one_line_error(result, 2)
    assert "no-such-scene" in result.stderr
    assert not target.exists()


def test_the_entry_point_exits_with_the_commands_code(run_app, one_line_error):
    one_line_error(run_app("fly"), 2)
    assert run_app("scenes").returncode == 0


def test_show_into_a_missing_folder_writes_nothing(tmp_path, cli, one_line_error):
    result = cli("show", "bar", "--png", tmp_path / "missing" / "x.png")
    one_line_error(result, 2)
    assert list(tmp_path.iterdir()) == []


def write_scene(tmp_path: Path, text: str) -> Path:
    """A problem file next to copies of bar's directives, so relative paths resolve."""
    (tmp_path / "bar.dmd.yaml").write_text((SCENES_DIR / "bar.dmd.yaml").read_text())
    path = tmp_path / "custom.yaml"
    path.write_text(text)
    return path


BAR = (SCENES_DIR / "bar.yaml").read_text()


@pytest.mark.parametrize(
    "text, expected",
    [
        (BAR + "colour: red\n", "colour"),  # unknown key
        (re.sub(r"(?m)^start: .*$", "start: [10, 50, 0]", BAR), "'start' needs 9"),
        (BAR.replace("resolution: 0.5", "resolution: [0.5"), "bad scene file"),  # malformed YAML
        (BAR.replace("resolution: 0.5", "resolution: fast"), "bad scene file"),  # wrong type
        (BAR.replace("collisions: environment", "collisions: some"), "collisions must be"),
        (BAR.replace("frame: base", "frame: nose"), "passage frame 'nose'"),
        (BAR.replace("robot: [arm]", "robot: [rover]"), "no model instance named 'rover'"),
    ],
)
def test_bad_scene_files_are_rejected_with_a_reason(tmp_path, cli, one_line_error, text, expected):
    path = write_scene(tmp_path, text)
    with pytest.raises(UserError, match=expected):
        Scene(str(path))
    result = cli("show", path, "--png", tmp_path / "x.png")
    one_line_error(result, 2)
    assert not (tmp_path / "x.png").exists()


def test_a_good_custom_scene_file_loads(tmp_path):
    scene = Scene(str(write_scene(tmp_path, BAR)))
    assert scene.dim == 9 and scene.name == "custom"


def test_wrong_length_or_non_finite_configuration_is_a_user_error(oracles):
    oracle = oracles("bar")
    with pytest.raises(UserError, match="has 3 values"):
        oracle.space.check_configuration([1, 2, 3], "start")
    with pytest.raises(UserError, match="finite"):
        oracle.space.check_configuration([np.nan] * 9, "goal")
    assert oracle.space.check_configuration(list(range(9))).shape == (9,)


# ---- exit codes and argument types ----------------------------------------------------------------------------------
def test_every_error_class_has_its_exit_code():
    """The one map covers every exception the core raises to a user (app.errors, its warnings apart: they are given,
    not raised; the samplers define none)."""
    import app.samplers
    import app.samplers.base
    import app.samplers.bridge
    import app.samplers.levy
    import app.samplers.uniform
    import app.samplers.walk

    modules = [
        errors,
        app.samplers,
        app.samplers.base,
        app.samplers.bridge,
        app.samplers.levy,
        app.samplers.uniform,
        app.samplers.walk,
    ]
    classes = {
        obj
        for module in modules
        for obj in vars(module).values()
        if isinstance(obj, type) and issubclass(obj, BaseException) and not issubclass(obj, Warning)
    }
    assert classes and classes <= set(EXIT_CODES)
    assert {cls.__name__: code for cls, code in EXIT_CODES.items()} == {
        "NoPath": 1,
        "SamplerBudgetExceeded": 1,
        "UserError": 2,
        "InvalidEndpoint": 3,
        "KeyboardInterrupt": 130,
        "BrokenPipeError": 141,
    }
    assert not any(hasattr(cls, "exit_code") for cls in classes)  # the core does not know about exit codes
    assert exit_code(errors.NoPath("x")) == 1 and exit_code(errors.InvalidEndpoint("x")) == 3


def test_budget_syntax():
    assert parse_budget("30s") == Budget(seconds=30)
    assert parse_budget("2min") == Budget(seconds=120)
    assert parse_budget("30s,200kchecks") == Budget(seconds=30, checks=200000)
    for bad in ["", "30", "-5s", "0s", "nans", "30s,40s", "1e3checks", "10 parsecs", "s"]:
        with pytest.raises(argparse.ArgumentTypeError):
            parse_budget(bad)


def test_a_check_budget_keeps_the_time_safety_net_unless_told_to_leave_it_out():
    """A slow CAD-mesh arm ran 22 minutes without a word on --budget 300kchecks: a check limit alone keeps the
    default budget's seconds, and only `nolimit` beside it leaves them out. A build is bounded by its nodes instead."""
    net = DEFAULT_BUDGET.seconds
    assert net == SAFETY_NET_SECONDS and PlanSettings().budget.seconds == net
    assert parse_budget("200000checks") == Budget(seconds=net, checks=200000)
    assert parse_budget("200kchecks") == Budget(seconds=net, checks=200000)
    assert parse_budget("1.5Mchecks") == Budget(seconds=net, checks=1500000)
    assert parse_budget("300kchecks,nolimit") == parse_budget("nolimit, 300kchecks") == Budget(checks=300000)
    for bad in ["nolimit", "30s,nolimit", "nolimit,nolimit", "300kchecks,nolimit,30s"]:
        with pytest.raises(argparse.ArgumentTypeError, match="300kchecks,nolimit"):
            parse_budget(bad)
    assert parse_build_budget("3Mchecks") == Budget(checks=3_000_000)
    assert parse_build_budget("60s,3Mchecks") == Budget(seconds=60, checks=3_000_000)
    commands = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction)).choices
    for command in ("plan", "run"):
        assert "which 200kchecks,nolimit leaves out" in " ".join(commands[command].format_help().split())
    args = build_parser().parse_args(["plan", "bar", "--budget", "300kchecks"])
    assert args.budget == Budget(seconds=net, checks=300000)


def test_comma_lists_are_parsed_one_way():
    assert comma_list(" bar, joint3d,,") == ["bar", "joint3d"]
    assert sampler_names("lfbs, rbbs") == ["lfbs", "rbbs"]
    assert names_from(["welding", "window"], "job")("window") == ["window"]
    for parse, text, words in [
        (comma_list, " , ", "at least one"),
        (sampler_names, "lfbs,levy", "unknown sampler"),
        (names_from(["welding"], "job"), "parking", "unknown job 'parking'"),
    ]:
        with pytest.raises(argparse.ArgumentTypeError, match=words):
            parse(text)


@pytest.mark.parametrize(
    "args",
    [
        ["plan", "bar", "--sampler", "magic"],
        ["bench", "plan", "--samplers", "lfbs,magic"],
        ["bench", "sampling", "--steps", "2,-1"],
        ["bench", "paper", "--parts", "everything"],
        ["plan", "bar", "--budget", "forever"],
    ],
)
def test_bad_values_are_refused_by_the_parser(cli, one_line_error, args):
    line = one_line_error(cli(*args), 2)
    assert re.search(r"argument (--sampler|--samplers|--steps|--parts|--budget)", line), line


def test_help_does_not_load_drake():
    """The command line starts fast: building every command's parser imports neither Drake nor the heavy
    libraries (they load when a command needs them)."""
    code = (
        "import sys; from app.cli import build_parser; build_parser(); "
        "print(sorted(m for m in ('pydrake', 'ompl', 'matplotlib', 'scipy', 'networkx', 'distributed') "
        "if m in sys.modules))"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "[]"


@pytest.mark.parametrize(
    "args, code, error",
    [
        (["plan", "bar", "--start", "1,2,3"], 2, "INVALID_INPUT"),
        (["plan", "bar", "--sampler", "nope"], 2, "INVALID_INPUT"),
        (["plan", "bar", "--start", "50,30,0,0,0,0,0,0,0"], 3, "START_STATE_IN_COLLISION"),
        (["plan", "bar", "--goal", "500,50,0,0,0,0,0,0,0"], 3, "GOAL_STATE_INVALID"),
        (["plan", "joint3d", "--sampler", "uniform", "--narrow", "0", "--budget", "2000checks"], 1, "PLANNING_FAILED"),
        (
            ["plan", "joint3d", "--sampler", "uniform", "--narrow", "0", "--uniform", "10", "--full-roadmap"],
            1,
            "PLANNING_FAILED",
        ),
    ],
)
def test_json_answers_failures_with_one_object_and_a_stable_code(cli, args, code, error):
    result = cli(*args, "--json")
    assert result.returncode == code
    lines = result.stdout.strip().splitlines()
    assert len(lines) == 1
    answer = json.loads(lines[0])
    assert answer["success"] is False and answer["exit_code"] == code and answer["error"]["code"] == error
    assert answer["error"]["message"] and result.stderr.count("\n") == 1


def test_json_answers_success_with_one_object(cli):
    result = cli("scenes", "--json")
    assert result.returncode == 0 and json.loads(result.stdout)["success"] is True


PROGRESS_CHILD = """
import sys, time, types
import app.commands.common as common
common.PROGRESS_AFTER = 0.1
oracle = types.SimpleNamespace(answered=0)
with common.progress(types.SimpleNamespace(json={json}), oracle, "plan bar"):
    for _ in range(40):
        oracle.answered += 1000
        time.sleep(0.02)
print("after", file=sys.stderr)
"""


def _stderr_on_a_terminal(code: str) -> str:
    """What a child running `code` writes to stderr when stderr is a 100-column terminal (a pty)."""
    import fcntl
    import os
    import pty
    import struct
    import subprocess
    import sys
    import termios

    leader, follower = pty.openpty()
    fcntl.ioctl(follower, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))
    child = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                             stderr=follower)  # fmt: skip
    os.close(follower)
    out = b""
    while True:
        try:
            chunk = os.read(leader, 4096)
        except OSError:  # the child closed the terminal
            break
        if not chunk:
            break
        out += chunk
    assert child.wait(timeout=60) == 0
    return out.decode()


def test_progress_shows_on_a_terminal_then_clears():
    shown = _stderr_on_a_terminal(PROGRESS_CHILD.format(json=False))
    lines = shown.split("\r")
    assert any(line.startswith("plan bar: ") and "000 collision checks" in line for line in lines), shown
    assert shown.endswith("after\r\n") and lines[-3].strip() == ""  # the progress line was blanked before "after"


def test_no_progress_with_json():
    assert _stderr_on_a_terminal(PROGRESS_CHILD.format(json=True)) == "after\r\n"


def test_sample_takes_the_scenes_own_step(cli, tmp_path):
    from app.planning.settings import default_step
    from app.scene.model import Scene

    png = tmp_path / "window.png"
    result = cli("sample", "window", "--sampler", "lfbs", "-k", "5", "--json", "--png", png)
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)["step"] == default_step(Scene("window")) == Scene("window").step
    assert result.stderr.splitlines() == [f"wrote {png}"]


def test_an_output_onto_a_symbolic_link_replaces_the_link_and_says_so(tmp_path, cli):
    """`--out` onto a symbolic link writes a file in its place (atomically, as every output), leaves the file the
    link pointed to as it was, and the line naming the file written says so."""
    target, link = tmp_path / "target.png", tmp_path / "link.png"
    target.write_bytes(b"kept")
    link.symlink_to(target)
    out = cli("show", "bar", "--png", link)
    assert out.returncode == 0
    assert not link.is_symlink() and link.stat().st_size > 1000 and target.read_bytes() == b"kept"
    assert f"wrote {link} (it replaced a symbolic link to {target}, which is left as it was)" in out.stderr


class _Log:
    """A stderr that is no terminal (a log file), which says when something was written to it."""

    def __init__(self):
        self.text, self.written = "", threading.Event()

    def write(self, text: str) -> int:
        self.text += text
        self.written.set()
        return len(text)

    def flush(self) -> None:
        pass

    def isatty(self) -> bool:
        return False


@pytest.mark.parametrize("json_flag", [False, True])
def test_progress_in_a_log_is_a_plain_line_now_and_then(json_flag, monkeypatch):
    """Where stderr is no terminal a long command once said nothing until it ended: it writes a plain line every
    PROGRESS_LOG_EVERY s (here made tiny), each ending in a newline, no carriage return; none with --json."""
    import types

    from app.commands import common

    log = _Log()
    monkeypatch.setattr(sys, "stderr", log)
    monkeypatch.setattr(common, "PROGRESS_LOG_EVERY", 0.001)
    oracle = types.SimpleNamespace(answered=0)
    with common.progress(types.SimpleNamespace(json=json_flag), oracle, "plan bar"):
        oracle.answered = 12_000
        if not json_flag:
            assert log.written.wait(60)  # a line came (the wait only ends a test that would hang)
    if json_flag:
        assert log.text == ""
        return
    lines = log.text.split("\n")
    assert lines[-1] == "" and "\r" not in log.text
    assert all(re.fullmatch(r"plan bar: \d+ s, [\d,]+ collision checks", line) for line in lines[:-1]), log.text


def test_roadmap_build_in_a_log_says_how_far_it_is(cli, tmp_path, monkeypatch):
    """`roadmap build` into a log: plain lines of nodes and checks as its round goes (every PROGRESS_LOG_EVERY s:
    here every report), none with --json."""
    from app.commands import common
    from app.planning import cell

    monkeypatch.setattr(common, "PROGRESS_LOG_EVERY", 0.0)
    monkeypatch.setattr(cell, "PART_SECONDS", 0.0)  # a report every FIRST_PART edges
    monkeypatch.setattr(cell, "FIRST_PART", 8)
    result = cli("roadmap", "build", "bar", "--nodes", "40", "--out", tmp_path / "bar.npz")
    assert result.returncode == 0, result.stderr
    found = re.findall(r"^roadmap build: (\d+)/40 nodes, [\d,]+ collision checks, \d+ s$", result.stderr, re.M)
    nodes = [int(n) for n in found]
    assert len(nodes) > 2 and nodes == sorted(nodes) and nodes[0] < 40 and "\r" not in result.stderr
    quiet = cli("roadmap", "build", "bar", "--nodes", "40", "--out", tmp_path / "again.npz", "--json")
    assert quiet.returncode == 0 and "roadmap build:" not in quiet.stderr


def _subparser(*names: str) -> argparse.ArgumentParser:
    from app.cli import build_parser

    parser = build_parser()
    for name in names:
        action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
        parser = action.choices[name]
    return parser


def _option(parser: argparse.ArgumentParser, flag: str) -> argparse.Action:
    return next(a for a in parser._actions if flag in a.option_strings)


def test_the_sampler_flags_name_every_registered_sampler():
    from app.samplers import SAMPLERS

    for command in (("plan",), ("sample",), ("run",), ("roadmap", "build"), ("gui",)):
        help_text = _option(_subparser(*command), "--sampler").help
        assert all(name in help_text for name in SAMPLERS), (command, help_text)


def test_every_bench_scenes_flag_says_what_it_takes():
    bench = _subparser("bench")
    kinds = next(a for a in bench._actions if isinstance(a, argparse._SubParsersAction)).choices
    explained = []
    for kind, parser in kinds.items():
        if any("--scenes" in a.option_strings for a in parser._actions):
            help_text = _option(parser, "--scenes").help or ""
            assert "scene" in help_text and len(help_text) > 30, (kind, help_text)
            explained.append(kind)
    assert "ablation" in explained and "ompl" in explained


def test_show_sample_and_view_take_a_robot_of_ones_own(cli, one_line_error, tmp_path, monkeypatch):
    """As plan does: --robot/--env instead of a scene file written first, through the same flags."""
    monkeypatch.setenv("NPP_CACHE_DIR", str(tmp_path / "cache"))
    robot = ["--robot", ROOT / "robots" / "planar_arm_3.urdf", "--env", SCENES_DIR / "bar_obstacles.sdf"]
    result = cli("show", *robot, "--png", tmp_path / "own.png")
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "own.png").stat().st_size > 0
    result = cli("sample", *robot, "--sampler", "uniform", "-k", "3", "--json")
    assert result.returncode == 0, result.stderr
    assert len(json.loads(result.stdout)["samples"]) == 3
    trajectory = tmp_path / "motion.json"
    result = cli("plan", *robot, "--start", "20,80,0,0,0", "--goal", "25,80,0,0,0", "--out", trajectory)
    assert result.returncode == 0, result.stderr
    monkeypatch.setenv("DRAKE_ALLOW_NETWORK", "meshcat")  # the viewer needs Meshcat even to export a page
    result = cli("view", *robot, "--trajectory", trajectory, "--html", tmp_path / "motion.html", "--json")
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)["scene"] == "planar_arm_3-in-bar_obstacles"
    assert "--srdf needs --robot" in one_line_error(cli("show", "bar", "--png", tmp_path / "b.png", "--srdf", "x"), 2)
    assert "not both" in one_line_error(cli("view", "bar", *robot, "--trajectory", trajectory, "--html", "x.html"), 2)


def test_a_library_warning_is_one_line_on_stderr_each_time(cli, monkeypatch):
    """Library code warns (app.errors.PlannerWarning, Note) and never prints: the command line shows each warning as
    one line, "warning: ..." or "note: ...", every time one is given; other warnings keep Python's own form."""
    import warnings

    from app.commands import scenes
    from app.errors import Note, PlannerWarning

    def names():
        for _ in range(2):
            warnings.warn("arm.urdf: Drake ignored 2 elements\nit does not use", Note, stacklevel=1)
        warnings.warn("arm.stl became 900 convex pieces", PlannerWarning, stacklevel=1)
        return ["bar"]

    monkeypatch.setattr(scenes, "scene_names", names)
    result = cli("scenes")
    assert result.returncode == 0, result.stderr
    assert result.stderr.splitlines() == [
        "note: arm.urdf: Drake ignored 2 elements it does not use",
        "note: arm.urdf: Drake ignored 2 elements it does not use",
        "warning: arm.stl became 900 convex pieces",
    ]
    assert result.stdout.startswith("bar ")
    with pytest.warns(PlannerWarning) as given:  # a library user gets them as Python warnings
        names()
    assert [w.category for w in given] == [Note, Note, PlannerWarning]
