"""OMPL on our collision oracle: state spaces, a validity checker, OMPL's planners, and valid-state samplers.

- `OmplSpace(cspace, wrap_angles)` is our configuration space as an OMPL state space, with states converted both
  ways. Linear coordinates and joint-limited angles are scaled by their metric weights, x = w*q, into one
  RealVectorStateSpace. With `wrap_angles` every continuous angle is an SO2StateSpace of its own (subspace weight =
  the angle's metric weight) beside it, in a CompoundStateSpace, so OMPL's motions take the short way round, as
  ours do. Without, the angles are intervals [-pi, pi] of the real-vector space: this only removes motions across
  +-pi, and it is what BIT* needs -- its informed sampler refuses compound spaces ("PathLengthDirectInfSampler only
  supports RealVector, SE2, SE3, ...").
- The two metrics are not the same function. OMPL's compound distance is the weighted *sum* of the subspaces'
  distances, sqrt(sum (w dx)^2) + sum_i w_i |dtheta_i|, where ours is the Euclidean norm over all coordinates:
  equal when one subspace moves, never smaller, and at most sqrt(1 + #angles) times larger. Straight motions
  (interpolation) are the same in both; what differs is which nodes OMPL calls nearest and its range. Path
  lengths are measured in our metric, whatever the planner.
- Motion checks no coarser than the scene's resolution r in our metric: `motion_check_steps` (the rule and its
  proof are there), applied by `OmplSpace.apply_motion_checks`; `motion_spacing` measures the spacing OMPL's motion
  validator really uses, on random edges.
- `OmplProblem(oracle, planner=...)` sets up OMPL's SimpleSetup with the oracle as validity checker (every check
  counted in the problem's own context, `problem.checker.checks`, like our own planner's), the scene's start and goal,
  and one of `PLANNERS`. Every planner gets a path-length objective whose cost threshold is infinite, so the optimising
  ones (PRM, BIT*) stop at their first solution, as RRTConnect and KPIECE1 do anyway.
- OMPL's Gaussian and bridge-test samplers are not bound in the Python wheel; `GaussianSampler` and
  `BridgeTestSampler` re-implement OMPL 2.0.1's algorithms as `ValidStateSampler` subclasses. `ProjectSampler`
  offers any of our samplers (lfbs, rbbs, ...) to OMPL's PRM: `problem.use_sampler("lfbs", step=10)`.

OMPL's RNG takes one seed per process (the first OmplProblem sets it): OMPL runs are not reproducible per seed.
States from `space.allocState()` are owned by the Python wrapper: never `freeState` them (a segfault follows).
"""

import math

import numpy as np

from app.errors import UserError
from app.samplers import make_sampler

# Importing this module loads OMPL (an optional dependency; the samplers below subclass its classes), so callers
# import it only where OMPL is needed.

# The planners the benchmark runs (all bound by OMPL 2.0.1's wheel); the ones that need a real-vector space.
PLANNERS = ("RRTConnect", "BITstar", "PRM", "KPIECE1")
REAL_VECTOR_ONLY = frozenset({"BITstar"})

_seeded = False


def ompl_modules():
    """OMPL's base, geometric and util modules, or one clear UserError when OMPL is not installed."""
    try:
        from ompl import base as ob
        from ompl import geometric as og
        from ompl import util as ou
    except ImportError:
        raise UserError("OMPL is not installed: pip install 'narrow-passage-planner[ompl]'") from None
    ou.setLogLevel(ou.LogLevel.LOG_WARN)
    return ob, og, ou


