"""Inverse kinematics: a tool pose -> a collision-free configuration of the scene's robot.

Drake's `InverseKinematics` on the oracle's own plant (one new context per call, never a second diagram): the tool
frame's origin within `position_tolerance` of the pose's position (a box inside that ball), its orientation within
`angle_tolerance` (both tightened by 10 % inside the program to leave room for SNOPT's feasibility tolerance), and a
small weighted quadratic cost towards the reference configuration. Translations are bounded by the scene; angles are
not (SNOPT converges far more often without those bounds), and a solution's angles are shifted by whole
turns into the scene's bounds afterwards, which leaves the kinematics unchanged. SNOPT runs from several seeds: the
reference first, then configurations drawn uniformly from the bounds with the caller's rng. A solution counts only if
forward kinematics confirms the pose and the oracle says it is free; the first `keep` (6) such solutions are compared
and the one nearest the reference (in the scene's weighted metric) wins (comparing fewer let an odd, backward-reaching
posture through: benchmark pages, "Tuning notes"). If every solution found collides, a second round adds Drake's
minimum-distance constraint (every counted collision pair at least `clearance` apart), seeded with those colliding
solutions, so the solver itself pushes them clear. Nothing free: `InvalidEndpoint` naming the pose.

An unreachable pose fails fast; a pose reachable only in collision costs the minimum-distance round (timings on the
benchmark pages).

IK is set-up work, not planning: it takes the shared oracle and its collision answers are not counted in any query.
"""

from __future__ import annotations

import contextlib
import math
from typing import NamedTuple

import numpy as np

from app.errors import InvalidEndpoint, UserError

# pydrake is imported inside the functions that use it, so that importing the package does not load Drake.

POSITION_TOLERANCE = 1e-3  # m
ANGLE_TOLERANCE = math.radians(0.5)
CLEARANCE = 0.005  # m, the second round's minimum distance
# A tool line is solved every TOOL_STEP metres of tool travel or TOOL_TURN radians of its turn, whichever is finer;
# consecutive solutions further apart than JUMP x the step in the scene metric are a jump (its lever arms are upper
# bounds, so a step of the tool measures a few times its length there, a change of arm posture far more). The step
# is short so that the tool keeps to its line: a longer one saved no job time (benchmark pages, "Tuning notes").
TOOL_STEP, TOOL_TURN, JUMP = 0.02, math.radians(10.0), 10.0
# distinct_solutions: random references it solves from besides the caller's, and how near (scene metric) two
# solutions are the same one.
REFERENCES, DISTINCT = 6, 0.05


def pose_error(oracle, q, pose, frame=None) -> tuple[float, float]:
    """(position error in m, rotation error in rad) of the tool frame at q against `pose` (a RigidTransform)."""
    X = tool_pose(oracle, q, frame)
    position = float(np.linalg.norm(X.translation() - pose.translation()))
    R = pose.rotation().inverse().multiply(X.rotation())
    angle = float(R.ToAngleAxis().angle())
    return position, angle


def _pose(oracle, pose):
    """(label, RigidTransform) from a pose name of the scene or a RigidTransform."""
    if isinstance(pose, str):
        if pose not in oracle.scene.poses:
            known = ", ".join(oracle.scene.poses) or "none"
            raise UserError(f"unknown pose '{pose}' in scene {oracle.scene.name} (known: {known})")
        return pose, oracle.scene.poses[pose]
    p = pose.translation()
    return f"[{p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}]", pose


def _into_bounds(oracle, q) -> np.ndarray:
    """Each angle shifted by whole turns to its first value at or above its lower bound (kinematically the same
    configuration); continuous angles wrapped as the oracle wraps them."""
    q = np.array(q, float)
    turn = 2 * math.pi
    limited = oracle.space.angular & ~oracle.space.continuous
    q[limited] = oracle.space.lower[limited] + np.mod(q[limited] - oracle.space.lower[limited], turn)
    return oracle.space.wrap(q)


