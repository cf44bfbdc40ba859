"""What the commands share: one argparse type per kind of value, so a value is checked the same way wherever it is
given, the one-line JSON answer, and `answering()`, inside which a command writes its answer whole.

A type raises argparse.ArgumentTypeError; the parser turns that into one line naming the flag (exit code 2).
"""

import argparse
import contextlib
import io
import json
import math
import os
import re
import signal
import sys
import threading
import time

from app.checking.budget import MAX_CHECKS, MAX_SECONDS, SAFETY_NET_SECONDS, Budget
from app.checking.certify import CLEARANCE
from app.checking.oracle import CollisionOracle
from app.errors import NoPath, UserError
from app.io import check_output
from app.planning.sources import ADAPTIVE, check_source_name
from app.samplers import SAMPLERS, check_name


def whole_number(least: int, most: int):
    """An argparse type: a whole number from `least` to `most`; the message names both limits."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
        if not least <= value <= most:
            raise argparse.ArgumentTypeError(f"must be from {least} to {most}, got {text}")
        return value

    return parse


# Limits far above any useful run (the paper's roadmaps have hundreds of samples), so that a typo such as 1e9
# samples is refused at once instead of filling memory or running for days.
seed = whole_number(0, 2**32 - 1)  # what every random generator here (numpy, OMPL) takes
sample_count = whole_number(0, 100_000)  # samples of one kind in one roadmap
samples_wanted = whole_number(1, 100_000)  # `sample -k`, samples per trial
neighbours = whole_number(1, 1_000)  # k nearest neighbours
shortcut_rounds = whole_number(0, 10_000)
repetitions = whole_number(1, 10_000)  # seeds, trials, runs, repeats per measured cell
MAX_PROCESSES = 256
processes = whole_number(1, MAX_PROCESSES)  # workers, threads
check_count = whole_number(1, MAX_CHECKS)  # collision checks of a budget, configurations of a measurement


def _finite_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text}")
    return value


def positive_float(text: str) -> float:
    value = _finite_float(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be a positive finite number: {text}")
    return value


def budget_seconds(text: str) -> float:
    """A time budget in seconds: positive, at most MAX_SECONDS."""
    value = positive_float(text)
    if value > MAX_SECONDS:
        raise argparse.ArgumentTypeError(f"must be at most {MAX_SECONDS:g} s (a day), got {text}")
    return value


def non_negative_float(text: str) -> float:
    value = _finite_float(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must not be negative: {text}")
    return value


# A longer period samples a motion of a few seconds at its ends only: the samples no longer describe the motion.
MAX_SAMPLE_PERIOD = 1.0


def sample_period(text: str) -> float:
    """A trajectory's sample period in seconds: positive, at most MAX_SAMPLE_PERIOD."""
    value = positive_float(text)
    if value > MAX_SAMPLE_PERIOD:
        raise argparse.ArgumentTypeError(f"must be at most {MAX_SAMPLE_PERIOD:g} s, got {text}")
    return value


def share(text: str) -> float:
    """A fraction from 0 to 1."""
    value = _finite_float(text)
    if not 0 <= value <= 1:
        raise argparse.ArgumentTypeError(f"must be a share from 0 to 1: {text}")
    return value


def fraction(text: str) -> float:
    """A fraction in (0, 1]: a scaling factor."""
    value = _finite_float(text)
    if not 0 < value <= 1:
        raise argparse.ArgumentTypeError(f"must be a fraction in (0, 1]: {text}")
    return value


def add_scaling_arguments(p) -> None:
    """--velocity-scale and --acceleration-scale, as MoveIt's scaling factors, and --clearance, for a command that
    times motion."""
    for kind in ("velocity", "acceleration"):
        p.add_argument(
            f"--{kind}-scale",
            type=fraction,
            default=1.0,
            metavar="S",
            help=f"time the motion with this fraction (0, 1] of the {kind} limits (default 1)",
        )
    p.add_argument(
        "--clearance",
        type=positive_float,
        default=CLEARANCE,
        metavar="D",
        help=f"the distance the certified motion keeps from everything (scene length units: metres for the robots; "
        f"default {CLEARANCE:g}); the straight lines between its samples and the path's waypoints keep half of it, "
        "so a controller that interpolates linearly between them stays clear",
    )


def add_change_arguments(p) -> None:
    """--change: the cell as a change file leaves it (app.scene.changes), repeatable, applied in order."""
    p.add_argument(
        "--change",
        metavar="CHANGE.yaml",
        action="append",
        default=[],
        help="plan in the cell as this change leaves it: obstacles added, moved or removed, objects attached to or "
        "detached from the robot (repeatable, applied in order); a change file of ours or a MoveIt PlanningScene "
        "diff (is_diff: true); with --roadmap, the roadmap is repaired for it",
    )


