"""`plan SCENE ...`: PRM with narrow-passage samples, shortcut smoothing and Toppra timing
(app.planning.planner.plan)."""

import argparse
import contextlib
import dataclasses

from app.checking.budget import Budget
from app.checking.oracle import CollisionOracle
from app.commands import custom, view
from app.commands.common import (
    BUDGET_HELP,
    add_change_arguments,
    add_scaling_arguments,
    announce,
    answering,
    failure_details,
    float_list,
    known_sources,
    neighbours,
    open_cell,
    parse_budget,
    positive_float,
    print_json,
    progress,
    read_changes,
    sample_count,
    sample_period,
    seed,
    share,
    shortcut_rounds,
    source_name,
)
from app.errors import UserError
from app.io import all_or_nothing
from app.planning import moveit
from app.planning.ik import pose_goal, robot_frame
from app.planning.query import plan
from app.planning.settings import PlanSettings
from app.scene import moveit as moveit_files
from app.scene import moveit_messages
from app.scene.changes import ChangedScene

DEFAULTS = PlanSettings()


def register(subparsers) -> None:
    p = subparsers.add_parser("plan", help="plan a path (PRM + narrow-passage samples) and time it with Toppra")
    p.add_argument(
        "scene", nargs="?", help="scene name, problem-file path or custom scene file (or --robot/--env instead)"
    )
    add_settings_arguments(p)
    p.add_argument("--start", type=float_list, default=None, help="comma-separated start configuration")
    p.add_argument("--goal", type=float_list, default=None, help="comma-separated goal configuration")
    for end in ("start", "goal"):
        p.add_argument(
            f"--{end}-pose",
            metavar="X,Y,Z,R,P,Y",
            type=pose,
            help=f"{end} as a pose of the tool frame (metres; roll,pitch,yaw in degrees), solved by IK: "
            + (
                "the solution nearest the scene's start"
                if end == "start"
                else "every solution found, any of which the plan may reach"
            ),
        )
    p.add_argument(
        "--tool",
        metavar="FRAME",
        help="the robot frame the poses place (default: the scene's tool frame, else the robot's last body)",
    )
    p.add_argument(
        "--roadmap",
        metavar="FILE.npz",
        help="answer on this cell roadmap (`roadmap build`): refused if it was built for another cell",
    )
    p.add_argument(
        "--update",
        action="store_true",
        help="write back to --roadmap what the query learned (its samples, the edges it decided or proved); a "
        "query that finds no path writes back its edge verdicts",
    )
    p.add_argument("--json", action="store_true", help="one JSON object on stdout")
    p.add_argument(
        "--out",
        default=None,
        help="write the trajectory (times, positions, path, narrow samples) as JSON for `view "
        "--trajectory`; only on success",
    )
    add_change_arguments(p)
    view.add_arguments(p)  # --html / --meshcat / --frame / --collision: show the planned trajectory
    custom.add_arguments(p)  # --robot / --package-path / --env / --env-pose / --bounds ...
    add_moveit_arguments(p)
    p.set_defaults(func=run)


def add_moveit_arguments(p) -> None:
    group = p.add_argument_group("a MoveIt problem (with --robot URDF, --srdf SRDF for a group)")
    group.add_argument(
        "--moveit-request",
        metavar="REQUEST.yaml",
        help="a moveit_msgs/MotionPlanRequest as YAML: its start state, goal constraints (joints, or a link's "
        "position and orientation, solved by IK), group (its joints planned, the others held at the start), "
        "scaling factors and allowed planning time (a time limit on --budget)",
    )
    group.add_argument(
        "--moveit-scene",
        metavar="SCENE.yaml",
        help="the moveit_msgs/PlanningScene it is posed on, as YAML: world collision objects (boxes, spheres, "
        "cylinders), robot state (the start the request's completes), allowed collision matrix",
    )
    group.add_argument(
        "--moveit-out",
        metavar="RESPONSE.yaml",
        help="write the answer as a moveit_msgs/MotionPlanResponse YAML; a failure's too, with MoveIt's error code",
    )


