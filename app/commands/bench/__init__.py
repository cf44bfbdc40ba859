"""`bench KIND ...`: one module per benchmark; each adds its sub-command, runs its experiment (app.bench.KIND) and
prints the result."""

from app.commands.bench import (
    ablation,
    audit,
    certify,
    changes,
    jobs,
    moveit,
    ompl,
    oracle,
    paper,
    plan,
    queries,
    sampling,
    summary,
    uav,
)

KINDS = [oracle, sampling, plan, uav, jobs, ompl, moveit, paper, audit, certify, queries, changes, ablation, summary]


def register(subparsers) -> None:
    p = subparsers.add_parser("bench", help="benchmarks (figures side by side with their peers, in one run)")
    kinds = p.add_subparsers(dest="kind", required=True, parser_class=type(p))
    for kind in KINDS:
        kind.register(kinds)
