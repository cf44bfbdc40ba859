"""`bench summary`: the benchmark page's opening tables, one per question, rewritten from the results stores
(app.bench.summary); nothing is run."""

import sys
from pathlib import Path

from app.bench.summary import PAGE, RESULTS, tables, write_page
from app.commands.common import announce, answering, check_outputs


def register(kinds) -> None:
    p = kinds.add_parser(
        "summary",
        help="the benchmark page's opening tables (the shipped scenes, against OMPL, with a stored roadmap, MoveIt's "
        "problems), read from the results stores and written into docs/benchmarks.md; runs nothing",
    )
    p.add_argument(
        "--results",
        default=None,
        metavar="FOLDER",
        help="folder of the results stores, each in its bench's subfolder (default: the repository's results/)",
    )
    p.add_argument(
        "--page",
        default=None,
        metavar="FILE.md",
        help="page whose lines between its two bench-summary marker lines are rewritten (default: the repository's "
        "docs/benchmarks.md)",
    )
    p.add_argument("--print", action="store_true", help="print the tables on stdout instead of writing the page")
    p.set_defaults(func=run)


def run(args) -> int:
    page = Path(args.page) if args.page else PAGE
    if not args.print:
        check_outputs(str(page))
    block = tables(Path(args.results) if args.results else RESULTS)
    with answering():
        if args.print:
            print(block)
        elif write_page(block, page):
            announce(str(page))
        else:
            print(f"{page} is up to date: its tables are those the stores give", file=sys.stderr)
        return 0