# What a MoveIt request sets, and so may not be given beside it: dest -> the flag as a user types it.
MOVEIT_SETS = {
    "start": "--start",
    "goal": "--goal",
    "start_pose": "--start-pose",
    "goal_pose": "--goal-pose",
    "tool": "--tool",
    "roadmap": "--roadmap",
    "ompl_app": "--ompl-app",
    "floating": "--floating",
    "env": "--env",
    "env_pose": "--env-pose",
    "bounds": "--bounds",
    "hold": "--hold",
    "change": "--change",
}


def add_sampling_arguments(p) -> None:
    """The flags of where samples come from (sampler, step, seed, workspace share, k), for `plan` and `roadmap
    build` alike (their defaults are the same)."""
    p.add_argument(
        "--sampler",
        type=source_name,
        default=DEFAULTS.sampler,
        help=f"where narrow-passage samples come from: {known_sources()} (default {DEFAULTS.sampler})",
    )
    p.add_argument(
        "--step",
        type=positive_float,
        default=None,
        help="sampler base step a in the weighted metric (default: the scene file's step, else a tenth "
        "of the scene's extent)",
    )
    p.add_argument("--seed", type=seed, default=DEFAULTS.seed)
    p.add_argument(
        "--workspace",
        type=share,
        default=DEFAULTS.workspace,
        help="share of the narrow-passage samples placed with a piece of the robot in a narrow gap of the "
        f"workspace (0: the sampler alone; default {DEFAULTS.workspace})",
    )
    p.add_argument(
        "-k",
        "--neighbours",
        type=neighbours,
        default=DEFAULTS.k,
        help="k nearest neighbours per node (default: k-PRM*'s e(1 + 1/d) ln n, for n nodes in d dimensions)",
    )


def add_settings_arguments(p) -> None:
    """The PlanSettings flags (sampler, counts, step, seed, budget, k, smoothing, dt, limit scaling), for any command
    that plans."""
    add_sampling_arguments(p)
    add_scaling_arguments(p)
    p.add_argument(
        "--narrow",
        type=sample_count,
        default=DEFAULTS.narrow,
        help=f"narrow-passage samples, once uniform rounds stall: per round narrow/16 at first, doubling up to "
        f"narrow/4; with --full-roadmap all of them (default {DEFAULTS.narrow})",
    )
    p.add_argument(
        "--uniform",
        type=sample_count,
        default=DEFAULTS.uniform,
        help=f"uniform free samples: uniform/4 per round; with --full-roadmap all of them (default {DEFAULTS.uniform})",
    )
    p.add_argument(
        "--budget",
        type=parse_budget,
        default=DEFAULTS.budget,
        help=f"what the query may spend before it gives up: {BUDGET_HELP} (default {DEFAULTS.budget})",
    )
    p.add_argument(
        "--full-roadmap",
        action="store_true",
        help="build the whole roadmap (all --narrow + --uniform samples, every edge checked) before the "
        "query, as in the paper; default: add samples a quarter at a time, check edges lazily, and "
        "stop as soon as start and goal connect",
    )
    p.add_argument(
        "--smooth",
        type=shortcut_rounds,
        default=DEFAULTS.smooth_rounds,
        help=f"random shortcut rounds after the greedy pass (default {DEFAULTS.smooth_rounds})",
    )
    p.add_argument(
        "--dt",
        type=sample_period,
        default=DEFAULTS.dt,
        help=f"trajectory sample period in seconds (default {DEFAULTS.dt})",
    )


def settings_from_args(args) -> PlanSettings:
    return PlanSettings(
        sampler=args.sampler,
        narrow=args.narrow,
        uniform=args.uniform,
        step=args.step,
        seed=args.seed,
        budget=args.budget,
        k=args.neighbours,
        smooth_rounds=args.smooth,
        dt=args.dt,
        full_roadmap=args.full_roadmap,
        workspace=args.workspace,
        velocity_scale=args.velocity_scale,
        acceleration_scale=args.acceleration_scale,
        clearance=args.clearance,
    )