def solve_pose(
    oracle,
    pose,
    rng: np.random.Generator,
    reference=None,
    *,
    frame=None,
    label: str | None = None,
    seeds: int = 64,
    keep: int = 6,
    position_tolerance: float = POSITION_TOLERANCE,
    angle_tolerance: float = ANGLE_TOLERANCE,
    clearance: float = CLEARANCE,
    every: bool = False,
) -> np.ndarray:
    """A free configuration putting `frame` (default: the scene's tool frame) at `pose` (a pose name of the scene or
    a RigidTransform in the world), the nearest to `reference` (default: the scene's start) among the first `keep`
    found; with `every`, all the distinct ones found, nearest first, (k, dim): goals a planner may reach any of.
    `label` names the pose in errors. Raises InvalidEndpoint if no seed gives one."""
    default_label, X_WT = _pose(oracle, pose)
    label = label or default_label
    scene = oracle.scene
    frame = frame or scene.tool_frame
    if frame is None:
        raise UserError(f"scene {scene.name} names no tool frame, so it has no tool poses to reach")
    reference = scene.start if reference is None else oracle.space.check_configuration(reference, "reference")
    target = _Target(X_WT, frame, reference, position_tolerance, angle_tolerance, clearance)

    def attempt(seed_list, with_clearance: bool, colliding: list) -> list[np.ndarray]:
        return _solutions(oracle, target, seed_list, with_clearance, keep, colliding)

    colliding: list[np.ndarray] = []
    first = [reference] + [rng.uniform(oracle.space.lower, oracle.space.upper) for _ in range(seeds - 1)]
    found = attempt(first, False, colliding)
    if not found and colliding:
        # The pose is reachable but every solution found collides: push those (and a few fresh seeds) clear.
        second = colliding[:keep] + [rng.uniform(oracle.space.lower, oracle.space.upper) for _ in range(seeds // 16)]
        found = attempt(second, True, [])
    if not found:
        raise InvalidEndpoint(
            f"pose '{label}' cannot be reached collision-free by {frame.name()} "
            f"(tolerance {position_tolerance * 1000:g} mm, {math.degrees(angle_tolerance):g} deg)",
            "NO_IK_SOLUTION",
        )
    found.sort(key=lambda c: float(oracle.space.distance(reference, c)))
    if not every:
        return found[0]
    # Seeds that converge to the same posture give the same goal twice; one of them is enough.
    distinct = []
    for q in found:
        if all(oracle.space.distance(q, other) > oracle.space.resolution for other in distinct):
            distinct.append(q)
    return np.array(distinct)


def distinct_solutions(
    oracle,
    pose,
    rng: np.random.Generator,
    reference,
    *,
    known=(),
    posture=None,
    references: int = REFERENCES,
    distinct: float = DISTINCT,
) -> np.ndarray:
    """Distinct free solutions of `pose` from several postures (k, dim), the one nearest `reference` first: where
    `solve_pose(..., every=True)` keeps what one search from one reference finds, this also starts from random
    references, for other branches of the arm's IK (a work cell's goals, any of which will do). `solve_pose` from
    the reference (16 seeds), then from `references` random ones (2 seeds each; one solution per call), plus `known`
    solutions; one closer than `distinct` (scene metric) to a solution kept is the same. With `posture`, first the
    solution SNOPT reaches from that posture, and none at all when it reaches none. Empty when none is found."""
    found = [np.asarray(q, float) for q in known]
    if posture is not None:
        try:
            found.append(solve_pose(oracle, pose, rng, posture, seeds=1, keep=1))
        except InvalidEndpoint:
            return np.empty((0, oracle.space.dim))
    starts = [reference] + list(oracle.space.uniform(rng, references))
    for k, ref in enumerate(starts):
        try:
            q = solve_pose(oracle, pose, rng, ref, seeds=16 if k == 0 else 2, keep=1 if k else 6)
        except InvalidEndpoint:
            if k == 0 and not found:
                return np.empty((0, oracle.space.dim))  # not reachable from 16 seeds: not worth the others
            continue
        if all(oracle.space.distance(q, other) > distinct for other in found):
            found.append(q)
    if not found:
        return np.empty((0, oracle.space.dim))
    found.sort(key=lambda q: float(oracle.space.distance(reference, q)))
    return np.array(found)


def tool_pose(oracle, q, frame=None):
    """The pose (a RigidTransform) of `frame` (default: the scene's tool frame) in the world at configuration q."""
    plant = oracle.plant
    context = plant.CreateDefaultContext()
    plant.SetPositions(context, oracle.scene.positions(np.asarray(q, float)))
    return (frame or oracle.scene.tool_frame).CalcPoseInWorld(context)


def tool_line(oracle, qa, qb, rng: np.random.Generator, *, frame=None, step: float = TOOL_STEP) -> np.ndarray | None:
    """Configurations between qa and qb that carry the tool frame along the straight line (and the shortest turn)
    from its pose at qa to its pose at qb, every `step` metres (or TOOL_TURN radians), each solved from the one before
    so the arm keeps its posture: what a cell's linear move does (MoveIt's Cartesian path). None when a pose on the
    way has no free solution near the last one, or the arm would have to jump (a branch change, more than
    JUMP x the step in the scene's metric) to go on or to reach qb."""
    from pydrake.math import RigidTransform, RotationMatrix

    Xa, Xb = tool_pose(oracle, qa, frame), tool_pose(oracle, qb, frame)
    qa_rot, qb_rot = Xa.rotation().ToQuaternion(), Xb.rotation().ToQuaternion()
    turn = Xa.rotation().inverse().multiply(Xb.rotation()).ToAngleAxis().angle()
    distance = float(np.linalg.norm(Xb.translation() - Xa.translation()))
    n = max(1, math.ceil(distance / step), math.ceil(turn / TOOL_TURN))
    jump = JUMP * max(distance, turn * step / TOOL_TURN) / n
    q, out = np.asarray(qa, float), []
    for k in range(1, n):
        t = k / n
        X = RigidTransform(RotationMatrix(qa_rot.slerp(t, qb_rot)), (1 - t) * Xa.translation() + t * Xb.translation())
        try:
            nxt = solve_pose(oracle, X, rng, q, frame=frame, seeds=1, keep=1)
        except InvalidEndpoint:
            return None
        if oracle.space.distance(q, nxt) > jump:
            return None
        out.append(nxt)
        q = nxt
    if oracle.space.distance(q, qb) > jump:
        return None
    return np.array(out).reshape(-1, oracle.space.dim)


class _Target(NamedTuple):
    """What solve_pose asks of IK: the frame at the pose X_WT, within the tolerances, near `reference`, and (when
    its solutions collide) this far from everything."""

    X_WT: object
    frame: object
    reference: np.ndarray
    position_tolerance: float
    angle_tolerance: float
    clearance: float


def _solutions(oracle, target: _Target, seed_list, with_clearance: bool, keep: int, colliding: list) -> list:
    """Up to `keep` free configurations in bounds that put the target's frame at its pose, solved from each seed of
    `seed_list` in turn; those that solve but collide go to `colliding`."""
    from pydrake.solvers import Solve

    scene, prog, q = oracle.scene, *_program(oracle, target, with_clearance)
    found = []
    for seed in seed_list:
        result = Solve(prog, scene.positions(seed))
        if not result.is_success():
            continue
        candidate = _into_bounds(oracle, result.GetSolution(q))
        position, angle = pose_error(oracle, candidate, target.X_WT, target.frame)
        if position > target.position_tolerance or angle > target.angle_tolerance:
            continue
        # Touching counts as colliding: no motion out of a contact can be certified (endpoints.check_endpoint).
        inside = oracle.space.within_bounds(candidate)[0]
        if inside and oracle.free(candidate) and not oracle.diagnostics.touching(candidate):
            found.append(candidate)
            if len(found) >= keep:
                break
        else:
            colliding.append(candidate)
    return found


def _program(oracle, target: _Target, with_clearance: bool):
    """(the IK program, its coordinates' decision variables) for the target, on a context of the scene's policy."""
    from pydrake.math import RotationMatrix
    from pydrake.multibody.inverse_kinematics import InverseKinematics

    plant, mimic = oracle.plant, oracle.scene.position_map
    context = plant.GetMyMutableContextFromRoot(oracle.policy_context())
    ik = InverseKinematics(plant, context, with_joint_limits=False)
    positions = ik.q()  # the plant's: mimic joints' positions are bound to their coordinates' below
    q = positions if mimic is None else positions[mimic.planned]
    prog = ik.get_mutable_prog()
    if mimic is not None:
        prog.AddLinearEqualityConstraint(*mimic.equalities(), positions)
    p = target.X_WT.translation()
    # A box inside the tolerance ball and a tighter angle, leaving room for SNOPT's feasibility tolerance.
    half = 0.9 * target.position_tolerance / math.sqrt(3.0)
    frame = target.frame
    ik.AddPositionConstraint(
        frameB=frame, p_BQ=np.zeros(3), frameA=plant.world_frame(), p_AQ_lower=p - half, p_AQ_upper=p + half
    )
    ik.AddOrientationConstraint(
        frameAbar=plant.world_frame(),
        R_AbarA=target.X_WT.rotation(),
        frameBbar=frame,
        R_BbarB=RotationMatrix(),
        theta_bound=0.9 * target.angle_tolerance,
    )
    # Translations are bounded; angles are not (SNOPT converges far more often without them): a revolute
    # joint's kinematics repeat every 2 pi, so a solution is shifted into the bounds afterwards.
    space = oracle.space
    prog.AddBoundingBoxConstraint(
        np.where(space.angular, -np.inf, space.lower), np.where(space.angular, np.inf, space.upper), q
    )
    # Small, so it picks among nearby solutions without fighting the constraints.
    prog.AddQuadraticErrorCost(1e-2 * np.diag(space.weights**2), target.reference, q)
    if with_clearance:
        ik.AddMinimumDistanceLowerBoundConstraint(target.clearance, 0.05)
    return prog, q


def solve_poses(oracle, rng: np.random.Generator, names=None, reference=None, **options) -> dict[str, np.ndarray]:
    """Configurations for the scene's poses (default: all, in file order) that form a chain: a forward pass solves
    the first pose nearest `reference` (a full solve) and each next one from the previous solution's posture (one
    local solve: the solution SNOPT reaches from there; a full solve if that fails); a backward pass then solves each
    pose again from its successor's posture and keeps whichever of the two is nearer that successor, so an odd arm
    posture picked for the first pose does not survive when the rest of the sequence (a weld seam, say) settled on
    another. (Full solves in place of the local ones give the same postures, slower: benchmark pages, "Tuning
    notes".)"""
    names = list(oracle.scene.poses) if names is None else list(names)
    chain = []
    local = {**options, "seeds": 1, "keep": 1}
    for name in names:
        found = None
        if chain:
            with contextlib.suppress(InvalidEndpoint):
                found = solve_pose(oracle, name, rng, reference, **local)
        reference = found if found is not None else solve_pose(oracle, name, rng, reference, **options)
        chain.append(reference)
    for i in range(len(chain) - 2, -1, -1):
        try:
            again = solve_pose(oracle, names[i], rng, chain[i + 1], **local)
        except InvalidEndpoint:
            continue
        if oracle.space.distance(again, chain[i + 1]) < oracle.space.distance(chain[i], chain[i + 1]):
            chain[i] = again
    return dict(zip(names, chain))


def robot_frame(oracle, name: str | None = None):
    """The robot's frame `name`; without a name the scene's tool frame, else the robot's last body: the one with
    the most joints between it and the world (the tip of the kinematic chain; the latest in the model on a tie)."""
    plant, scene = oracle.plant, oracle.scene
    bodies = [plant.get_body(b) for instance in scene.robot_instances for b in plant.GetBodyIndices(instance)]
    if name:
        frames = [plant.GetFrameByName(name, i) for i in scene.robot_instances if plant.HasFrameNamed(name, i)]
        if not frames:
            raise UserError(f"unknown tool frame '{name}' (robot bodies: {', '.join(b.name() for b in bodies)})")
        return frames[0]
    if scene.tool_frame is not None:
        return scene.tool_frame
    parent = {}
    for index in plant.GetJointIndices():
        joint = plant.get_joint(index)
        parent[joint.child_body().index()] = joint.parent_body().index()

    def depth(body) -> int:
        index, count = body.index(), 0
        while index in parent:
            index, count = parent[index], count + 1
        return count

    return max(reversed(bodies), key=depth).body_frame()


def pose_goal(
    oracle, values, *, tool: str | None = None, reference=None, seed: int = 0, every: bool = False
) -> np.ndarray:
    """A free configuration putting the robot's `tool` frame (see robot_frame) at the world pose `values`:
    x, y, z in metres, roll, pitch, yaw in degrees (R = Rz(yaw) Ry(pitch) Rx(roll)), the nearest to `reference`
    (default: the scene's start) of those found from several seeds; with `every`, all the distinct ones, nearest
    first (k, dim). Unreachable: InvalidEndpoint NO_IK_SOLUTION."""
    from pydrake.math import RigidTransform, RollPitchYaw

    values = np.asarray(values, float)
    if values.shape != (6,) or not np.all(np.isfinite(values)):
        raise UserError(f"a pose needs 6 finite numbers x,y,z (m), roll,pitch,yaw (deg); got {values.size}")
    pose = RigidTransform(RollPitchYaw(np.radians(values[3:])), values[:3])
    label = ",".join(f"{v:g}" for v in values)
    frame = robot_frame(oracle, tool)
    return solve_pose(oracle, pose, np.random.default_rng(seed), reference, frame=frame, label=label, every=every)
