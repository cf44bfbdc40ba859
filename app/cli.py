"""`python -m app ...`: the parser of every command, and the one place where a failure becomes an exit code.

Each command module (app/commands) exposes `register(subparsers)`, which adds its parser and sets `func` to a
callable taking the parsed arguments; it returns on success and raises on failure. `main` prints what was raised
as one line on stderr and exits with its code from EXIT_CODES, and each warning the library gives
(app.errors.PlannerWarning) as one line on stderr when it is given: "warning: ..." or, for a Note, "note: ...".
"""

import argparse
import os
import re
import sys
import warnings

from app import commands
from app.commands.common import INTERRUPTED_WHILE_ANSWERING, answer_written, answering, forget_answer, print_json
from app.errors import InvalidEndpoint, NoPath, Note, PlannerWarning, SamplerBudgetExceeded, UserError

# The one map from a failure to the process's exit code (0: success). An exception takes the code of its nearest
# class here: NoPath is also a UserError, and gets 1.
EXIT_CODES = {
    NoPath: 1,  # no path found
    SamplerBudgetExceeded: 1,  # a sampler spent its check budget before it had its samples
    UserError: 2,  # bad input
    InvalidEndpoint: 3,  # start or goal out of bounds or in collision
    KeyboardInterrupt: 130,  # Ctrl-C (128 + SIGINT, as a shell reports it)
    BrokenPipeError: 141,  # the reader of stdout went away (`... | head -1`): 128 + SIGPIPE, as a shell reports it
}


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # argparse's own errors also get one line and exit code 2
        raise UserError(f"{self.prog}: {message}")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="python -m app", description="Narrow-passage PRM planning on Drake.")
    subparsers = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    for module in commands.MODULES:
        module.register(subparsers)
    return parser


# A value that starts with a minus sign and a digit: a negative number or list ("-1.57,0,0", "-1..1,-2..2").
_NEGATIVE_VALUE = re.compile(r"^-\.?\d")


def join_negative_values(argv: list[str]) -> list[str]:
    """argv with each negative value glued to the flag before it ("--start", "-1.57,0" -> "--start=-1.57,0"):
    argparse takes a lone negative number as a value but reads "-1.57,0" as an unknown flag ("expected one
    argument"). No flag of ours starts with a digit, so such a token is always a value."""
    joined: list[str] = []
    for i, token in enumerate(argv):
        if token == "--":
            return joined + argv[i:]
        previous = joined[-1] if joined else ""
        if (
            _NEGATIVE_VALUE.match(token)
            and previous.startswith("-")
            and "=" not in previous
            and not _NEGATIVE_VALUE.match(previous)
        ):
            joined[-1] = f"{previous}={token}"
        else:
            joined.append(token)
    return joined


def refuse_empty_values(argv: list[str]) -> None:
    """An empty argument ("--out ''", "--robot=", a blank scene) is a slip (an unset shell variable), never a value
    of ours: refused, where argparse would take it and the command would quietly act as if the flag were not given."""
    for i, token in enumerate(argv):
        flag, equals, value = token.partition("=") if token.startswith("--") else ("", "", token)
        if equals and not value.strip():
            raise UserError(f"argument {flag}: empty value")
        if not flag and not token.strip():
            raise UserError(f"empty argument after {argv[i - 1]}" if i else "empty first argument")


def exit_code(exc: BaseException) -> int:
    """The exit code of a failure: that of the nearest class of `exc` in EXIT_CODES."""
    return next(EXIT_CODES[cls] for cls in type(exc).__mro__ if cls in EXIT_CODES)


