"""An interrupt and a command's answer (app.commands.common.answering): once a command writes its answer (its files
and what it prints), SIGINT and SIGTERM wait until it is written whole and the command ends as it would have; before
that, Ctrl-C stops it with exit code 130 and writes nothing. With --json, every path prints exactly one JSON object.

The interrupts are sent by the process to itself from inside the code under test (a writer wrapped to send one), so
where they land does not depend on timing."""

import io
import json
import os
import signal
import subprocess
import sys
import textwrap

import pytest

from app.commands.common import INTERRUPTED_WHILE_ANSWERING, print_json
from app.motion.trajectory import TrajectoryFile
from app.planning.cell import CellRoadmap


@pytest.fixture(scope="module")
def roadmap(tmp_path_factory):
    """A small cell roadmap of bar-3link, built once; each test plans on a copy of it."""
    from app.cli import main

    path = tmp_path_factory.mktemp("cell") / "bar-3link.npz"
    assert main(["roadmap", "build", "bar-3link", "--nodes", "60", "--out", str(path)]) == 0
    return path.read_bytes()


@pytest.fixture
def cell(tmp_path, roadmap):
    path = tmp_path / "cell.npz"
    path.write_bytes(roadmap)
    return path


def _plan_update(cell, out):
    return ["plan", "bar-3link", "--roadmap", cell, "--update", "--out", out, "--json"]


def _one_json(stdout: str) -> dict:
    """stdout holds exactly one line, one JSON object."""
    lines = stdout.splitlines()
    assert len(lines) == 1, stdout
    return json.loads(lines[0])


def _queries_answered(cli, cell) -> int:
    return json.loads(cli("roadmap", "info", cell, "--json").stdout)["provenance"]["queries"]


def _interrupting(original, signum=signal.SIGINT):
    """`original`, which sends this process `signum` once it has done its work."""

    def call(*args, **kwargs):
        result = original(*args, **kwargs)
        os.kill(os.getpid(), signum)
        return result

    return call


def test_ctrl_c_while_the_files_are_written_finishes_them_and_the_answer(cli, cell, tmp_path, monkeypatch):
    """plan --update --json: Ctrl-C after the trajectory is written, before the roadmap is: both files are written,
    the one JSON answer is whole, exit code 0."""
    out = tmp_path / "motion.json"
    before = _queries_answered(cli, cell)  # (the build's cover made some)
    monkeypatch.setattr(TrajectoryFile, "write", _interrupting(TrajectoryFile.write))
    result = cli(*_plan_update(cell, out))
    assert result.returncode == 0, result.stderr
    answer = _one_json(result.stdout)
    assert answer["success"] is True and answer["path"]
    assert INTERRUPTED_WHILE_ANSWERING in result.stderr.splitlines()
    assert json.loads(out.read_text())["positions"]
    monkeypatch.undo()
    assert _queries_answered(cli, cell) == before + 1  # the roadmap was written back


class _Pipe(io.RawIOBase):
    """The write end of a pipe whose reader is slow: each write takes at most 4 kB, and the first is cut short by a
    Ctrl-C (write(2) then returns what it wrote so far)."""

    def __init__(self):
        self.written, self.writes = bytearray(), 0

    def writable(self):
        return True

    def write(self, data):
        self.writes += 1
        if self.writes == 1:
            os.kill(os.getpid(), signal.SIGINT)
        taken = bytes(data[:4096])
        self.written += taken
        return len(taken)


def test_ctrl_c_while_the_answer_is_printed_finishes_it(cli, monkeypatch):
    """A Ctrl-C that cuts the write of the JSON line short: the line is written whole all the same. stdout is
    unbuffered here (as with PYTHONUNBUFFERED or python -u: a TextIOWrapper straight on the file), where a write cut
    short used to lose the rest of the line."""
    pipe = _Pipe()
    monkeypatch.setattr(sys, "stdout", io.TextIOWrapper(pipe, encoding="utf-8", write_through=True))
    result = cli("scenes", "--json")
    assert result.returncode == 0, result.stderr
    assert result.stderr.count(INTERRUPTED_WHILE_ANSWERING) == 1
    assert pipe.writes > 1 and _one_json(pipe.written.decode())["success"] is True


def test_ctrl_c_before_the_answer_stops_the_command_and_writes_nothing(cli, cell, tmp_path, monkeypatch):
    out = tmp_path / "motion.json"
    before = cell.read_bytes()
    monkeypatch.setattr(CellRoadmap, "solve", _interrupting(CellRoadmap.solve))
    result = cli(*_plan_update(cell, out))
    assert result.returncode == 130
    answer = _one_json(result.stdout)
    assert answer["success"] is False and answer["error"]["code"] == "PREEMPTED" and answer["exit_code"] == 130
    assert result.stderr.splitlines() == ["error: interrupted"]
    assert not out.exists() and cell.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cell.npz"]  # no temporary file left either