def read_changes(files: list[str]) -> list:
    """The changes in `files`, CellChange YAML or MoveIt planning-scene diffs (each read and checked before any slow
    work)."""
    from app.scene.moveit_diff import read_change_file

    return [read_change_file(path) for path in files]


def open_cell(roadmap: str | None, scene, changes: list, threads: int | None = None):
    """(oracle, cell roadmap or None) for `scene` after `changes`: with a roadmap file, the roadmap in the cell it
    was last repaired for, repaired for `changes` too (CellRoadmap.open); without one, the changed cell's oracle."""
    from app.planning.cell import CellRoadmap
    from app.scene.changes import changed_scene

    if roadmap:
        cell = CellRoadmap.open(roadmap, CollisionOracle(scene, threads=threads), changes)
        return cell.oracle, cell
    return CollisionOracle(changed_scene(scene, changes), threads=threads), None


def comma_list(text: str) -> list[str]:
    """'a, b,c' -> ['a', 'b', 'c'] (blank items dropped): the one parser of comma-separated values."""
    items = [item.strip() for item in text.split(",") if item.strip()]
    if not items:
        raise argparse.ArgumentTypeError(f"needs at least one comma-separated value: {text!r}")
    return items


def names_from(known, what: str):
    """A type for a comma-separated list of names out of `known` (jobs, sweep parts, ...)."""

    def names(text: str) -> list[str]:
        items = comma_list(text)
        unknown = [item for item in items if item not in known]
        if unknown:
            raise argparse.ArgumentTypeError(f"unknown {what} '{unknown[0]}' (known: {', '.join(known)})")
        return items

    return names


def float_list(text: str) -> list[float]:
    """Comma-separated numbers, all finite."""
    try:
        values = [float(v) for v in comma_list(text)]
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a comma-separated list of numbers: {text!r}") from None
    if not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(f"needs finite numbers: {text!r}")
    return values


def positive_float_list(text: str) -> list[float]:
    """Comma-separated positive finite numbers (steps, for example)."""
    values = float_list(text)
    if not all(v > 0 for v in values):
        raise argparse.ArgumentTypeError(f"must be positive numbers: {text!r}")
    return values


def sampler_name(text: str) -> str:
    """A registered sampler's name (app.samplers.check_name)."""
    try:
        return check_name(text)
    except UserError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def source_name(text: str) -> str:
    """A registered sampler's name or the adaptive mixture's (app.planning.sources.check_source_name): where a
    query's narrow-passage samples come from."""
    try:
        return check_source_name(text)
    except UserError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def sampler_names(text: str) -> list[str]:
    """Comma-separated registered sampler names."""
    return [sampler_name(name) for name in comma_list(text)]


def known_samplers() -> str:
    """The registered samplers' names (app.samplers.SAMPLERS), for a flag's help."""
    return ", ".join(SAMPLERS)


def known_sources() -> str:
    """The names `source_name` takes, for a flag's help."""
    return f"{ADAPTIVE} (a mix learned while the query runs), or one sampler with placements: {known_samplers()}"


_BUDGET_PART = re.compile(r"^(?P<number>\d+(?:\.\d*)?|\.\d+)\s*(?P<unit>s|min|k?checks|M?checks)$")
# Beside a check limit: no time limit at all (a query's time safety net, SAFETY_NET_SECONDS, left out).
NO_TIME_LIMIT = "nolimit"
_BUDGET_USAGE = "use e.g. 30s, 2min, 200000checks, 200kchecks, 30s,200kchecks or 200kchecks,nolimit"
BUDGET_HELP = (
    "30s, 2min, 200000checks, 200kchecks, or both as 30s,200kchecks; checks alone keep the "
    f"{SAFETY_NET_SECONDS:g} s safety net (200kchecks means 200kchecks,{SAFETY_NET_SECONDS:g}s), which "
    f"200kchecks,{NO_TIME_LIMIT} leaves out"
)


def parse_budget(text: str) -> Budget:
    """A query's budget: '30s', '2min', '200000checks', '200kchecks', '5Mchecks', or a time and a check limit joined
    by a comma: '30s,200kchecks'. A check limit alone keeps the time safety net SAFETY_NET_SECONDS (a query on a
    slow machine or among heavy meshes still ends); 'nolimit' beside it ('300kchecks,nolimit') leaves that out."""
    return _budget(text, SAFETY_NET_SECONDS)


def parse_build_budget(text: str) -> Budget:
    """A cell roadmap build's budget: as parse_budget, without a time safety net (a build is bounded by its node
    count, looked at between rounds, and ends with the roadmap it has, not with a failure)."""
    return _budget(text, None)


