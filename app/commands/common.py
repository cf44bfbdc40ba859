"""What the commands share: one argparse type per kind of value, so a value is checked the same way wherever it is
given, and the one-line JSON answer.

A type raises argparse.ArgumentTypeError; the parser turns that into one line naming the flag (exit code 2).
"""

import argparse
import json
import math
import re
import sys

from app.budget import Budget
from app.errors import UserError
from app.samplers import check_name


def _whole_number_at_least(least: int, fault: str):
    """An argparse type: a whole number >= least, else `fault` (e.g. "must be positive") with the text."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
        if value < least:
            raise argparse.ArgumentTypeError(f"{fault}: {text}")
        return value

    return parse


positive_int = _whole_number_at_least(1, "must be positive")
non_negative_int = _whole_number_at_least(0, "must not be negative")


def _finite_number(accept, fault: str):
    """An argparse type: a finite number for which accept(value) holds, else `fault` with the text."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
        if not math.isfinite(value) or not accept(value):
            raise argparse.ArgumentTypeError(f"{fault}: {text}")
        return value

    return parse


positive_float = _finite_number(lambda v: v > 0, "must be a positive finite number")
non_negative_float = _finite_number(lambda v: v >= 0, "must be a finite number, zero or more")


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


def sampler_names(text: str) -> list[str]:
    """Comma-separated registered sampler names."""
    return [sampler_name(name) for name in comma_list(text)]


_BUDGET_PART = re.compile(r"^(?P<number>\d+(?:\.\d*)?|\.\d+)\s*(?P<unit>s|min|k?checks|M?checks)$")
_BUDGET_USAGE = "use e.g. 30s, 2min, 200000checks, 200kchecks or 30s,200kchecks"


def parse_budget(text: str) -> Budget:
    """'30s', '2min', '200000checks', '200kchecks', '5Mchecks', or two joined by a comma: '30s,200kchecks'."""
    seconds = checks = None
    parts = [p.strip() for p in str(text).split(",")]
    if not all(parts) or len(parts) > 2:
        raise argparse.ArgumentTypeError(f"bad budget {text!r}: {_BUDGET_USAGE}")
    for part in parts:
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
        else:
            if checks is not None:
                raise argparse.ArgumentTypeError(f"bad budget {text!r}: two check limits")
            scale = {"k": 1_000, "M": 1_000_000}.get(unit[0], 1)
            checks = int(round(number * scale))
            if checks <= 0:
                raise argparse.ArgumentTypeError(f"bad budget {part!r}: must be at least one check")
    return Budget(seconds=seconds, checks=checks)


def print_json(obj: dict) -> None:
    """A command's answer as one line of JSON on stdout; every answer says whether it is a success."""
    json.dump({"success": True, **obj}, sys.stdout, indent=None, separators=(",", ":"))
    sys.stdout.write("\n")
