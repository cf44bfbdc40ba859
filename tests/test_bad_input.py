"""Bad input, table-driven, across every command: each row is the arguments, the exit code and a fragment of the
one line on stderr. Every row must fail with that code, say so in one line without a traceback, write nothing
anywhere, and with --json answer one object with success false and the same exit code.

Most rows fail before any scene is loaded (argument types, output paths); a few need the scene to find the fault.
The tests run as root in CI, where a write-protected folder stays writable, so paths that cannot be written are a
file used as a folder, a folder used as a file, and /proc or /sys.

Placeholders: {file} is an existing file, {dir} an existing folder, {out} an empty folder, {stl} a garbage mesh,
{nan_weights} a scene file with a NaN weight. The working directory is the test's folder, so a default output path
(bench --store out/...) written by mistake would be seen too.
"""

import json
import os
import re
from pathlib import Path

import pytest

from app.scene.model import SCENES_DIR

ROBOT = ["--robot", "{stl}", "--start", "0,0,0,0,0,0", "--goal", "1,0,0,0,0,0", "--bounds", "-1..1,-1..1,-1..1"]

ROWS = [
    # -- output paths, refused before any work ---------------------------------------------------------------------
    (["plan", "bar", "--out", "{file}/t.json"], 2, "is a file, not a folder"),
    (["plan", "bar", "--out", "{dir}"], 2, "it is a folder"),
    (["plan", "bar", "--out", "/proc/t.json"], 2, "/proc is a system folder"),
    (["plan", "bar", "--out", "{out}/missing/t.json"], 2, "does not exist"),
    (["plan", "bar", "--out", "{out}/t.json", "--html", "{file}/x.html"], 2, "is a file, not a folder"),
    (["plan", "bar", "--out", "{out}/t.json", "--html", "{out}/t.json"], 2, "are the same file"),
    (["plan", "bar", "--html", "{out}/bar.html"], 2, "Meshcat is disabled by DRAKE_ALLOW_NETWORK"),
    (["run", "window", "--out", "{dir}"], 2, "it is a folder"),
    (["run", "window", "--html", "/sys/x.html"], 2, "/sys is a system folder"),
    (["sample", "bar", "--sampler", "lfbs", "--png", "{file}/x.png"], 2, "is a file, not a folder"),
    (["sample", "bar", "--sampler", "lfbs", "--png", "/proc/x.png"], 2, "/proc is a system folder"),
    (["show", "bar", "--png", "{dir}"], 2, "it is a folder"),
    (["view", "bar", "--trajectory", "{file}", "--html", "{file}/x.html"], 2, "is a file, not a folder"),
    (["bench", "plan", "--store", "{dir}"], 2, "it is a folder"),
    (["bench", "plan", "--store", "{file}/x.sqlite"], 2, "is a file, not a folder"),
    (["bench", "uav", "--store", "/proc/u.sqlite"], 2, "/proc is a system folder"),
    (["bench", "uav", "--store", "{file}"], 2, "as a results store: it is not a SQLite file"),
    (["bench", "jobs", "--store", "{dir}"], 2, "it is a folder"),
    (["bench", "ompl", "--png", "{dir}"], 2, "it is a folder"),
    (["bench", "ompl", "--png", "{out}/o.png", "--store", "{out}/o.png"], 2, "are the same file"),
    (["bench", "sampling", "--png", "{file}/s.png"], 2, "is a file, not a folder"),
    (["bench", "paper", "--out", "{file}"], 2, "is a file, not a folder"),
    (["bench", "paper", "--out", "/proc/paper", "--report-only"], 2, "/proc is a system folder"),
    # -- counts: whole numbers within limits the message names -----------------------------------------------------
    (["run", "window", "--seed", "-1"], 2, "argument --seed: must be from 0 to 4294967295, got -1"),
    (["plan", "bar", "--seed", "99999999999"], 2, "argument --seed: must be from 0 to"),
    (["plan", "bar", "--narrow", "1e9"], 2, "argument --narrow: not a whole number"),
    (["plan", "bar", "--narrow", "1000000000"], 2, "argument --narrow: must be from 0 to 100000"),
    (["plan", "bar", "--uniform", "-5"], 2, "argument --uniform: must be from 0 to 100000"),
    (["plan", "bar", "-k", "1e9"], 2, "argument -k/--neighbours: not a whole number"),
    (["plan", "bar", "-k", "5000"], 2, "argument -k/--neighbours: must be from 1 to 1000"),
    (["plan", "bar", "--smooth", "100000"], 2, "argument --smooth: must be from 0 to 10000"),
    (["run", "window", "--narrow", "200000"], 2, "argument --narrow: must be from 0 to 100000"),
    (["sample", "bar", "--sampler", "lfbs", "-k", "0"], 2, "argument -k: must be from 1 to 100000"),
    (["sample", "bar", "--sampler", "lfbs", "--threads", "0"], 2, "argument --threads: must be from 1 to 256"),
    (["bench", "paper", "--workers", "-1"], 2, "argument --workers: must be from 0 to 256"),
    (["bench", "paper", "--trials", "0"], 2, "argument --trials: must be from 1 to 10000"),
    (["bench", "paper", "--max-checks", "0"], 2, "argument --max-checks: must be from 1 to"),
    (["bench", "plan", "--workers", "1000"], 2, "argument --workers: must be from 1 to 256"),
    (["bench", "plan", "--seeds", "0"], 2, "argument --seeds: must be from 1 to 10000"),
    (["bench", "plan", "-k", "0"], 2, "argument -k/--neighbours: must be from 1 to 1000"),
    (["bench", "uav", "--seeds", "1000000"], 2, "argument --seeds: must be from 1 to 10000"),
    (["bench", "jobs", "--seeds", "-2"], 2, "argument --seeds: must be from 1 to 10000"),
    (["bench", "ompl", "--workers", "0"], 2, "argument --workers: must be from 1 to 256"),
    (["bench", "oracle", "-n", "0"], 2, "argument -n: must be from 1 to"),
    (["bench", "oracle", "--repeats", "100000"], 2, "argument --repeats: must be from 1 to 10000"),
    (["bench", "oracle", "--seed", "-3"], 2, "argument --seed: must be from 0 to"),
    (["bench", "sampling", "--trials", "0"], 2, "argument --trials: must be from 1 to 10000"),
    # -- numbers that are not finite, or out of range --------------------------------------------------------------
    (["plan", "bar", "--resolution", "inf"], 2, "argument --resolution: must be a finite number, got inf"),
    (["plan", "bar", "--mesh-tolerance", "nan"], 2, "argument --mesh-tolerance: must be a finite number"),
    (["plan", "bar", "--mesh-tolerance", "-1"], 2, "argument --mesh-tolerance: must not be negative"),
    (["plan", "bar", "--step", "nan"], 2, "argument --step: must be a finite number"),
    (["plan", "bar", "--step", "-1"], 2, "argument --step: must be a positive finite number"),
    (["plan", "bar", "--dt", "0"], 2, "argument --dt: must be a positive finite number"),
    (["plan", "bar", "--budget", "inf"], 2, "argument --budget: bad budget 'inf'"),
    (["plan", "bar", "--budget", "0s"], 2, "argument --budget: bad budget '0s': must be positive"),
    (["plan", "bar", "--budget", "30s,1min"], 2, "two time limits"),
    (["plan", "bar", "--start", "nan,80,0,0,0,0,0,0,0"], 2, "argument --start: needs finite numbers"),
    (["plan", "bar", "--goal", "1,2,x"], 2, "argument --goal: not a comma-separated list of numbers"),
    (["plan", "bar", "--env-pose", "0,0,0,0,0,inf"], 2, "argument --env-pose: needs finite numbers"),
    (["run", "window", "--budget", "-1s"], 2, "argument --budget: bad budget '-1s'"),
    (["sample", "bar", "--sampler", "lfbs", "--step", "inf"], 2, "argument --step: must be a finite number"),
    (["bench", "sampling", "--steps", "2,inf"], 2, "argument --steps: needs finite numbers"),
    (["bench", "sampling", "--margin", "nan"], 2, "argument --margin: must be a finite number"),
    (["bench", "jobs", "--budget", "nan"], 2, "argument --budget: must be a finite number"),
    (["bench", "ompl", "--budget", "0"], 2, "argument --budget: must be a positive finite number"),
    (["bench", "paper", "--steps", "0,10"], 2, "argument --steps: must be positive numbers"),
    # -- negative values typed as a user would, checked against the scene -------------------------------------------
    (["plan", "bar", "--start", "-1.57,0,0"], 2, "start has 3 values; the robot needs 9"),
    (["plan", "bar", "--goal", "-20,-80,0,0,0,0,0,0,0"], 3, "goal is out of bounds"),
    (["plan", "bar", "--start", "50,30,0,0,0,0,0,0,0"], 3, "start is in collision"),
    # -- names, files and combinations -----------------------------------------------------------------------------
    (["plan", "bar", "--sampler", "magic"], 2, "argument --sampler: unknown sampler 'magic'"),
    (["plan", "nowhere"], 2, "nowhere"),
    (["plan"], 2, "a SCENE (name or file) or --robot is required"),
    (["plan", "bar", *ROBOT], 2, "give either SCENE or --robot/--env, not both"),
    (["plan", "--env", "{stl}"], 2, "--env needs --robot"),
    (["plan", "bar", "--resolution", "0.5"], 2, "--resolution needs --robot"),
    (["plan", "bar", "--no-self-collision", "--mesh-method", "faces"], 2, "--mesh-method, --no-self-collision need"),
    (["plan", "window", "--srdf", "{file}"], 2, "--srdf needs --robot"),
    (["plan", "window", "--goal", "0,0,0,0,0,0,0,0", "--goal-pose", "0.3,0,0.3,0,90,0"], 2, "not both"),
    (["plan", "window", "--tool", "tcp"], 2, "--tool needs --start-pose or --goal-pose"),
    (["plan", "window", "--goal-pose", "0.3,0,0.3"], 2, "--goal-pose"),
    (["plan", "window", "--goal-pose", "5,0,0.3,0,90,0"], 3, "cannot be reached"),
    (["plan", "bar", "--wait", "2"], 2, "--wait needs --meshcat"),
    (["plan", "bar", "--meshcat", "--wait", "-1"], 2, "argument --wait"),
    (["bench", "certify", "--seeds", "0"], 2, "argument --seeds: must be from 1 to 10000"),
    (["bench", "certify", "--scenes", "nowhere"], 2, "argument --scenes"),
    (["bench", "audit", "--problems", "0"], 2, "argument --problems: must be from 1 to 10000"),
    (["bench", "audit", "--store", "{dir}"], 2, "it is a folder"),
    (["bench", "audit", "--workers", "1000"], 2, "argument --workers: must be from 1 to 256"),
    (["plan", *ROBOT], 2, "cannot read mesh garbage.stl: not a valid .stl file"),
    (["plan", "--robot", "{out}/none.urdf", "--start", "0", "--goal", "1"], 2, "robot file not found"),
    (["plan", "{nan_weights}"], 2, "'weights' needs finite numbers, item 2 is nan"),
    (["plan", "bar", "--mesh-method", "magic"], 2, "argument --mesh-method: invalid choice"),
    (["run", "painting"], 2, "unknown job 'painting'"),
    (["view", "bar", "--trajectory", "{file}"], 2, "nothing to do"),
    (["view", "bar", "--trajectory", "{out}/none.json", "--html", "{out}/x.html"], 2, "trajectory file not found"),
    (["sample", "bar"], 2, "the following arguments are required: --sampler"),
    (["show", "bar"], 2, "the following arguments are required: --png"),
    (["scenes", "extra"], 2, "unrecognized arguments: extra"),
    (["bench"], 2, "the following arguments are required: kind"),
    (["bench", "plan", "--samplers", "lfbs,magic"], 2, "argument --samplers: unknown sampler 'magic'"),
    (["bench", "jobs", "--jobs", "painting"], 2, "argument --jobs: unknown job 'painting'"),
    (["bench", "paper", "--parts", "everything"], 2, "argument --parts: unknown part 'everything'"),
    (["bench", "ompl", "--methods", "ompl:Magic"], 2, "argument --methods"),
    (["fly"], 2, "invalid choice: 'fly'"),
]