def main(argv=None) -> int:
    """Run one command. A failure is one line on stderr and its exit code; with --json also one JSON object on
    stdout: {"success": false, "error": {"code", "message"}, "exit_code"}, and "details" when the failure (a planning
    query's, or an interrupt during one) carries them. A command writes its answer inside
    app.commands.common.answering(): an interrupt that comes once it has begun no longer stops the command (exit 0,
    one line on stderr saying so), and --json prints exactly one object on every path. The library's warnings
    show as one line each, every time one is given (`one_line_warnings`)."""
    argv = sys.argv[1:] if argv is None else list(argv)
    forget_answer()
    with warnings.catch_warnings():
        warnings.simplefilter("always", PlannerWarning)
        warnings.showwarning = one_line_warnings(warnings.showwarning)
        return _run(argv)


def one_line_warnings(other):
    """A `warnings.showwarning` that prints a PlannerWarning as one line on stderr, "note: ..." for a Note and
    "warning: ..." for the others, and hands every other warning to `other`."""

    def show(message, category, filename, lineno, file=None, line=None):
        if not issubclass(category, PlannerWarning):
            return other(message, category, filename, lineno, file, line)
        prefix = "note" if issubclass(category, Note) else "warning"
        print(f"{prefix}: {' '.join(str(message).split())}", file=sys.stderr, flush=True)

    return show


def _run(argv: list[str]) -> int:
    """`main` on arguments, its warnings set up."""
    try:
        refuse_empty_values(argv)
        args = build_parser().parse_args(join_negative_values(argv))
        code = int(args.func(args) or 0)
        sys.stdout.flush()  # here, so that a closed pipe is met inside this try, not at the interpreter's exit
        return code
    except BrokenPipeError as exc:
        # Nobody reads the rest: end quietly. Later writes (and the final flush) go nowhere instead of raising again.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return exit_code(exc)
    except KeyboardInterrupt as exc:
        return _interrupted(argv, getattr(exc, "details", None))
    except UserError as exc:
        return _fail(argv, str(exc), exit_code(exc), exc.code, getattr(exc, "details", None))
    except Exception as exc:
        if caused_by_interrupt(exc):  # e.g. Ctrl-C while pydrake loads: ImportError("initialization failed")
            return _interrupted(argv)
        # A bug, not bad input (or an error raised in Drake's C++, which pydrake raises as RuntimeError): the
        # traceback stays, on stderr (it is what a report needs), and a --json reader still gets its one answer on
        # stdout, with MoveIt's generic FAILURE and Python's exit code for an uncaught exception.
        if "--json" in argv and not answer_written():
            _print_failure("FAILURE", f"internal error: {type(exc).__name__}: {exc}", status=1)
        raise


def caused_by_interrupt(exc: BaseException) -> bool:
    """Whether `exc` is a Ctrl-C or was raised because of one: an interrupt inside a C extension's import comes out
    as the ImportError it caused."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


def _interrupted(argv: list[str], details: dict | None = None) -> int:
    """Ctrl-C: exit code 130 and PREEMPTED, unless the command's answer is out whole already (then it came too late
    to matter: exit 0). `details`: what the interrupted query had spent, when the interrupt came during one."""
    if answer_written():
        print(INTERRUPTED_WHILE_ANSWERING, file=sys.stderr, flush=True)
        return 0
    return _fail(argv, "interrupted", EXIT_CODES[KeyboardInterrupt], "PREEMPTED", details)


def _fail(argv: list[str], message: str, code: int, error: str, details: dict | None = None) -> int:
    """A failure's one line on stderr and, with --json, its one JSON object (none if the command's answer is out
    already: --json prints one object), with `details` when the failure has them; returns its exit code."""
    with answering():  # a second Ctrl-C does not cut the failure's answer either
        print(f"error: {message}", file=sys.stderr, flush=True)
        if "--json" in argv and not answer_written():
            _print_failure(error, message, code, details)
    return code


def _print_failure(code: str, message: str, status: int, details: dict | None = None) -> None:
    """The failure's JSON object; `details` (what a planning query spent: its counts and phase times, see
    docs/schemas/failure.json) only when there are some."""
    extra = {"details": details} if details else {}
    print_json({"success": False, "error": {"code": code, "message": message}, "exit_code": status, **extra})