def motion_check_steps(extents, resolution: float) -> np.ndarray:
    """Each subspace's longest unchecked step, in our weighted metric, so that every motion's consecutive checked
    states are at most `resolution` (r) apart in that metric: l_c = r sqrt(e_c / sum e), e_c the subspaces'
    weighted extents.

    OMPL cuts a motion into n = max_c ceil(d_c / L_c) pieces (d_c, L_c: subspace c's distance and longest valid
    segment, in its own units; one subspace: the same with c alone), so a piece moves subspace c by at most L_c,
    which is l_c in our metric when L_c = l_c / weight_c. Our metric is the Euclidean norm over the subspaces, so a
    piece is at most sqrt(sum_c l_c^2) = r long. Steps growing with sqrt(e_c) keep a small subspace (a wrist
    angle) from being checked far finer than the motion needs, which steps proportional to e_c (what one fraction
    for every subspace amounts to) do (docs/benchmarks-history.md, "Side by side with OMPL")."""
    extents = np.asarray(extents, float)
    return resolution * np.sqrt(extents / extents.sum())


class OmplSpace:
    """Our ConfigurationSpace as an OMPL state space (see the module docstring), with states converted both ways."""

    def __init__(self, cspace, wrap_angles: bool = True):
        ob, _, _ = ompl_modules()
        self.cspace = cspace
        self.weights = np.asarray(cspace.weights, float)
        continuous = np.asarray(cspace.continuous, bool)
        self.compound = bool(wrap_angles and continuous.any())
        self.linear = np.flatnonzero(~continuous) if self.compound else np.arange(cspace.dim)
        self.angles = np.flatnonzero(continuous) if self.compound else np.arange(0)
        real = None
        if len(self.linear):
            real = ob.RealVectorStateSpace(len(self.linear))
            bounds = ob.RealVectorBounds(len(self.linear))
            for j, i in enumerate(self.linear):
                bounds.setLow(j, float(cspace.lower[i] * self.weights[i]))
                bounds.setHigh(j, float(cspace.upper[i] * self.weights[i]))
            real.setBounds(bounds)
        if not self.compound:
            self.space = real
            self.extents = [real.getMaximumExtent()]
            return
        self.space = ob.CompoundStateSpace()
        self.extents = []  # per subspace, in our weighted metric
        if real is not None:
            self.space.addSubspace(real, 1.0)
            self.extents.append(real.getMaximumExtent())
        for i in self.angles:
            so2 = ob.SO2StateSpace()
            self.space.addSubspace(so2, float(self.weights[i]))
            self.extents.append(float(self.weights[i]) * so2.getMaximumExtent())  # pi x weight
        # KPIECE1 needs a projection and a compound space has no default one: OMPL's default projection of the
        # first subspace (the real-vector one: the identity up to 2 dimensions, else a random linear map to 2).
        self._projection = ob.SubspaceProjectionEvaluator(self.space, 0)
        self.space.registerDefaultProjection(self._projection)
        self._real = 1 if real is not None else 0  # the first SO2 subspace's index

    @property
    def kind(self) -> str:
        return "compound" if self.compound else "real-vector"

    def fractions(self) -> np.ndarray:
        """Each subspace's longest valid segment as a fraction of its extent (what OMPL is told): the steps of
        `motion_check_steps` for the scene's resolution over the subspaces' weighted extents."""
        return motion_check_steps(self.extents, self.cspace.resolution) / np.asarray(self.extents)

    def apply_motion_checks(self, si) -> None:
        """Make `si`'s motion validator check at `fractions()`, before `si` is set up.

        `si.setStateValidityCheckingResolution(f)` gives a compound space's subspaces all the same fraction f (and
        each then checks at f x its own extent); it is given the smallest, and each subspace its own fraction
        after it. `si.setup()` keeps them (`segment_lengths` reads them back)."""
        fractions = self.fractions()
        si.setStateValidityCheckingResolution(float(fractions.min()))
        if self.compound:
            for c, fraction in enumerate(fractions):
                self.space.getSubspace(c).setLongestValidSegmentFraction(float(fraction))

    def segment_lengths(self) -> np.ndarray:
        """The longest valid segment OMPL uses per subspace, in our weighted metric (after set-up)."""
        if not self.compound:
            return np.array([self.space.getLongestValidSegmentLength()])
        return np.array(
            [
                self.space.getSubspace(c).getLongestValidSegmentLength() * self.space.getSubspaceWeight(c)
                for c in range(self.space.getSubspaceCount())
            ]
        )

    def write(self, state, q) -> None:
        q = self.cspace.wrap(np.asarray(q, float))  # continuous angles into [-pi, pi): in bounds either way
        if not self.compound:
            for i, v in enumerate(q * self.weights):
                state[i] = float(v)
            return
        if len(self.linear):
            real = state[0]
            for j, i in enumerate(self.linear):
                real[j] = float(q[i] * self.weights[i])
        for k, i in enumerate(self.angles):
            state[self._real + k].value = float(q[i])

    def state(self, q):
        state = self.space.allocState()  # owned by the wrapper: never freeState it
        self.write(state, q)
        return state

    def q(self, state) -> np.ndarray:
        """The configuration of an OMPL state. Scaled back from the weighted space and held to the bounds: a state on
        OMPL's bound (a goal at a joint limit) comes back up to a rounding outside ours, where our checker calls
        every configuration invalid."""
        q = np.empty(self.cspace.dim)
        if not self.compound:
            for i in range(self.cspace.dim):
                q[i] = state[i]
            return np.clip(q / self.weights, self.cspace.lower, self.cspace.upper)
        if len(self.linear):
            real = state[0]
            for j, i in enumerate(self.linear):
                q[i] = np.clip(real[j] / self.weights[i], self.cspace.lower[i], self.cspace.upper[i])
        for k, i in enumerate(self.angles):
            q[i] = state[self._real + k].value
        return q

    def for_oracle(self, path: np.ndarray) -> np.ndarray:
        """Waypoints whose short-way edges (our oracle's) are OMPL's motions between `path`'s states: the path
        itself in the compound space (SO2 takes the short way too), `straight_waypoints` in the real-vector one."""
        return np.array(path, float) if self.compound else straight_waypoints(self.cspace, path)


