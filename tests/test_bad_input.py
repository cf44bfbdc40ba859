"""Bad input, table-driven, across every command (the table: app.bench.bad_input.ROWS, which `bench audit` also
runs): each row is the arguments, the exit code and a fragment of the one line on stderr. Every row must fail with
that code, say so in one line without a traceback, write nothing anywhere, and with --json answer one object with
success false and the same exit code.

Most rows fail before any scene is loaded (argument types, output paths); a few need the scene to find the fault.
The working directory is the test's folder, so a default output path (bench --store out/...) written by mistake
would be seen too.
"""

import json
import os
import re

import pytest

from app.bench.bad_input import NO_INTERNAL_FILE, ROWS, arguments, files, prepare, run_case


@pytest.fixture
def place(tmp_path, monkeypatch):
    """A folder with the placeholders' files (app.bench.bad_input.prepare), made the working directory; returns the
    placeholder values."""
    monkeypatch.chdir(tmp_path)
    return prepare(tmp_path)


@pytest.mark.parametrize("argv, exit_code, fragment", ROWS, ids=[" ".join(argv)[:60] for argv, _, _ in ROWS])
def test_bad_input_fails_in_one_line_and_writes_nothing(cli, place, tmp_path, argv, exit_code, fragment):
    argv = arguments(argv, place)
    before = files(tmp_path)
    result = cli(*argv)
    assert result.returncode == exit_code, result.stderr
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].strip(), result.stderr
    assert "Traceback" not in result.stderr
    assert fragment in lines[0]
    assert not re.search(NO_INTERNAL_FILE, lines[0])  # the user's files are named, never the cache's
    assert result.stdout == ""

    answer = cli(*argv, "--json")
    assert answer.returncode == exit_code
    [line] = answer.stdout.splitlines()
    obj = json.loads(line)
    assert obj["success"] is False and obj["exit_code"] == exit_code
    assert obj["error"]["code"] == "INVALID_INPUT" if exit_code == 2 else obj["error"]["code"] != "INVALID_INPUT"
    assert answer.stderr == f"error: {obj['error']['message']}\n" and fragment in obj["error"]["message"]
    assert files(tmp_path) == before  # nothing written, nothing left behind


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


def test_an_audited_case_reports_its_exit_code_first_line_and_what_it_wrote():
    """run_case (what `bench audit` runs per row) sees a refusal as such, and sees the files a command does write."""
    refused = run_case(["plan", "bar", "--out", "{long}"])
    assert refused["exit_code"] == 2 and "File name too long" in refused["first_line"]
    assert refused["stderr_lines"] == 1 and not refused["traceback"] and refused["written"] == []
    drawn = run_case(["show", "bar", "--png", "{out}/bar.png"])
    assert drawn["exit_code"] == 0 and drawn["written"] == ["out/bar.png"]
