"""`python -m app ...`: argument parsing, exit codes and one-line errors. Commands live in their own modules.

Each command module exposes `register(subparsers)`, which adds its parser and sets `func` to a callable taking the
parsed arguments and returning an exit code. Exit codes: 0 ok, 1 no path found, 2 bad input, 3 start/goal invalid.
"""
import argparse
import json
import math
import sys

from app.errors import UserError


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # argparse's own errors also get one line and exit code 2
        raise UserError(f"{self.prog}: {message}")


def positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be positive: {text}")
    return value


def non_negative_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"must not be negative: {text}")
    return value


def positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f"must be a positive finite number: {text}")
    return value


def float_list(text: str) -> list[float]:
    """Comma-separated numbers, all finite."""
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a comma-separated list of numbers: {text!r}") from None
    if not values or not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(f"needs finite numbers: {text!r}")
    return values


def print_json(obj) -> None:
    json.dump(obj, sys.stdout, indent=None, separators=(",", ":"))
    sys.stdout.write("\n")


def build_parser() -> argparse.ArgumentParser:
    from app import commands

    parser = _Parser(prog="python -m app", description="Narrow-passage PRM planning on Drake.")
    subparsers = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    for module in commands.MODULES:
        module.register(subparsers)
    return parser


def main(argv=None) -> int:
    try:
        args = build_parser().parse_args(argv)
        return int(args.func(args) or 0)
    except UserError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        print("error: interrupted", file=sys.stderr)
        return 130
