"""Stage (e): the configuration space derived, in numpy alone (no Drake).

For a Scene (`derive_space`): from its plant's joints (app.scene.build.joint_table) and its problem file, the planned
coordinates (mimic joints left out), their bounds (a continuous angle wraps), weights, start and goal, the edge-check
step and sampler step, and the speed and acceleration limits, every one checked, with messages naming the scene.

For a custom scene (`custom_problem`): the keys of the problem file it writes, from the robot as Drake measured it
alone (app.scene.build.measure_robot) and the inputs: start and goal (default: the home), bounds (the joints'
limits, for a floating robot the environment's box grown by its reach), weights (an angle's is the robot's reach),
the model's velocity limits and the edge-check step.
"""

import math
from dataclasses import dataclass

import numpy as np

from app.errors import UserError
from app.scene.cspace import ConfigurationSpace, PositionMap
from app.scene.spec import CustomSpec, SceneInputs, check_bounds_count, check_vector

MIN_RESOLUTION = 1e-5  # the finest edge-check step, as a fraction of the weighted diagonal of the bounds


@dataclass
class SceneSpace:
    """A scene's configuration space as its problem file and plant define it."""

    position_map: PositionMap | None  # mimic and held joints, or None
    joint_names: list[str]  # every position's, mimic and held joints' included: what a trajectory carries
    coordinate_names: list[str]
    angular: np.ndarray
    continuous: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    weights: np.ndarray
    start: np.ndarray
    goal: np.ndarray
    resolution: float
    step: float | None
    velocity_limits: np.ndarray
    acceleration_limits: np.ndarray

    @property
    def dim(self) -> int:
        return len(self.coordinate_names)


def derive_space(table: dict, problem, bad: str) -> SceneSpace:
    """The space of a plant's positions (`table`: names, angular, lower, upper, velocity per position) and a problem
    file (app.scene.problem.ProblemFile). `bad` starts every refusal ("bad scene file NAME")."""
    names = table["names"]
    try:
        position_map = PositionMap.of(
            names, [(m.joint, m.follows, m.multiplier, m.offset) for m in problem.mimic], problem.hold
        )
        if position_map is not None:
            position_map.check_held(table["lower"], table["upper"])
    except UserError as exc:
        raise UserError(f"{bad}: {exc}") from None
    # Per plant position first; the planned coordinates are the positions of joints that mimic none.
    planned = position_map.planned if position_map else np.arange(len(names))
    coordinates = [names[i] for i in planned]
    angular = table["angular"][planned]

    def vector(key: str, values: list[float], default: "np.ndarray | None") -> np.ndarray:
        return _vector(key, values, default, len(planned), bad)

    lower, upper, continuous = _bounds(table, planned, angular, position_map, problem, vector, bad)
    weights = vector("weights", problem.weights, np.ones(len(planned)))
    if np.any(weights <= 0):
        raise UserError(f"{bad}: weights must be positive")
    start = vector("start", problem.start, None)
    goal = vector("goal", problem.goal, None)
    resolution = _resolution(problem.resolution, lower, upper, weights, bad)
    space = ConfigurationSpace(lower, upper, weights, angular, continuous, resolution, coordinates)
    step = _step(problem.step, space, bad)
    model_velocity = table["velocity"]
    velocity = vector("velocity_limits", problem.velocity_limits, model_velocity[planned])
    if position_map:  # a mimic joint moves |multiplier| times as fast as its coordinate
        velocity = np.minimum(velocity, position_map.coordinate_speeds(model_velocity))
    acceleration = vector("acceleration_limits", problem.acceleration_limits, 2.0 * velocity)
    for key, limits in (("velocity_limits", velocity), ("acceleration_limits", acceleration)):
        if np.any(limits <= 0):  # refused now, not after a plan has been found
            i = int(np.flatnonzero(limits <= 0)[0])
            raise UserError(f"{bad}: '{key}' must be positive, item {i + 1} ({coordinates[i]}) is {limits[i]:g}")
    return SceneSpace(
        position_map, names, coordinates, angular, continuous, lower, upper, weights, start, goal, resolution, step,
        velocity, acceleration,
    )  # fmt: skip