def motion_spacing(cspace, wrap_angles: bool = True, edges: int = 200, seed: int = 0) -> dict:
    """How finely OMPL's motion validator checks motions of `OmplSpace(cspace, wrap_angles)` with
    `motion_check_steps`, measured on `edges` random edges (uniform pairs of states): the states it hands the
    validity checker are recorded (no collision check runs), ordered along the motion, and their spacing measured
    in our metric. Returns the fractions, the largest spacing seen / r (at most 1 by the rule) and how many states
    OMPL checks per edge over the ceil(length / r) an exact r-spacing needs (median, 90th percentile, max)."""
    _, og, _ = ompl_modules()
    space = OmplSpace(cspace, wrap_angles)
    setup = og.SimpleSetup(space.space)
    seen = []

    def record(state):
        seen.append((space.space.distance(a, state), space.q(state)))
        return True

    setup.setStateValidityChecker(record)
    si = setup.getSpaceInformation()
    space.apply_motion_checks(si)
    si.setup()
    rng = np.random.default_rng(seed)
    a, b = space.space.allocState(), space.space.allocState()
    r = cspace.resolution
    largest, ratios = 0.0, []
    for _ in range(edges):
        qa, qb = cspace.uniform(rng, 2)
        space.write(a, qa)
        space.write(b, qb)
        qa, qb = space.q(a), space.q(b)  # as OMPL holds them (angles wrapped)
        seen.clear()
        si.checkMotion(a, b)
        # OMPL's distance from a grows linearly along a straight motion: it orders the states from a to b
        along = [qa] + [q for _, q in sorted(seen, key=lambda item: item[0])]
        if not np.allclose(along[-1], qb):
            raise RuntimeError("OMPL's motion check did not reach the end of the motion")
        steps = cspace.distance(np.array(along[:-1]), np.array(along[1:]))
        if space.compound:
            length = float(cspace.distance(qa, qb))
        else:  # OMPL's straight line, not unwrapped (its pieces are shorter than half a turn: the short way)
            length = float(steps.sum())
        largest = max(largest, float(steps.max()))
        ratios.append(len(seen) / max(1, math.ceil(length / r - 1e-9)))
    ratios = np.array(ratios)
    return {
        "space": space.kind,
        "fractions": space.fractions().tolist(),
        "edges": edges,
        "max_spacing_over_resolution": largest / r,
        "checks_over_exact_median": float(np.median(ratios)),
        "checks_over_exact_p90": float(np.percentile(ratios, 90)),
        "checks_over_exact_max": float(ratios.max()),
    }