@pytest.fixture
def place(tmp_path, monkeypatch):
    """A folder with the placeholders' files, made the working directory; returns the placeholder values."""
    (tmp_path / "file").write_text("x")
    (tmp_path / "dir").mkdir()
    (tmp_path / "out").mkdir()
    (tmp_path / "garbage.stl").write_bytes(bytes(range(256)) * 2)
    (tmp_path / "bar.dmd.yaml").write_text((SCENES_DIR / "bar.dmd.yaml").read_text())
    bar = (SCENES_DIR / "bar.yaml").read_text()
    nan_weights = re.sub(r"(?m)^weights: \[1, 1,", "weights: [1, .nan,", bar)
    assert nan_weights != bar
    (tmp_path / "nan_weights.yaml").write_text(nan_weights)
    monkeypatch.chdir(tmp_path)
    return {
        "file": tmp_path / "file",
        "dir": tmp_path / "dir",
        "out": tmp_path / "out",
        "stl": tmp_path / "garbage.stl",
        "nan_weights": tmp_path / "nan_weights.yaml",
    }


def _files(folder: Path) -> set:
    return {(p, p.stat().st_size) for p in folder.rglob("*")}


@pytest.mark.parametrize("argv, exit_code, fragment", ROWS, ids=[" ".join(argv)[:60] for argv, _, _ in ROWS])
def test_bad_input_fails_in_one_line_and_writes_nothing(cli, place, tmp_path, argv, exit_code, fragment):
    argv = [a.format(**place) for a in argv]
    before = _files(tmp_path)
    result = cli(*argv)
    assert result.returncode == exit_code, result.stderr
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].strip(), result.stderr
    assert "Traceback" not in result.stderr
    assert fragment in lines[0]
    assert result.stdout == ""

    answer = cli(*argv, "--json")
    assert answer.returncode == exit_code
    [line] = answer.stdout.splitlines()
    obj = json.loads(line)
    assert obj["success"] is False and obj["exit_code"] == exit_code
    assert obj["error"]["code"] == "INVALID_INPUT" if exit_code == 2 else obj["error"]["code"] != "INVALID_INPUT"
    assert answer.stderr == f"error: {obj['error']['message']}\n" and fragment in obj["error"]["message"]
    assert _files(tmp_path) == before  # nothing written, nothing left behind


