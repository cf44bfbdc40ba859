"""`bench KIND ...`: each benchmark lives in app/bench/KIND.py and registers its own sub-command."""
from app.bench import jobs, ompl, oracle, paper, plan, sampling, uav

BENCHES = [oracle, sampling, plan, uav, jobs, ompl, paper]


def register(subparsers) -> None:
    p = subparsers.add_parser("bench", help="benchmarks (figures side by side with their peers, in one run)")
    kinds = p.add_subparsers(dest="kind", required=True, parser_class=type(p))
    for bench in BENCHES:
        bench.register(kinds)