class OmplProblem:
    """One OMPL planning problem on our oracle: the scene's start and goal, one of `PLANNERS` (or PRM with a
    valid-state sampler, `use_sampler`), motion checks at most the scene's resolution apart (`motion_check_steps`)."""

    def __init__(self, oracle, seed: int = 0, planner: str = "PRM"):
        global _seeded
        ob, og, ou = ompl_modules()
        if planner not in PLANNERS:
            raise UserError(f"unknown OMPL planner '{planner}' (known: {', '.join(PLANNERS)})")
        self.ob, self.og = ob, og
        if not _seeded:  # OMPL takes one seed per process, before its first random draw
            ou.RNG.setSeed(int(seed) + 1)  # (seed 0 would mean "pick one")
            _seeded = True
        self.oracle, self.planner_name = oracle, planner
        self.checker = oracle.context()  # this problem's collision checks, counted apart from other queries'
        self.rng = np.random.default_rng(seed)
        self.map = OmplSpace(oracle.space, wrap_angles=planner not in REAL_VECTOR_ONLY)
        self.space = self.map.space
        self.setup = og.SimpleSetup(self.space)
        self.setup.setStateValidityChecker(self._valid)
        self.si = self.setup.getSpaceInformation()
        # OMPL's default spacing (1 % of the extent) is too coarse for a narrow passage: at most r in our metric.
        self.map.apply_motion_checks(self.si)
        self.setup.setStartAndGoalStates(self.to_state(oracle.scene.start), self.to_state(oracle.scene.goal))
        # Path length, threshold infinite: any solution satisfies it, so PRM and BIT* stop at their first one.
        self.objective = ob.PathLengthOptimizationObjective(self.si)
        self.objective.setCostThreshold(self.objective.infiniteCost())
        self.setup.setOptimizationObjective(self.objective)
        self.planner = getattr(og, planner)(self.si)
        self.setup.setPlanner(self.planner)
        self._samplers = []

    def to_state(self, q):
        return self.map.state(q)

    def to_q(self, state) -> np.ndarray:
        return self.map.q(state)

    def _valid(self, state) -> bool:
        return self.checker.is_free(self.map.q(state))

    def use_sampler(self, name: str, **params) -> None:
        """Make OMPL's PRM draw valid states from `name`: ompl-uniform, ompl-obstacle, ompl-gaussian, ompl-bridge,
        or any of our samplers (uniform, gaussian, rbbs, rws, lfs, rwbs, lfbs). (Only PRM uses a valid-state
        sampler; the other planners draw plain states.)"""
        ob = self.ob
        sigma = params.get("sigma")

        def allocate(si):
            if name == "ompl-uniform":
                sampler = ob.UniformValidStateSampler(si)
            elif name == "ompl-obstacle":
                sampler = ob.ObstacleBasedValidStateSampler(si)
            elif name == "ompl-gaussian":
                sampler = GaussianSampler(si, sigma)
            elif name == "ompl-bridge":
                sampler = BridgeTestSampler(si, sigma)
            else:
                sampler = ProjectSampler(si, self, name, params)
            self._samplers.append(sampler)  # OMPL holds a raw pointer: keep the Python object alive
            return sampler

        self.si.setValidStateSamplerAllocator(allocate)

    def set_query(self, start, goals) -> None:
        """Make (start, goals) the problem's query, keeping what the planner has built: OMPL's `clearQuery()` forgets
        the last start and goal (PRM keeps its roadmap, the last query's start and goal milestones among it; other
        planners clear their trees), and the last solution is dropped so that `solve` reports this query's.
        `goals`: one configuration or several (k, dim), any of which will do (an OMPL GoalStates)."""
        self.planner.clearQuery()
        self.setup.getProblemDefinition().clearSolutionPaths()
        goal = self.ob.GoalStates(self.si)
        for q in np.atleast_2d(goals):
            goal.addState(self.to_state(q))  # copied into the goal
        self.setup.clearStartStates()
        self.setup.addStartState(self.to_state(start))
        self.setup.setGoal(goal)
        self._goal = goal  # the problem definition holds it by a shared pointer; keep the Python side alive too
        if self.planner_name == "PRM":
            # PRM adds one goal state per solve() before it starts its solution-checking thread, which adds the rest
            # with validity checks of its own: our Python callback there waits for the GIL that the solve() call
            # holds (the binding does not release it) while PRM's main thread waits for that thread's graph lock --
            # a deadlock with two goals or more. Solves with no time add the others here, one each, on this thread.
            for _ in range(len(np.atleast_2d(goals)) - 1):
                self.setup.solve(0.0)

    def use_milestones(self, replay=()) -> None:
        """Make OMPL's PRM draw its valid states from `MilestoneSampler`: first the configurations `replay`, in
        order, those free in this problem's cell; then as OMPL's uniform valid-state sampler. Every state it gives
        is kept in `self.milestones`, in order: a PRM grown with it can be grown again, the same way, in another cell
        (`regrow`)."""
        self._replay = [np.asarray(q, float) for q in reversed(list(replay))]
        self.milestones: list[np.ndarray] = []

        def allocate(si):
            sampler = MilestoneSampler(si, self)
            self._samplers.append(sampler)  # OMPL holds a raw pointer: keep the Python object alive
            return sampler

        self.si.setValidStateSamplerAllocator(allocate)

    def regrow(self, milestones) -> None:
        """PRM only: the roadmap a PRM grew from `milestones` (`use_milestones`' record of it, from a problem in
        another cell) grown again in this problem's cell: each milestone checked, and the free ones added in their
        order, each connected as PRM connects a new milestone (to its nearest, every motion checked). In the cell it
        was grown in, the same graph; in a changed one, that graph re-validated: every vertex and every edge PRM
        tried checked again, through this problem's checker. After it, the sampler draws as OMPL's uniform one."""
        self.use_milestones(milestones)
        self.setup.setup()
        self.planner.growRoadmapPtc(self.ob.PlannerTerminationCondition(lambda: not self._replay))

    def grow(self, seconds: float, checks: int | None = None) -> None:
        """PRM only: grow the roadmap for `seconds` with no query (`PRM.growRoadmap`: sample valid states, connect
        each to its nearest neighbours; no expand phase), after the planner is set up; and until this problem's
        checker has made `checks` more collision checks if given."""
        self.setup.setup()
        if checks is None:
            self.planner.growRoadmap(float(seconds))
        else:
            self.planner.growRoadmapPtc(self._termination(seconds, checks))

    def solve(self, seconds: float, checks: int | None = None) -> bool:
        """Run the planner for at most `seconds`, and until this problem's checker has made `checks` collision checks
        if given (it returns at its first solution); whether it found an exact one."""
        if checks is None:
            self.setup.solve(float(seconds))
        else:
            self.setup.solve(self._termination(seconds, checks))
        return bool(self.setup.haveExactSolutionPath())

    def _termination(self, seconds: float, checks: int):
        """OMPL's condition: `seconds` gone, or `checks` more collision checks made by this problem's checker."""
        limit = self.checker.checks + int(checks)
        spent = self.ob.PlannerTerminationCondition(lambda: self.checker.checks >= limit)
        timed = self.ob.timedPlannerTerminationCondition(float(seconds))
        return self.ob.plannerOrTerminationCondition(spent, timed)

    def simplify(self) -> None:
        """OMPL's own smoothing of the solution (`SimpleSetup.simplifySolution`: vertex reduction, shortcuts and
        B-spline smoothing until nothing improves), in place."""
        self.setup.simplifySolution()

    def solution(self) -> np.ndarray:
        return np.array([self.to_q(s) for s in self.setup.getSolutionPath().getStates()])

    def solution_for_oracle(self) -> np.ndarray:
        """The solution as waypoints whose short-way edges (our oracle's) are OMPL's own motions: check this one
        with a checker's edges_free, measure it with app.motion.path.path_length."""
        return self.map.for_oracle(self.solution())


