"""`sample SCENE --sampler NAME`: draw k narrow-passage samples, report them (JSON or a summary) and draw them."""

from app.bench.sampling import run_trial
from app.checking.oracle import CollisionOracle
from app.commands import custom
from app.commands.common import (
    announce,
    answering,
    check_outputs,
    known_samplers,
    positive_float,
    print_json,
    processes,
    sampler_name,
    samples_wanted,
    seed,
)
from app.errors import SamplerBudgetExceeded
from app.planning.settings import default_step


def register(subparsers) -> None:
    p = subparsers.add_parser("sample", help="draw k samples with one of the seven samplers")
    p.add_argument(
        "scene", nargs="?", help="scene name, problem-file path or custom scene file (or --robot/--env instead)"
    )
    p.add_argument("--sampler", type=sampler_name, required=True, help=f"the sampler: {known_samplers()}")
    p.add_argument("-k", type=samples_wanted, default=30, help="number of samples (default 30)")
    p.add_argument(
        "--step",
        type=positive_float,
        default=None,
        help="step a / bridge length / Gaussian sigma, weighted workspace units (default: the scene file's step, "
        "else a tenth of the scene's extent, as `plan`)",
    )
    p.add_argument("--seed", type=seed, default=0)
    p.add_argument("--threads", type=processes, default=None, help="oracle threads (default: up to 2)")
    p.add_argument("--json", action="store_true", help="one JSON object on stdout")
    p.add_argument("--png", help="draw the samples over the scene to this PNG")
    custom.add_arguments(p)  # --robot / --package-path / --env ...
    p.set_defaults(func=run)


def run(args) -> int:
    check_outputs(args.png)
    oracle = CollisionOracle(custom.scene_from_args(args, args.scene), threads=args.threads)
    step = args.step or default_step(oracle.scene)
    result = run_trial(oracle, args.sampler, step, args.seed, k=args.k, keep_samples=True)
    if not result["ok"]:
        raise SamplerBudgetExceeded(
            f"{args.sampler}: no {args.k} samples within {result['collision_checks']} collision checks"
        )
    samples = result["samples"]
    with answering():  # the picture and the samples are the answer
        if args.png:
            from app.draw import draw_samples  # loads matplotlib: only when a picture is asked for

            draw_samples(
                oracle,
                samples,
                args.png,
                title=f"{oracle.scene.name}: {args.sampler}, k={args.k}, step {step:g}, seed {args.seed}",
            )
            announce(args.png)
        out = {
            "scene": oracle.scene.name,
            "sampler": args.sampler,
            "k": args.k,
            "step": step,
            "seed": args.seed,
            "samples": samples.tolist(),
            "collision_checks": result["collision_checks"],
            "seconds": result["seconds"],
            "passage_fraction": result["passage_fraction"],
            "gave_up": result["gave_up"],
            "attempts": result["attempts"],
        }
        bridges = result["bridges"]
        if bridges is not None:
            out["bridges"] = bridges.tolist()
        if args.json:
            print_json(out)
        else:
            passage = (
                f"{100 * out['passage_fraction']:.0f} % in the passage"
                if oracle.scene.passage_boxes
                else "no passage region declared"
            )
            print(
                f"{out['scene']} {out['sampler']}: {args.k} samples in {out['seconds']:.3f} s, "
                f"{out['collision_checks']} collision checks, {passage}, {out['gave_up']} gave up"
            )
    return 0