def _bounds(table: dict, planned, angular, position_map, problem, vector, bad: str) -> tuple:
    """Lower and upper bounds (the problem file's, else the joints' limits; a mimicked coordinate's kept so that its
    mimic joints stay within theirs) and which coordinates are continuous: angles with no limit, which wrap."""
    position_lower, position_upper = table["lower"], table["upper"]
    model_lower, model_upper = position_lower[planned], position_upper[planned]
    # An angle with no joint limit wraps: it lives on a circle, and the metric takes the short way round.
    continuous = angular & ~np.isfinite(model_lower) & ~np.isfinite(model_upper)
    model_lower = np.where(continuous, -math.pi, model_lower)
    model_upper = np.where(continuous, math.pi, model_upper)
    mimic_lower, mimic_upper = (
        position_map.coordinate_limits(position_lower, position_upper) if position_map else (-np.inf, np.inf)
    )
    # A mimicked coordinate's bounds keep its mimic joints within their limits (a limited coordinate: no wrap).
    continuous &= ~np.isfinite(mimic_lower) & ~np.isfinite(mimic_upper)
    lower = np.maximum(vector("lower", problem.lower, model_lower), mimic_lower)
    upper = np.minimum(vector("upper", problem.upper, model_upper), mimic_upper)
    if not np.all(np.isfinite(lower) & np.isfinite(upper)) or np.any(lower >= upper):
        raise UserError(f"{bad}: bounds must be finite with lower < upper")
    return lower, upper, continuous


def _resolution(resolution: float, lower, upper, weights, bad: str) -> float:
    """Edges are checked at points this far apart: a finer step makes an edge check of millions of points, one
    longer than the bounds' weighted diagonal checks every edge at its two ends only."""
    diagonal = float(np.linalg.norm((upper - lower) * weights))
    if not (math.isfinite(resolution) and MIN_RESOLUTION * diagonal <= resolution <= diagonal):
        raise UserError(
            f"{bad}: resolution must be from {MIN_RESOLUTION:g} x the bounds' diagonal "
            f"({MIN_RESOLUTION * diagonal:.3g}) to the diagonal ({diagonal:.3g}), got {resolution:g}"
        )
    return float(resolution)


def _step(step: float, space: ConfigurationSpace, bad: str) -> float | None:
    """The scene's sampler step (None: the sampler's default)."""
    if not (step >= 0 and math.isfinite(step)):
        raise UserError(f"{bad}: step must be a non-negative number")
    if not step:
        return None
    try:
        space.check_step(float(step))
    except UserError as exc:
        raise UserError(f"{bad}: {exc}") from None
    return float(step)


def _vector(key: str, values: list[float], default: "np.ndarray | None", dim: int, bad: str) -> np.ndarray:
    if not values:
        if default is None:
            raise UserError(f"{bad}: '{key}' is required")
        return np.asarray(default, float).copy()
    vector = np.asarray(values, float)
    if vector.shape != (dim,):
        raise UserError(f"{bad}: '{key}' needs {dim} numbers, got {len(values)}")
    if not np.all(np.isfinite(vector)):
        i = int(np.flatnonzero(~np.isfinite(vector))[0])
        raise UserError(f"{bad}: '{key}' needs finite numbers, item {i + 1} is {vector[i]}")
    return vector


def passage_boxes(problem, bad: str) -> list[tuple[np.ndarray, np.ndarray]]:
    """The problem file's passage boxes as (lo, hi) 3-vectors, each finite with lo <= hi."""
    try:
        boxes = [(np.array(b.lo, float).reshape(3), np.array(b.hi, float).reshape(3)) for b in problem.passage.boxes]
    except ValueError:
        raise UserError(f"{bad}: passage boxes need 3-vectors lo and hi") from None
    for k, (lo, hi) in enumerate(boxes):
        if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)) and np.all(lo <= hi)):
            raise UserError(
                f"{bad}: passage box {k + 1} needs finite lo <= hi, got lo {lo.tolist()} and hi {hi.tolist()}"
            )
    return boxes


# ---- a custom scene's problem file ---------------------------------------------------------------------------------
def custom_problem(
    spec: CustomSpec,
    inputs: SceneInputs,
    robot,
    robot_instances: list[str],
    env_boxes: list[tuple[np.ndarray, np.ndarray]],
    resolution: float,
) -> dict:
    """The problem file's keys: start, goal, limits and weights from the robot measured alone
    (app.scene.build.RobotMeasure), and the edge-check step."""
    names = robot.names
    nq = len(names)
    angular = np.array([k == "revolute" for k in robot.kinds])
    home = np.zeros(nq)
    start = check_vector(spec.start, nq, "start", names) if spec.start else home
    goal = check_vector(spec.goal, nq, "goal", names) if spec.goal else home
    lower, upper = _custom_limits(robot, angular, inputs, start, goal, env_boxes)
    start = start if spec.start else np.clip(home, lower, upper)
    goal = goal if spec.goal else np.clip(home, lower, upper)
    # Weights: an angle's weight is the lever arm it swings (the robot's radius or reach), metres weigh 1.
    weights = np.where(angular, max(robot.reach, 1e-6), 1.0)
    _check_custom_resolution(resolution, lower, upper, weights)
    env_names = ", ".join(p.name for p in inputs.env_paths) or "-"
    # A joint without a velocity limit gets 1 (m/s or rad/s), so the trajectory has a sensible duration.
    model_velocity = np.where(np.isfinite(robot.velocity) & (robot.velocity > 0), robot.velocity, 1.0)
    return {
        "description": spec.description or f"{inputs.robot_path.name} among {env_names}",
        "directives": "scene.dmd.yaml",
        "robot": robot_instances,
        "collisions": spec.collisions,
        "srdf": str(inputs.srdf_path or ""),
        "lower": lower.tolist(),
        "upper": upper.tolist(),
        "start": start.tolist(),
        "goal": goal.tolist(),
        "weights": weights.tolist(),
        "resolution": float(resolution),
        "view": "3d",
        "velocity_limits": model_velocity.tolist(),
        "mimic": robot.mimic,
        "hold": dict(spec.hold),
        "allowed_collisions": [list(pair) for pair in spec.allowed_collisions],
        **_given_limits(spec, names),  # the Scene's default accelerations: twice its velocity limits
    }


