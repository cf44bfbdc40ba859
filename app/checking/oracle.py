"""The collision oracle: the one object samplers and planners talk to. It owns every Drake query and counts them.

Three paths for a batch (their costs per configuration are measured by `python -m app bench oracle`):
- raw SceneGraph `QueryObject.HasCollisions` from a Python loop: the same cost free or not; always used for one
  configuration (`CheckConfigCollisionFree` computes distances and costs several times more);
- `SceneGraphCollisionChecker.CheckConfigsCollisionFree`, whose C++ loop spreads a batch over threads. It is cheaper
  than the raw loop per *free* configuration but dearer per *colliding* one (it computes signed distances of
  penetrating pairs), and it suffers most when other processes hold the cores;
- split: the raw loop here on part of the batch while helper processes, each with its own oracle of the scene, run
  it on the rest (`_Helpers`). pydrake holds the GIL in `HasCollisions`, so threads cannot parallelise the raw loop;
  processes can. The helpers start once large batches have taken about half a second (`_HELPERS_AFTER`), so a short
  run never pays for them.
So no fixed choice fits both a walker's batches (mostly colliding proposals) and a roadmap's edge points (mostly
free): `are_free` keeps a running cost per configuration for each path, takes the cheapest, and re-measures the
others now and then, so it follows the caller's phase and the machine's load. Every path gives the same answers.
Edge checks (`first_hits`) take the raw loop: their points come in coarse-to-fine order, and an edge's points after
its first collision are skipped, which a batch cannot do.
Every path sees the same collision pairs: the scene's policy is applied to the checker (body pairs) and to the raw
query context (geometry filter), and a test holds them to agreement. An SRDF's disabled pairs need neither: the
Scene filters them on the SceneGraph model, which the checker and every context start from.

One oracle per scene is shared by every query on it; a query counts and bounds what it asks through its own
`QueryContext` (app.checking.context; `oracle.context()`), so the oracle holds no per-query state. It may be
shared between threads: its Drake contexts are one set, so every query on them holds the oracle's lock (pydrake holds
the GIL inside them anyway, so the lock costs no parallelism; the batch path spreads over Drake's own threads).
"""

from __future__ import annotations

import functools
import logging
import os
import threading
import time

import numpy as np

from app.checking.batch_paths import SPLIT_MIN, BatchPaths, splits
from app.checking.context import QueryContext
from app.checking.diagnostics import Diagnostics
from app.checking.helpers import CONFIGURATIONS, Helpers
from app.checking.workspace import Workspace
from app.scene.cspace import ConfigurationSpace
from app.scene.model import Scene

# pydrake is imported inside the methods that use it, so that importing the package does not load Drake.

# Below this many configurations the checker's batch set-up costs more than the raw loop saves.
_BATCH_MIN = 8
# Configurations the helpers must answer as this process does before they are used (uniform, uncounted).
_PROBE_BATCH = 64
# Helper processes start once such batches have taken this many seconds: a short run never pays for their start
# (about half a second of the other core, more for a scene's first mesh decomposition), a long one gets every core.
_HELPERS_AFTER = 0.5


def default_threads() -> int:
    return max(1, min(2, os.cpu_count() or 1))