def straight_waypoints(cspace, path: np.ndarray) -> np.ndarray:
    """Split each edge so no continuous joint turns by half a turn or more within a piece: the short way round
    (our metric) and a real-vector space's linear interpolation are then the same motion. `cspace`: a
    ConfigurationSpace (or an oracle, for its space)."""
    cspace = getattr(cspace, "space", cspace)
    out = [path[0]]
    for a, b in zip(path[:-1], path[1:]):
        turn = np.max(np.abs(b - a)[cspace.continuous], initial=0.0)
        pieces = max(1, int(np.ceil(turn / (0.5 * np.pi))))  # < pi per piece, with room to spare
        out.extend(a + (b - a) * t for t in np.linspace(0.0, 1.0, pieces + 1)[1:])
    return np.array(out)


def _base():
    ob, _, _ = ompl_modules()
    return ob.ValidStateSampler


class _Sampler(_base()):
    """Common set-up: OMPL's own state sampler for uniform and Gaussian draws, and 100 attempts per sample()."""

    ATTEMPTS = 100

    def __init__(self, si, sigma=None):
        super().__init__(si)
        self.si_ = si
        space = si.getStateSpace()
        self.sigma = sigma if sigma is not None else 0.1 * space.getMaximumExtent()  # OMPL's default
        self.base = si.allocStateSampler()
        self.a = space.allocState()
        self.b = space.allocState()

    def sampleNear(self, state, near, distance):
        return False