def _check_custom_resolution(resolution: float, lower, upper, weights) -> None:
    """As derive_space checks it: here, so that the message names the value, not a generated file."""
    with np.errstate(over="ignore", invalid="ignore"):
        diagonal = float(np.linalg.norm((upper - lower) * weights))
    if not math.isfinite(diagonal):
        raise UserError("the bounds are too large to plan in: their diagonal is not a finite number (give bounds)")
    if not MIN_RESOLUTION * diagonal <= resolution <= diagonal:
        raise UserError(
            f"resolution must be from {MIN_RESOLUTION:g} x the bounds' diagonal ({MIN_RESOLUTION * diagonal:.3g}) to "
            f"the diagonal ({diagonal:.3g}), got {resolution:g}"
        )


def _given_limits(spec: CustomSpec, names: list[str]) -> dict:
    """The velocity and acceleration limits the spec gives, each one positive number per coordinate."""
    limits = {}
    for key, given in (("velocity_limits", spec.velocity_limits), ("acceleration_limits", spec.acceleration_limits)):
        if given:
            limits[key] = check_vector(given, len(names), key, names)
            if not np.all(limits[key] > 0):
                raise UserError(f"{key} must be positive numbers")
            limits[key] = limits[key].tolist()
    return limits


def _custom_limits(
    robot,
    angular: np.ndarray,
    inputs: SceneInputs,
    start: np.ndarray,
    goal: np.ndarray,
    env_boxes: list[tuple[np.ndarray, np.ndarray]],
) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper limits: the given bounds, else the joints' own (angles without any: one turn); a floating robot's
    x, y, z default to the environment's box grown by the robot's reach and stretched to hold start and goal."""
    names = robot.names
    nq = len(names)
    floating, bounds = inputs.floating, inputs.bounds
    lower = np.where(np.isfinite(robot.lower), robot.lower, -math.pi)
    upper = np.where(np.isfinite(robot.upper), robot.upper, math.pi)
    lower = np.where(angular | np.isfinite(robot.lower), lower, np.nan)
    upper = np.where(angular | np.isfinite(robot.upper), upper, np.nan)
    if floating:
        lower[:3], upper[:3] = -1e4, 1e4
        lower[3:6], upper[3:6] = -math.pi, math.pi
    if bounds:
        check_bounds_count(bounds, names, floating)
        if len(bounds) == nq:
            lower, upper = np.array([b[0] for b in bounds]), np.array([b[1] for b in bounds])
        else:
            lower[:3], upper[:3] = [b[0] for b in bounds], [b[1] for b in bounds]
    elif floating:
        if not env_boxes:
            raise UserError("a floating robot with no environment needs bounds for x, y, z")
        margin = robot.reach
        env_lo = np.min([lo for lo, _ in env_boxes], axis=0)
        env_hi = np.max([hi for _, hi in env_boxes], axis=0)
        lower[:3] = np.minimum(env_lo - margin, np.minimum(start[:3], goal[:3]))
        upper[:3] = np.maximum(env_hi + margin, np.maximum(start[:3], goal[:3]))
    if not np.all(np.isfinite(lower) & np.isfinite(upper)):
        missing = [names[i] for i in range(nq) if not (np.isfinite(lower[i]) and np.isfinite(upper[i]))]
        raise UserError(f"no limits for {', '.join(missing)}: give bounds")
    if np.any(lower >= upper):
        i = int(np.flatnonzero(lower >= upper)[0])
        raise UserError(
            f"{inputs.robot_path.name}: joint '{names[i]}': lower limit {lower[i]:g} is not below upper "
            f"limit {upper[i]:g}, no room to move (give bounds)"
        )
    return lower, upper