class CollisionOracle:
    """The one object every collision question about `scene` goes through: made once per scene and shared by every
    query on it, also between threads (its Drake queries hold its lock). A query counts and bounds what it asks
    through its own QueryContext (`context()`); the oracle keeps no per-query state.

    `threads` (default: up to 2, at most the machine's cores) are the cores it may use: Drake's threaded batch, or
    threads - 1 helper processes with their own copy of the scene, which share large batches once they have taken
    half a second (`start_helpers()` starts them at once). Answers and counts are the same on any number.

    Attributes:
        scene: The scene.
        space: Its configuration space: bounds, metric, edge-check resolution.
        threads: The cores it may use.
        processes: The processes a batch or a cell build's edges may be spread over: this one and its helpers.
        answered: Configurations answered for every query since it was made (a query's own count is its context's
            `checks`).
        seconds: Seconds spent answering since it was made, by kind: "checks", "distances", "points".
    """

    def __init__(self, scene: Scene, threads: int | None = None):
        from pydrake.common import Parallelism
        from pydrake.planning import SceneGraphCollisionChecker

        # Drake logs an INFO line per checker about its thread contexts; users should see only what matters.
        # (pydrake mirrors this logger's level into its C++ logger; it must be set after pydrake is imported.)
        logging.getLogger("drake").setLevel(logging.WARNING)
        self.scene = scene
        self.space = ConfigurationSpace.of(scene)
        self.positions = scene.positions  # configurations -> the plant's positions (mimic joints follow)
        self.threads = threads or default_threads()
        self._parallelism = Parallelism(self.threads)
        # Which batch path to take, per size class of batch (`_Paths`): a split's round trip and the checker's batch
        # set-up are costs per call, so a path's cost per configuration depends on the batch's size.
        self._paths: dict[int, BatchPaths] = {}
        # Processes a batch or a cell build's edges may be spread over: this one and its helpers, no more than the
        # machine's cores (more would only take turns on them).
        self.processes = max(1, min(self.threads, os.cpu_count() or 1))
        # (A scene another process cannot rebuild, from a user's own checker, has no recipe: no helpers.)
        with_helpers = self.processes > 1 and scene.recipe is not None
        self._helpers = Helpers(scene.recipe, self.processes - 1) if with_helpers else None
        self._split_seconds = 0.0  # spent on batches large enough to split, until the helpers start
        self.lock = threading.RLock()  # held by every query on the shared Drake contexts
        # Configurations answered for every query since the oracle was made: for a progress display that watches
        # the oracle from another thread. A query's own count is its context's `checks`.
        self.answered = 0
        # Seconds spent answering geometric questions since the oracle was made, by kind: collision checks and
        # signed-distance queries (Drake's), workspace point queries (mostly numpy, app.checking.polytopes). A
        # benchmark takes the difference over a run to tell the share of its time that queries took from the share
        # that went to everything else.
        self.seconds = {"checks": 0.0, "distances": 0.0, "points": 0.0}

        # The checker takes ownership of the diagram; everything below goes through checker.model(). Drake requires
        # an edge step, but nothing calls the checker's edge methods (edges are checked on the raw loop: first_hits),
        # so edge_step_size is unused here. A scene from a user's own checker (from_checker) brings it along.
        self.checker = getattr(scene, "collision_checker", None) or SceneGraphCollisionChecker(
            model=scene.diagram,
            robot_model_instances=scene.robot_instances,
            edge_step_size=scene.resolution,
            env_collision_padding=0.0,
            self_collision_padding=0.0,
        )
        self.model = self.checker.model()
        self.plant = self.model.plant()
        from app.checking import kernels  # numba: loaded with the scene, not on the command line's parser

        # The compiled loops of the kinematics and the certificate, loaded (or on a machine's first run, compiled)
        # with the scene, so that no query's time includes it.
        kernels.load()
        robot_bodies = [
            self.plant.get_body(b) for inst in scene.robot_instances for b in self.plant.GetBodyIndices(inst)
        ]
        self.robot_geometries = {g for body in robot_bodies for g in self.plant.GetCollisionGeometriesForBody(body)}
        if not scene.self_collisions:
            # One matrix update, not one per body pair: each update re-filters every thread's context, which costs
            # seconds among a thousand environment pieces.
            matrix = self.checker.GetFilteredCollisionMatrix().copy()
            index = [int(body.index()) for body in robot_bodies]
            pairs = np.ix_(index, index)
            matrix[pairs] = np.where(np.eye(len(index), dtype=bool), matrix[pairs], 1)  # (the diagonal stays -1)
            self.checker.SetCollisionFilterMatrix(matrix)
        # Policy context: the scene's collision pairs, used for every counted answer.
        self._root = self.policy_context()
        self._ctx = self.plant.GetMyContextFromRoot(self._root)
        self._query_port = self.plant.get_geometry_query_input_port()

    def policy_context(self):
        """A new root context of the model whose SceneGraph sees exactly the scene's collision pairs (the same
        pairs the checker is told to filter), for any Drake query that must agree with the oracle's answers."""
        from pydrake.geometry import CollisionFilterDeclaration, GeometrySet
        from pydrake.multibody.tree import BodyIndex

        root = self.model.CreateDefaultContext()
        scene_graph = self.model.scene_graph()
        manager = scene_graph.collision_filter_manager(scene_graph.GetMyMutableContextFromRoot(root))
        if not self.scene.self_collisions:
            manager.Apply(CollisionFilterDeclaration().ExcludeWithin(GeometrySet(list(self.robot_geometries))))
        # A user's own checker filters body pairs in its own contexts (its collision filter matrix): the same here.
        for a, b in getattr(self.scene, "filtered_body_pairs", ()):
            geometries = [self.plant.GetCollisionGeometriesForBody(self.plant.get_body(BodyIndex(i))) for i in (a, b)]
            if geometries[0] and geometries[1]:
                manager.Apply(CollisionFilterDeclaration().ExcludeBetween(*(GeometrySet(g) for g in geometries)))
        return root

    def of_scene(self, scene) -> CollisionOracle:
        """An oracle like this one (as many threads) for another scene: the same cell after a change."""
        return CollisionOracle(scene, threads=self.threads)

    def context(self) -> QueryContext:
        """A new QueryContext on this oracle: one query's counters (its calls each take the stop that bounds them)."""
        return QueryContext(self)

    @functools.cached_property
    def workspace(self) -> Workspace:
        """Where the robot's pieces are, and where the environment leaves narrow gaps (app.checking.workspace)."""
        return Workspace(self)

    @functools.cached_property
    def diagnostics(self) -> Diagnostics:
        """What a configuration touches, named (app.checking.diagnostics)."""
        return Diagnostics(self)

    # ---- collision answers (uncounted: a QueryContext counts and bounds them) ---------------------------------
    def free_raw(self, Q: np.ndarray) -> np.ndarray:
        """Free flags of configurations (n, dim) by HasCollisions, one by one. Drake's methods are bound once: this
        loop is the oracle's only per-configuration cost outside Drake (benchmark pages, "Time outside the
        checks")."""
        set_positions, evaluate, context = self.plant.SetPositions, self._query_port.Eval, self._ctx
        free = np.empty(len(Q), bool)
        for i, q in enumerate(self.positions(Q)):
            set_positions(context, q)
            free[i] = not evaluate(context).HasCollisions()
        return free

    def first_hits(self, Q: np.ndarray, owner: np.ndarray, hit: list, until_one: bool) -> tuple[int, int]:
        """Collision answers for configurations (n, dim), within bounds, in order: Q[i] is a point of edge owner[i],
        skipped once hit[owner[i]] is True (a point found colliding sets it). With until_one, stops after the first
        collision. Returns (points passed, configurations checked). The edge checks' loop (QueryContext.edges_status):
        one call for points that free_batch would take in a call per coarse-to-fine round."""
        set_positions, evaluate, context = self.plant.SetPositions, self._query_port.Eval, self._ctx
        positions, edges = self.positions(Q), owner.tolist()
        checked, passed = 0, len(edges)
        with self.lock:
            start = time.perf_counter()
            for i, edge in enumerate(edges):
                if hit[edge]:
                    continue
                checked += 1
                set_positions(context, positions[i])
                if evaluate(context).HasCollisions():
                    hit[edge] = True
                    if until_one:
                        passed = i + 1
                        break
            self.answered += checked
            self.seconds["checks"] += time.perf_counter() - start
        return passed, checked

    def free(self, q: np.ndarray) -> bool:
        """Whether the configuration q (within bounds) is collision-free under the scene's policy."""
        with self.lock:
            self.answered += 1
            start = time.perf_counter()
            free = bool(self.free_raw(np.asarray(q, float)[None])[0])
            self.seconds["checks"] += time.perf_counter() - start
            return free

    def free_batch(self, Q: np.ndarray) -> np.ndarray:
        """Free flags for configurations (n, dim), all within bounds, by the cheapest path so far (module
        docstring)."""
        Q = np.atleast_2d(np.asarray(Q, float))
        free = np.zeros(len(Q), bool)
        if not len(Q):
            return free
        with self.lock:
            self.answered += len(Q)
            if self.threads == 1 or len(Q) < _BATCH_MIN:
                path, choice = "raw", None
            else:
                self._follow_helpers()
                choice = self.paths_for(len(Q))
                path = choice.choose()
            start = time.perf_counter()
            if path == "raw":
                free = self.free_raw(Q)
            elif path == "split":
                free = self._helpers.free(Q, self.free_raw)
            else:
                free[:] = self.checker.CheckConfigsCollisionFree(list(self.positions(Q)), parallelize=self._parallelism)
            spent = time.perf_counter() - start
            self.seconds["checks"] += spent
            if len(Q) >= SPLIT_MIN and self._helpers is not None and self._helpers.state == "idle":
                self._split_seconds += spent
                if self._split_seconds >= _HELPERS_AFTER:
                    self._helpers.start()
            if choice is not None:
                choice.measured(path, spent / len(Q))
        return free

    def paths_for(self, n: int) -> BatchPaths:
        """The path choice for batches of n configurations (n >= _BATCH_MIN): one per power of two up to 4096."""
        size = min(n.bit_length(), 13)
        if size not in self._paths:
            split = self._helpers is not None and self._helpers.ready() and splits(size)
            self._paths[size] = BatchPaths(("batch", "raw", "split") if split else ("batch", "raw"))
        return self._paths[size]

    def start_helpers(self) -> bool:
        """Start the helper processes now, not after half a second of batches, and wait until they are ready (or have
        failed: the oracle then answers alone). Whether they are ready."""
        if self._helpers is None:
            return False
        with self.lock:
            if self._helpers.state == "idle":
                self._helpers.start()
            self._helpers.wait()
            self._follow_helpers()
            return self._helpers.ready()

    def spread_edges(self, checker: QueryContext, Q1: np.ndarray, Q2: np.ndarray, resolution: float) -> np.ndarray:
        """Free flags of straight edges whose ends are free, checked by `checker` here and by the helpers (started
        and waited for if need be), their checks added to checker's. An edge's verdict and check count do not depend
        on which process checked it or with which other edges."""
        with self.lock:  # the pipes carry one conversation at a time
            if len(Q1) < 2 or self._helpers is None or not self.start_helpers():
                return checker.edges_free(Q1, Q2, resolution, ends_free=True)
            free, checks = self._helpers.edges_free(
                Q1, Q2, resolution, lambda A, B: checker.edges_free(A, B, resolution, ends_free=True)
            )
        checker.checks += checks
        return free

    def _follow_helpers(self) -> None:
        """The split path joins the choices of batches large enough once the helpers are ready and answer a probe
        batch as this process does (they load the scene anew: a scene file changed since must not split answers
        between two scenes); it leaves them if a helper has failed since."""
        helpers = self._helpers
        if helpers is None or helpers.state == "idle":
            return
        if helpers.ready() and not helpers.checked:
            helpers.checked = True
            probe = self.space.uniform(np.random.default_rng(0), _PROBE_BATCH)
            if not np.array_equal(helpers.free(probe, self.free_raw), self.free_raw(probe)):
                helpers.give_up()
        if helpers.ready():
            for size, choice in self._paths.items():
                if splits(size):
                    choice.cost.setdefault("split", None)
        else:
            for choice in self._paths.values():
                choice.cost.pop("split", None)

    # ---- geometry (not counted: these are measurements, not collision answers) ------------------------------
    def plant_context(self, q: np.ndarray):
        """The plant's context under the scene's collision policy with the robot at q (the caller holds `lock`, and
        reads it before the oracle's next query)."""
        self.plant.SetPositions(self._ctx, self.positions(np.asarray(q, float)))
        return self._ctx

    def query_object(self, q: np.ndarray):
        """SceneGraph's QueryObject with the robot at q, under the scene's collision policy, for pictures and
        measurements that need Drake's own answers (not counted). Valid until the oracle's next query: one thread's
        use only."""
        with self.lock:
            return self._query_port.Eval(self.plant_context(q))

    def is_robot_geometry(self, geometry_id) -> bool:
        """Whether a SceneGraph geometry belongs to the robot (else to the environment)."""
        return geometry_id in self.robot_geometries

    def in_contact(self, q: np.ndarray) -> bool:
        """Whether a pair the scene's policy counts penetrates at q: HasCollisions, cheaper than signed distances,
        where the certificate needs no distances from Drake; timed as a distance query."""
        with self.lock:
            start = time.perf_counter()
            hit = not self.free_raw(np.asarray(q, float)[None])[0]
            self.seconds["distances"] += time.perf_counter() - start
            return bool(hit)

    def pair_distances(self, q: np.ndarray, pairs: list) -> list:
        """SceneGraph's SignedDistancePair at q of each given pair of GeometryIds, however far apart (the
        certificate's direction for a pair it bounds itself); timed as a distance query."""
        with self.lock:
            start = time.perf_counter()
            query = self.query_object(q)
            found = [query.ComputeSignedDistancePairClosestPoints(a, b) for a, b in pairs]
            self.seconds["distances"] += time.perf_counter() - start
            return found

    def signed_distance_pairs(self, q: np.ndarray, max_distance: float) -> list:
        """SceneGraph's SignedDistancePairs at q of the pairs the scene's policy counts that lie within
        `max_distance` (farther pairs are left out)."""
        with self.lock:
            start = time.perf_counter()
            pairs = self.query_object(q).ComputeSignedDistancePairwiseClosestPoints(max_distance)
            self.seconds["distances"] += time.perf_counter() - start
            return pairs