def _budget(text: str, safety_net: float | None) -> Budget:
    seconds = checks = None
    no_limit = False
    parts = [p.strip() for p in str(text).split(",")]
    if not all(parts) or len(parts) > 2:
        raise argparse.ArgumentTypeError(f"bad budget {text!r}: {_BUDGET_USAGE}")
    for part in parts:
        if part == NO_TIME_LIMIT:
            no_limit = True
            continue
        match = _BUDGET_PART.match(part)
        if not match:
            raise argparse.ArgumentTypeError(f"bad budget {part!r}: {_BUDGET_USAGE}")
        number, unit = float(match["number"]), match["unit"]
        if not math.isfinite(number) or number <= 0:
            raise argparse.ArgumentTypeError(f"bad budget {part!r}: must be positive")
        if unit in ("s", "min"):
            if seconds is not None:
                raise argparse.ArgumentTypeError(f"bad budget {text!r}: two time limits")
            seconds = number * (60.0 if unit == "min" else 1.0)
            if seconds > MAX_SECONDS:
                raise argparse.ArgumentTypeError(f"bad budget {part!r}: at most {MAX_SECONDS:g} s (a day)")
        else:
            if checks is not None:
                raise argparse.ArgumentTypeError(f"bad budget {text!r}: two check limits")
            scale = {"k": 1_000, "M": 1_000_000}.get(unit[0], 1)
            checks = int(round(number * scale))
            if not 0 < checks <= MAX_CHECKS:
                raise argparse.ArgumentTypeError(f"bad budget {part!r}: from 1 to {MAX_CHECKS} checks")
    if no_limit and (seconds is not None or checks is None):
        raise argparse.ArgumentTypeError(
            f"bad budget {text!r}: {NO_TIME_LIMIT} leaves the time limit out of a check limit "
            f"(e.g. 300kchecks,{NO_TIME_LIMIT}); a budget of neither would let a query run until killed"
        )
    if checks is not None and seconds is None and not no_limit:
        seconds = safety_net
    return Budget(seconds=seconds, checks=checks)


def check_outputs(*files: str | None, creating_folders: tuple = ()) -> None:
    """Every output path a command was given, checked before any work starts: each writable (app.io.check_output;
    the missing folders of those in `creating_folders` may still be created) and no two the same file. None stands
    for a flag not given."""
    paths = [(f, False) for f in files if f] + [(f, True) for f in creating_folders]
    seen = {}
    for path, make_folders in paths:
        real = os.path.realpath(check_output(path, make_folders=make_folders))
        if os.path.islink(path):  # replaced by the file written, as `cp` would not: announce says so
            _links[os.path.abspath(path)] = os.readlink(path)
        if real in seen:
            raise UserError(f"{seen[real]} and {path} are the same file; give each output its own path")
        seen[real] = path


@contextlib.contextmanager
def failure_details(extra: dict):
    """Inside the block, a planning failure (NoPath) or an interrupt leaves with `extra` added to its `details`, which
    app.cli prints in the --json failure answer: what a command knows beside the query's own figures (a custom scene's
    load time and mesh decompositions)."""
    try:
        yield
    except (NoPath, KeyboardInterrupt) as exc:
        if extra:
            exc.details = {**extra, **(getattr(exc, "details", None) or {})}
        raise


# A command that runs longer than this shows its progress (on a terminal): shorter ones stay quiet.
PROGRESS_AFTER = 1.5
PROGRESS_EVERY = 0.25  # seconds between updates of the progress line
# Seconds between the plain progress lines written where stderr is no terminal (a log file, a pipe, CI).
PROGRESS_LOG_EVERY = 10.0


@contextlib.contextmanager
def progress(args, oracle, what: str):
    """While the block runs longer than PROGRESS_AFTER s: one line on stderr, rewritten in place, with the time so far
    and the collision checks the oracle answered since the block began, cleared when the block ends. Where stderr is
    no terminal (a log), the same as a plain line every PROGRESS_LOG_EVERY s instead. Never with --json (a program
    reads that answer)."""
    if getattr(args, "json", False):
        yield
        return
    from tqdm import tqdm

    done, answered = threading.Event(), oracle.answered

    def log() -> None:
        started = time.monotonic()
        while not done.wait(PROGRESS_LOG_EVERY):
            seconds, checks = time.monotonic() - started, oracle.answered - answered
            print(f"{what}: {seconds:.0f} s, {checks:,} collision checks", file=sys.stderr, flush=True)

    def show() -> None:
        if done.wait(PROGRESS_AFTER):
            return
        started = time.monotonic() - PROGRESS_AFTER
        with tqdm(file=sys.stderr, leave=False, bar_format="{desc}", dynamic_ncols=True) as line:
            while True:
                line.set_description_str(
                    f"{what}: {time.monotonic() - started:.0f} s, {oracle.answered - answered:,} collision checks",
                    refresh=True,
                )
                if done.wait(PROGRESS_EVERY):
                    return

    shower = threading.Thread(target=show if sys.stderr.isatty() else log, name="progress", daemon=True)
    shower.start()
    try:
        yield
    finally:
        done.set()
        shower.join()