class GaussianSampler(_Sampler):
    """OMPL's GaussianValidStateSampler: uniform q1, q2 ~ N(q1, sigma); return the valid one if exactly one is."""

    def sample(self, state):
        space = self.si_.getStateSpace()
        for _ in range(self.ATTEMPTS):
            self.base.sampleUniform(self.a)
            valid_a = self.si_.isValid(self.a)
            self.base.sampleGaussian(self.b, self.a, self.sigma)
            valid_b = self.si_.isValid(self.b)
            if valid_a != valid_b:
                space.copyState(state, self.a if valid_a else self.b)
                return True
        return False


class BridgeTestSampler(_Sampler):
    """OMPL's BridgeTestValidStateSampler: invalid uniform q1, invalid Gaussian q2, valid midpoint."""

    def sample(self, state):
        space = self.si_.getStateSpace()
        for _ in range(self.ATTEMPTS):
            self.base.sampleUniform(self.a)
            if self.si_.isValid(self.a):
                continue
            self.base.sampleGaussian(self.b, self.a, self.sigma)
            if self.si_.isValid(self.b):
                continue
            space.interpolate(self.a, self.b, 0.5, state)
            if self.si_.isValid(state):
                return True
        return False


class ProjectSampler(_Sampler):
    """One of this project's samplers behind OMPL's ValidStateSampler interface (batches drawn ahead)."""

    BATCH = 10

    def __init__(self, si, problem: OmplProblem, name: str, params: dict):
        super().__init__(si)
        self.problem = problem
        self.sampler = make_sampler(name, problem.checker, **params)
        self.buffer = []

    def sample(self, state):
        if not self.buffer:
            batch = self.sampler.sample(self.BATCH, self.problem.rng)
            self.buffer = list(batch)
            if not self.buffer:
                return False
        self.problem.map.write(state, self.buffer.pop())
        return True


class MilestoneSampler(_Sampler):
    """A valid-state sampler that replays configurations (OmplProblem.use_milestones) before it draws as OMPL's
    uniform valid-state sampler, and records every state it gives."""

    def __init__(self, si, problem: OmplProblem):
        super().__init__(si)
        self.problem = problem
        self.uniform = problem.ob.UniformValidStateSampler(si)

    def sample(self, state):
        problem = self.problem
        while problem._replay:
            q = problem._replay.pop()
            if problem.checker.is_free(q):
                problem.map.write(state, q)
                problem.milestones.append(q)
                return True
        if not self.uniform.sample(state):
            return False
        problem.milestones.append(problem.to_q(state))
        return True