def test_the_table_covers_every_command():
    commands = {" ".join(argv[:2]) if argv[0] == "bench" else argv[0] for argv, _, _ in ROWS}
    assert {"plan", "run", "view", "sample", "show", "scenes"} <= commands
    kinds = ("oracle", "sampling", "plan", "uav", "jobs", "ompl", "paper", "certify", "audit")
    assert {f"bench {kind}" for kind in kinds} <= commands
    assert len(ROWS) >= 60


def test_negative_values_follow_their_flag_as_typed():
    """argparse alone reads "-1.57,0" as an unknown flag ("expected one argument"); the command line glues it to
    the flag before it."""
    from app.cli import build_parser, join_negative_values

    argv = ["plan", "bar", "--start", "-1.57,0,0", "--bounds", "-1..1,-2..2", "--env-pose", "-1,0,0,0,0,-90"]
    args = build_parser().parse_args(join_negative_values(argv))
    assert args.start == [-1.57, 0, 0] and args.bounds == "-1..1,-2..2" and args.env_pose == [[-1, 0, 0, 0, 0, -90]]
    assert join_negative_values(["--json", "--", "-1"]) == ["--json", "--", "-1"]


def test_drake_refusing_to_start_offline_is_one_line_that_says_what_to_change(run_app, tmp_path):
    """Drake 1.51 wants its drake_models package in the download cache before it parses anything; with networking
    off and an empty cache it refuses to start."""
    env = {**os.environ, "DRAKE_ALLOW_NETWORK": "none", "XDG_CACHE_HOME": str(tmp_path)}
    result = run_app("plan", "bar-3link", env=env)
    assert result.returncode == 2 and "Traceback" not in result.stderr
    [line] = result.stderr.splitlines()
    assert "Drake cannot start its model parser" in line and "add package_map to it" in line