def serve(fd: int) -> None:
    """A helper's loop on the pipe at file descriptor fd: the scene's recipe first, then batches of configurations
    (free flags back) or pieces of edges whose ends are free (free flags and checks back), until the pipe closes."""
    import pickle
    from multiprocessing.connection import Connection

    pipe = Connection(fd)
    try:
        oracle = CollisionOracle(pickle.loads(pipe.recv_bytes())(), threads=1)
        pipe.send_bytes(b"ready")
        while True:
            message = pipe.recv_bytes()
            if message[:1] == CONFIGURATIONS:
                Q = np.frombuffer(message, offset=1).reshape(-1, oracle.space.dim)
                pipe.send_bytes(oracle.free_raw(Q).tobytes())
            else:
                Q1, Q2, resolution = pickle.loads(message[1:])
                checker = oracle.context()
                free = checker.edges_free(Q1, Q2, resolution, ends_free=True)
                pipe.send_bytes(pickle.dumps((free, checker.checks)))
    except Exception:  # the pipe closed, or the scene did not load here: the parent answers alone
        return


def from_checker(checker, name: str = "own", threads: int | None = None, **problem) -> CollisionOracle:
    """An oracle on a user's own Drake SceneGraphCollisionChecker: its diagram, robot model instances and collision
    filter matrix as they are, every plant position a coordinate. `problem`: what a problem file would say
    (app.scene.problem.ProblemFile: lower, upper, start, goal, weights, resolution, step, velocity_limits, ...;
    bounds default to the joints' limits, start and goal to the plant's default positions). The checker is the
    oracle's from then on (do not change its filters behind it)."""
    from app.scene.checker_scene import CheckerScene

    return CollisionOracle(CheckerScene(checker, name, **problem), threads=threads)
