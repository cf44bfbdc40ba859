"""The results-store flags of the benchmarks that keep their trials (--store, --fresh), and what they say about the
trials they reused instead of running (app.bench.store's docstring has the rule)."""

import sys

from app.commands.common import announce


def add_arguments(p, default: str) -> None:
    p.add_argument(
        "--store",
        default=default,
        metavar="FILE.sqlite",
        help=f"results store; trials already in it are reused, not run (a killed run resumes). Default {default}, "
        "relative to the working directory",
    )
    add_fresh_argument(p)


def add_fresh_argument(p) -> None:
    p.add_argument(
        "--fresh",
        action="store_true",
        help="do not reuse stored trials of another code version: run them again and replace their rows",
    )


def say_reused(reuse, store: str | None = None) -> None:
    """On stderr (stdout may carry the one JSON answer): how many trials came from the store and which code versions
    wrote them; a warning when that is not the current code; then the store written, if given."""
    if reuse.reused:
        print(reuse.message(), file=sys.stderr)
        warning = reuse.warning()
        if warning:
            print(f"warning: {warning}", file=sys.stderr)
    announce(store)
