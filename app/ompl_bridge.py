"""OMPL on our collision oracle: a state space, a validity checker, and valid-state samplers.

- `OmplProblem(oracle)` sets up OMPL's SimpleSetup with the oracle as validity checker (every check counted in
  oracle.checks, like our own planner's) and start/goal from the scene.
- OMPL's Gaussian and bridge-test samplers are not bound in the Python wheel; `GaussianSampler` and
  `BridgeTestSampler` re-implement OMPL 2.0.1's algorithms as `ValidStateSampler` subclasses.
- `ProjectSampler` offers any of our samplers (lfbs, rbbs, ...) to OMPL, so an OMPL user can put LFBS into their
  own pipeline: `problem.use_sampler("lfbs", step=10)`.

Coordinates are scaled by the scene's metric weights, so OMPL's Euclidean distance, its motion-check resolution and
its sigma mean the same as ours. OMPL's RealVectorStateSpace does not wrap angles: continuous joints are treated as
intervals [-pi, pi] on the OMPL side (our own PRM does wrap); this only removes shortcuts across +-pi.
"""
import numpy as np

from app.errors import UserError
from app.samplers import make_sampler
# Importing this module loads OMPL (an optional dependency; the samplers below subclass its classes), so callers
# import it only where OMPL is needed.

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


class OmplProblem:
    def __init__(self, oracle, seed: int = 0):
        global _seeded
        ob, og, ou = ompl_modules()
        self.ob, self.og = ob, og
        if not _seeded:  # OMPL takes one seed per process, before its first random draw
            ou.RNG.setSeed(int(seed) + 1)  # (seed 0 would mean "pick one")
            _seeded = True
        self.oracle = oracle
        self.rng = np.random.default_rng(seed)
        self.scale = oracle.space.weights
        dim = oracle.space.dim
        self.space = ob.RealVectorStateSpace(dim)
        bounds = ob.RealVectorBounds(dim)
        for i in range(dim):
            bounds.setLow(i, float(oracle.space.lower[i] * self.scale[i]))
            bounds.setHigh(i, float(oracle.space.upper[i] * self.scale[i]))
        self.space.setBounds(bounds)
        self.setup = og.SimpleSetup(self.space)
        self.setup.setStateValidityChecker(self._valid)
        self.si = self.setup.getSpaceInformation()
        # OMPL's default spacing (1 % of the extent) is too coarse for a narrow passage: use the scene's resolution.
        self.si.setStateValidityCheckingResolution(oracle.space.resolution / self.space.getMaximumExtent())
        self.setup.setStartAndGoalStates(self.to_state(oracle.scene.start), self.to_state(oracle.scene.goal))
        self._samplers = []

    def to_state(self, q):
        state = self.space.allocState()
        for i, v in enumerate(np.asarray(q, float) * self.scale):
            state[i] = float(v)
        return state

    def to_q(self, state) -> np.ndarray:
        return np.array([state[i] for i in range(self.oracle.space.dim)]) / self.scale

    def _valid(self, state) -> bool:
        return self.oracle.is_free(self.to_q(state))

    def use_sampler(self, name: str, **params) -> None:
        """Make OMPL's planners draw valid states from `name`: ompl-uniform, ompl-obstacle, ompl-gaussian,
        ompl-bridge, or any of our samplers (uniform, gaussian, rbbs, rws, lfs, rwbs, lfbs)."""
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

    def solve(self, seconds: float) -> bool:
        self.setup.setPlanner(self.og.PRM(self.si))
        self.setup.solve(float(seconds))
        return bool(self.setup.haveExactSolutionPath())

    def solution(self) -> np.ndarray:
        return np.array([self.to_q(s) for s in self.setup.getSolutionPath().getStates()])

    def solution_for_oracle(self) -> np.ndarray:
        """The solution with waypoints added so that our oracle's edges (which take the short way round on
        continuous joints) follow OMPL's straight, unwrapped motions: check this one with oracle.edges_free."""
        return straight_waypoints(self.oracle, self.solution())


def straight_waypoints(oracle, path: np.ndarray) -> np.ndarray:
    """Split each edge so no continuous joint turns by half a turn or more within a piece: the short way round
    (our metric) and OMPL's linear interpolation are then the same motion."""
    out = [path[0]]
    for a, b in zip(path[:-1], path[1:]):
        turn = np.max(np.abs(b - a)[oracle.space.continuous], initial=0.0)
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
        self.sampler = make_sampler(name, problem.oracle, **params)
        self.buffer = []

    def sample(self, state):
        if not self.buffer:
            batch = self.sampler.sample(self.BATCH, self.problem.rng)
            self.buffer = list(batch)
            if not self.buffer:
                return False
        q = self.buffer.pop()
        for i, v in enumerate(q * self.problem.scale):
            state[i] = float(v)
        return True