# Output paths that were symbolic links when check_outputs looked (absolute path -> the link's target): the file
# written replaces the link, and leaves its target alone (app.io writes through a temporary file and a rename).
_links: dict[str, str] = {}


def announce(*files: str | None) -> None:
    """Name each file a command wrote on stderr, one line each (stdout may carry its JSON answer); None: not asked.
    A file that replaced a symbolic link says so."""
    for file in files:
        if file:
            target = _links.pop(os.path.abspath(file), None)
            replaced = f" (it replaced a symbolic link to {target}, which is left as it was)" if target else ""
            print(f"wrote {file}{replaced}", file=sys.stderr)


# What `answering()` says on stderr when an interrupt came while the answer was being written.
INTERRUPTED_WHILE_ANSWERING = "interrupt received while writing the answer; finished it"
_DEFERRED_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class _Answer(threading.local):
    signals: list[int] | None = None  # inside the outermost answering() block: the signals received there
    written = False  # an answering() block has ended: the command's answer is out


_answer = _Answer()


def answer_written() -> bool:
    """Whether the running command has written its answer (an answering() block of it has ended)."""
    return _answer.written


def forget_answer() -> None:
    """A new command starts (cli.main): it has written no answer yet."""
    _answer.written = False


@contextlib.contextmanager
def answering(*, final: bool = True):
    """The block in which a command writes its answer: its output files (app.io.all_or_nothing) and what it prints
    on stdout (with `final` False: files written on the way to a failure, whose answer app.cli prints after it). A
    command enters it once it has its answer; inside it SIGINT (Ctrl-C) and SIGTERM wait until the block ends, so
    the answer is written whole, and the command then ends as it would have (exit 0 on success), with one line on
    stderr saying an interrupt came too late to matter. Before the block an interrupt stops the command as before
    (exit 130, nothing written).

    What the block prints on stdout is held and written when it ends, all of it (`_write_whole`), before the
    signals are let through; if the block fails, none of it (as none of its files): the failure is the answer.

    Only the main thread receives signals: in another thread (or inside an outer block) the block just runs."""
    if threading.current_thread() is not threading.main_thread() or _answer.signals is not None:
        yield
        return
    received: list[int] = []
    _answer.signals, previous, stdout = received, {}, sys.stdout
    try:
        for number in _DEFERRED_SIGNALS:
            previous[number] = signal.signal(number, lambda signum, frame: received.append(signum))
        sys.stdout = held = io.StringIO()
        try:
            yield
        finally:
            sys.stdout = stdout
        _write_whole(stdout, held.getvalue())
        _answer.written = final
        if received:
            print(INTERRUPTED_WHILE_ANSWERING, file=sys.stderr, flush=True)
    finally:
        for number, handler in previous.items():
            signal.signal(number, signal.SIG_DFL if handler is None else handler)
        _answer.signals = None


def _write_whole(stream, text: str) -> None:
    """`text` written to `stream` and flushed, all of it. Through the stream's binary buffer, since a signal can cut
    a write to a pipe short, and an unbuffered stdout (PYTHONUNBUFFERED, python -u: a TextIOWrapper straight on
    the file) drops the rest of a write cut short: the bytes are written again from where the write stopped."""
    stream.flush()
    binary = getattr(stream, "buffer", None)
    if binary is None:  # a stream of text only (one a test put there): its write takes the whole text
        stream.write(text)
        stream.flush()
        return
    rest = memoryview(text.encode(stream.encoding or "utf-8", stream.errors or "strict"))
    while rest:
        rest = rest[binary.write(rest) or 0 :]  # (None: a non-blocking stream took nothing this time)
    binary.flush()


def print_json(obj: dict) -> None:
    """A command's answer as one line of JSON on stdout, written in one call inside `answering()` (so that neither
    an interrupt nor a short write cuts it); every answer says whether it is a success. The whole line is made
    before anything is written: a value JSON cannot hold fails the call with nothing printed. JSON has no NaN or
    infinity (Python's json would print them anyway): they become null, e.g. a median over no successes."""
    text = json.dumps(_finite({"success": True, **obj}), indent=None, separators=(",", ":"), allow_nan=False)
    with answering():
        sys.stdout.write(text + "\n")


def _finite(value):
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {key: _finite(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(item) for item in value]
    return value