def run(args) -> int:
    if args.moveit_request or args.moveit_scene or args.moveit_out:
        return run_moveit(args)
    # Everything that can be wrong with the input is found before the (slow) planning starts.
    settings = settings_from_args(args)
    for end in ("start", "goal"):
        if getattr(args, end) is not None and getattr(args, f"{end}_pose") is not None:
            raise UserError(f"give either --{end} or --{end}-pose, not both")
    if args.tool and args.start_pose is None and args.goal_pose is None:
        raise UserError("--tool needs --start-pose or --goal-pose")
    if args.update and not args.roadmap:
        raise UserError("--update writes back to a roadmap: give --roadmap FILE")
    if args.roadmap and args.full_roadmap:
        raise UserError("--full-roadmap builds a roadmap of its own: give it or --roadmap, not both")
    view.check_from_args(args, args.out, args.roadmap if args.update else None)
    changes = read_changes(args.change)
    scene = custom.scene_from_args(args, args.scene)
    # --update: the roadmap's lock, held from before the file is read until it is written back (view.roadmap_lock),
    # so that a second process updating it waits, then adds to this one's update instead of writing over it.
    with view.roadmap_lock(args.roadmap) if args.update else contextlib.nullcontext():
        # The cell as it is now: the changes the roadmap was repaired for, then --change (the roadmap repaired).
        oracle, cell = open_cell(args.roadmap, scene, changes)
        posed = args.start_pose is not None or args.goal_pose is not None
        tool = tool_frame(oracle, args.tool) if posed else None  # the frame the poses place, named in the answer
        start, goal = args.start, args.goal
        # A failure or Ctrl-C from here on answers with what the query spent and, for a custom scene, what loading it
        # took (app.cli prints them as the failure's details).
        saved = (cell, args.roadmap) if args.update else None
        with (
            progress(args, oracle, f"plan {oracle.scene.name}"),
            failure_details(scene_details(oracle.scene)),
            view.kept_on_failure(saved),
        ):
            if args.start_pose is not None:
                start = pose_goal(oracle, args.start_pose, tool=args.tool, seed=args.seed)
            if args.goal_pose is not None:
                goal = pose_goal(oracle, args.goal_pose, tool=args.tool, reference=start, seed=args.seed, every=True)
            result = (
                plan(oracle, settings, start=start, goal=goal) if cell is None else cell.solve(start, goal, settings)
            )
        # Files first (all or none), the answer last: a failure writing one leaves no success printed.
        with answering():  # from here an interrupt waits until the files and the answer are written
            viewer = view.write_outputs(args, oracle.scene, result.trajectory_file(), args.out, saved)
            # a changed cell: the changes a roadmap file records, then --change
            changed = oracle.scene.changes if isinstance(oracle.scene, ChangedScene) else []
            if args.json:
                answer = {**result.to_json(), **certificate_scope(oracle.scene), "tool_frame": tool}
                if changed:
                    answer["changes"] = [c.to_dict() for c in changed]
                print_json({**answer, **scene_details(oracle.scene)})
            else:
                lines = [f"collisions {collisions(oracle.scene)}", *custom.describe(oracle.scene)]
                if changed:
                    lines.append("changed   " + "; ".join(c.describe() for c in changed))
                if tool is not None:
                    lines.append(f"tool      {tool['name']} placed by the pose(s) ({TOOL_CHOSEN[tool['chosen']]})")
                print("\n".join([summary(result, oracle.scene), *("  " + line for line in lines)]))
    view.wait(args, viewer)
    return 0