def test_sigterm_while_the_files_are_written_finishes_them(cell, tmp_path):
    """SIGTERM (`docker stop`, `kill`) waits as Ctrl-C does; in a child process, since by default it ends the
    process that gets it."""
    out = tmp_path / "motion.json"
    child = textwrap.dedent(f"""
        import signal, sys
        from app.cli import main
        from app.motion.trajectory import TrajectoryFile
        from test_answering import _interrupting
        TrajectoryFile.write = _interrupting(TrajectoryFile.write, signal.SIGTERM)
        sys.exit(main({[str(a) for a in _plan_update(cell, out)]!r}))
    """)
    paths = [os.path.dirname(__file__), os.environ.get("PYTHONPATH")]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, paths))}
    result = subprocess.run([sys.executable, "-c", child], capture_output=True, text=True, env=env, timeout=300)
    assert result.returncode == 0, result.stderr
    assert _one_json(result.stdout)["success"] is True and out.is_file()
    assert INTERRUPTED_WHILE_ANSWERING in result.stderr.splitlines()


def test_an_error_raised_in_drakes_cpp_is_one_failure_object(capsys, monkeypatch):
    """pydrake raises a C++ exception as RuntimeError: a bug, so the traceback stays (on stderr, where Python
    prints it), and stdout holds exactly one FAILURE object."""
    from pydrake.multibody.plant import MultibodyPlant

    from app.cli import main

    def drake_fails(*args, **kwargs):
        MultibodyPlant(0.0).GetBodyByName("no such body")  # raises in C++

    monkeypatch.setattr("app.commands.common.CollisionOracle", drake_fails)
    with pytest.raises(RuntimeError, match="no such body"):
        main(["plan", "bar", "--json"])
    out = capsys.readouterr().out
    answer = _one_json(out)
    assert answer["success"] is False and answer["error"]["code"] == "FAILURE" and answer["exit_code"] == 1
    assert "RuntimeError" in answer["error"]["message"] and "Traceback" not in out


def test_an_answer_json_cannot_hold_prints_nothing_but_the_failure(capsys, monkeypatch):
    """print_json makes the whole line before writing any of it: a value it cannot write fails the call with
    nothing printed, so the command's one answer is the failure object."""
    from app.cli import main
    from app.scene.model import Scene

    summary = Scene.summary
    monkeypatch.setattr(Scene, "summary", lambda self: {**summary(self), "extra": object()})
    with pytest.raises(TypeError):
        main(["scenes", "--json"])
    answer = _one_json(capsys.readouterr().out)
    assert answer["success"] is False and answer["error"]["code"] == "FAILURE" and answer["exit_code"] == 1


def test_print_json_writes_its_line_in_one_call(monkeypatch):
    writes = []

    class Recorder:  # a stream of text only
        def write(self, text):
            writes.append(text)

        def flush(self):
            pass

    monkeypatch.setattr(sys, "stdout", Recorder())
    print_json({"numbers": list(range(1000)), "nan": float("nan")})
    assert len(writes) == 1 and writes[0].endswith("}\n")
    assert json.loads(writes[0]) == {"success": True, "numbers": list(range(1000)), "nan": None}


def test_an_interrupt_that_a_c_extension_turned_into_an_import_error_is_an_interrupt(capsys, monkeypatch):
    """Ctrl-C while pydrake loads a module comes out as ImportError("initialization failed"), caused by the
    KeyboardInterrupt: exit code 130 and PREEMPTED, not a FAILURE with a traceback."""
    from app.cli import main

    def interrupted_import(*args, **kwargs):
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as exc:
            raise ImportError("initialization failed") from exc

    monkeypatch.setattr("app.commands.common.CollisionOracle", interrupted_import)
    assert main(["plan", "bar", "--json"]) == 130
    out, err = capsys.readouterr()
    answer = _one_json(out)
    assert answer["error"]["code"] == "PREEMPTED" and answer["exit_code"] == 130 and err == "error: interrupted\n"


@pytest.mark.parametrize(
    "how", ["raise KeyboardInterrupt", "raise ImportError('initialization failed') from KeyboardInterrupt()"]
)
def test_ctrl_c_while_the_command_line_loads_is_one_preempted_object(tmp_path, how):
    """`python -m app ... --json` interrupted while app.cli imports its modules (a stand-in tqdm, which the command
    line loads and `import app` does not, is interrupted): exit code 130, one PREEMPTED object, one line on stderr."""
    (tmp_path / "tqdm").mkdir()
    (tmp_path / "tqdm" / "__init__.py").write_text(how + "\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(tmp_path), os.environ.get("PYTHONPATH")]))}
    result = subprocess.run(
        [sys.executable, "-m", "app", "scenes", "--json"], capture_output=True, text=True, env=env, timeout=300
    )
    assert result.returncode == 130, result.stderr
    assert _one_json(result.stdout)["error"]["code"] == "PREEMPTED" and result.stderr == "error: interrupted\n"