def run_moveit(args) -> int:
    """`plan --moveit-request REQUEST.yaml [--moveit-scene SCENE.yaml] --robot URDF`: the request's problem planned
    (app.scene.moveit, app.planning.moveit); with --moveit-out its MotionPlanResponse written, on failure too."""
    given = [flag for dest, flag in MOVEIT_SETS.items() if getattr(args, dest)]
    if args.scene or given:
        raise UserError(f"a MoveIt request sets start, goal and world: give it without {', '.join(given) or 'SCENE'}")
    if not args.moveit_request or not args.robot:
        raise UserError(
            "a MoveIt problem needs --moveit-request REQUEST.yaml and --robot URDF (and --srdf for a group)"
        )
    view.check_from_args(args, args.out, args.moveit_out)
    settings = settings_from_args(args)
    problem = None
    with _failure_response(args, lambda: problem):
        options = {dest: getattr(args, dest) for dest in custom.OMPL_APP_OPTIONS}
        problem = moveit_files.read_problem(
            request=args.moveit_request,
            scene=args.moveit_scene,
            robot=args.robot,
            srdf=args.srdf,
            package_path=args.package_path,
            collisions="all" if args.self_collision else "environment",
            **options,
        )
        settings = _request_settings(args, settings, problem)
        oracle = CollisionOracle(problem.scene)
        with progress(args, oracle, f"plan {oracle.scene.name}"), failure_details(scene_details(oracle.scene)):
            goal = moveit.goal_configurations(oracle, problem, seed=args.seed)
            result = plan(oracle, settings, start=problem.start, goal=goal)
    answer = moveit.response(problem, trajectory=result.trajectory, planning_time=result.stats.seconds.total)
    with answering():
        with all_or_nothing():
            if args.moveit_out:
                moveit.write_response(args.moveit_out, answer)
            viewer = view.write_outputs(args, oracle.scene, result.trajectory_file(), args.out)
        announce(args.moveit_out)
        if args.json:
            moveit_answer = {"group": problem.group, "error_code": answer.error_code.val, "response": args.moveit_out}
            answer_json = {**result.to_json(), **certificate_scope(oracle.scene), "tool_frame": None}
            print_json({**answer_json, **scene_details(oracle.scene), "moveit": moveit_answer})
        else:
            lines = [f"collisions {collisions(oracle.scene)}", *custom.describe(oracle.scene)]
            held = oracle.scene.position_map.held if oracle.scene.position_map else {}
            lines.append(
                f"moveit    group {problem.group or '(every joint)'}: {', '.join(oracle.scene.coordinate_names)}"
                + (f"; held: {', '.join(held)}" if held else "")
            )
            print("\n".join([summary(result, oracle.scene), *("  " + line for line in lines)]))
    view.wait(args, viewer)
    return 0


def _request_settings(args, settings: PlanSettings, problem) -> PlanSettings:
    """The request's scaling factors for the scaling flags (given both ways only when they agree), and its allowed
    planning time as the budget's time limit (the budget's own when that is shorter)."""
    scales = {}
    for kind in ("velocity", "acceleration"):
        flag, asked = getattr(args, f"{kind}_scale"), getattr(problem, f"{kind}_scale")
        if flag != 1.0 and asked != 1.0 and flag != asked:
            raise UserError(f"--{kind}-scale {flag:g} and the request's max_{kind}_scaling_factor {asked:g} differ")
        scales[f"{kind}_scale"] = min(flag, asked)
    budget = settings.budget
    if problem.seconds is not None:
        seconds = problem.seconds if budget.seconds is None else min(budget.seconds, problem.seconds)
        budget = Budget(seconds=seconds, checks=budget.checks)
    return dataclasses.replace(settings, budget=budget, **scales)


@contextlib.contextmanager
def _failure_response(args, problem):
    """With --moveit-out, a failure inside the block is answered in the file too, with MoveIt's error code for it
    (`problem()`: the problem once read; before, the start is unknown and the group the request's, if readable)."""
    try:
        yield
    except UserError as exc:
        if args.moveit_out:
            known = problem()
            details = getattr(exc, "details", None) or {}
            seconds = (details.get("seconds") or {}).get("total", 0.0)
            if known is not None:
                answer = moveit.response(known, planning_time=seconds, code=exc.code)
            else:
                answer = moveit.response({}, _group_named(args.moveit_request), code=exc.code)
            with answering(final=False):  # (not announced: a failure is its one line)
                moveit.write_response(args.moveit_out, answer)
        raise


def _group_named(request: str) -> str:
    with contextlib.suppress(UserError):
        return moveit_messages.read_message(request, moveit_messages.MotionPlanRequest, "MoveIt request").group_name
    return ""


def pose(text: str) -> list[float]:
    values = float_list(text)
    if len(values) != 6:
        raise argparse.ArgumentTypeError(f"needs 6 numbers x,y,z,roll,pitch,yaw, got {len(values)}: {text!r}")
    return values


TOOL_CHOSEN = {
    "tool": "--tool",
    "scene": "the scene's tool frame",
    "last_body": "the robot's last body; --tool FRAME picks another",
}


def tool_frame(oracle, name: str | None) -> dict:
    """The frame --start-pose/--goal-pose place, and how it was chosen (a key of TOOL_CHOSEN): {"name", "chosen"}."""
    frame = robot_frame(oracle, name)
    chosen = "tool" if name else "scene" if oracle.scene.tool_frame is not None else "last_body"
    return {"name": frame.name(), "chosen": chosen}


def scene_details(scene) -> dict:
    """What a custom scene's loading took, for the answer (success or failure): `meshes`, its mesh decompositions
    (one per mesh: method, pieces, volume added, seconds, cached or not), and `scene_seconds`, preparing the scene
    (decompositions included) and Drake's load of it. Nothing for a shipped scene."""
    if not isinstance(scene, custom.CustomScene):
        return {}
    info = scene.info
    seconds = {"prepare": info.get("prepare_seconds"), "drake_load": info.get("drake_load_seconds")}
    return {"meshes": info["decompositions"], "scene_seconds": seconds}


def certificate_scope(scene) -> dict:
    """What `certified` covers, beside it in the JSON answer: self_collision (whether the robot's collisions with
    itself were counted at all) and certified_collisions: "all" (robot vs environment and itself, or a robot of
    one rigid body, which cannot collide with itself) or "environment" (robot vs environment only: a motion through
    the arm itself may be certified)."""
    return {
        "self_collision": scene.self_collisions,
        "certified_collisions": "all" if scene.self_collisions or scene.one_body else "environment",
    }


def collisions(scene) -> str:
    if scene.one_body:
        return "robot vs environment (the robot is one rigid body)"
    if not scene.self_collisions:
        return "robot vs environment only (self-collision off)"
    text = f"robot vs environment and itself ({len(scene.disabled_pairs)} SRDF pairs left out"
    allowed = getattr(scene, "allowed_collisions", [])  # (a user's own checker's scene has none)
    if allowed:
        text += f"; {len(allowed)} allowed-collision pairs"
    adjacent = getattr(scene, "adjacent_pairs", [])
    if adjacent:  # Drake leaves out a joint's parent and child; these meet at a joint across a link without geometry
        named = ", ".join(f"{a}-{b}" for a, b in adjacent[:3]) + (" ..." if len(adjacent) > 3 else "")
        text += f"; {len(adjacent)} adjacent across links without collision geometry: {named}"
    text += ")"
    links = getattr(scene, "info", {}).get("mesh_links")  # a custom robot's decomposed mesh links
    if links:
        text += (
            f"; mesh links decomposed: {links['pieces_self_collision']:.0%} of {links['samples']} random "
            f"configurations collide with the robot itself, {links['hull_self_collision']:.0%} with hulls"
        )
    return text


def summary(r, scene) -> str:
    m, s, t = r.stats.roadmap, r.stats.seconds, r.trajectory
    scope = "" if scene.self_collisions or scene.one_body else "; self-collision not checked"
    edges = (
        f"{m.edges} candidate edges, {m.edges_tried} checked when a search used them (lazy)"
        if m.lazy
        else f"{m.edges} edges, {m.components} components, {m.edges_tried} edges tried"
    )
    lines = [
        f"plan {r.scene}: path found with {r.sampler} (seed {r.seed}, step {r.step:g})",
        f"  roadmap   {m.nodes} nodes ({m.narrow_nodes} {r.sampler}, {m.workspace_nodes} in workspace gaps, "
        f"{m.uniform_nodes} uniform), {edges}, {r.stats.rounds} round(s)",
        f"  path      {len(r.roadmap_path)} roadmap nodes ({r.narrow_on_path} from {r.sampler}, "
        f"{r.workspace_on_path} from workspace gaps), length "
        f"{r.smoothing.raw_length:.1f} -> {len(r.path)} waypoints, length {r.smoothing.length_after:.1f} "
        f"after smoothing",
        f"  motion    {t.duration:.2f} s trajectory, {len(t.times)} samples, corners blended, "
        + (
            f"certified to keep {t.clearance:g} from everything (continuous{scope}); "
            "the lines between its samples and the waypoints keep half that"
            if t.certified
            else f"NOT certified: fine-checked only{scope}"
        ),
        f"  cost      {r.collision_checks} collision checks + {r.stats.distance_queries} distance queries "
        f"+ {r.stats.point_queries} point queries, "
        f"{s.total:.2f} s (sampling {s.sampling:.2f}, roadmap {s.roadmap:.2f}, search {s.search:.2f}, "
        f"smoothing {s.smoothing:.2f}, certify {s.certify:.2f}, timing {s.timing:.2f})",
    ]
    return "\n".join(lines)
