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
`QueryContext` (app.checking.context; `oracle.context(budget)`), so the oracle holds no per-query state. It may be
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

from app.checking.budget import Budget
from app.checking.context import QueryContext
from app.checking.polytopes import Polytopes, gaps
from app.scene.cspace import ConfigurationSpace
from app.scene.meshes import hull_vertices
from app.scene.model import Scene

# pydrake is imported inside the methods that use it, so that importing the package does not load Drake.

# Signed distance at or below which two geometries touch: an endpoint there is refused (see `touching`).
CONTACT = 1e-9
# Below this many configurations the checker's batch set-up costs more than the raw loop saves.
_BATCH_MIN = 8
# Batches of at least this many configurations may be split with helper processes; below it the pipe's round trip
# costs more than the half batch saves.
_SPLIT_MIN = 16
# Configurations the helpers must answer as this process does before they are used (uniform, uncounted).
_PROBE_BATCH = 64
# A helper's messages: a batch of configurations (their bytes), or a piece of edges to check (pickled).
_CONFIGURATIONS, _EDGES = b"Q", b"E"
# Pieces per process a call's edges are cut into and handed out as each process finishes its last (a piece with
# colliding edges is quick, and no process should wait long on another).
_PIECES = 8
# Pieces a helper holds at once (one it checks, the next waiting).
_IN_FLIGHT = 2
# Helper processes start once such batches have taken this many seconds: a short run never pays for their start
# (about half a second of the other core, more for a scene's first mesh decomposition), a long one gets every core.
_HELPERS_AFTER = 0.5
# Batch calls before the path not in favour is measured again: at first 16; each time it is found dearer still, twice
# as many, up to 1024. On the UR3 scenes the checker's batch costs 4x the raw loop per configuration (it lists every
# penetrating pair where HasCollisions stops at the first), and a probe every 16 calls spent a third of a welding
# job's collision-check time in it.
_PROBE_FIRST, _PROBE_MAX = 16, 1024
# Calls each path is given before the cheapest is chosen, its cost the least of them: one call slowed by another
# process once settled a benchmark on the raw loop, at half the speed of the split that a second call measured.
_TRIES = 2


def default_threads() -> int:
    return max(1, min(2, os.cpu_count() or 1))


class CollisionOracle:
    def __init__(self, scene: Scene, threads: int | None = None):
        from pydrake.common import Parallelism
        from pydrake.planning import SceneGraphCollisionChecker

        # Drake logs an INFO line per checker about its thread contexts; users should see only what matters.
        # (pydrake mirrors this logger's level into its C++ logger; it must be set after pydrake is imported.)
        logging.getLogger("drake").setLevel(logging.WARNING)
        self.scene = scene
        self.space = ConfigurationSpace.of(scene)
        self._positions = scene.positions  # configurations -> the plant's positions (mimic joints follow)
        self.threads = threads or default_threads()
        self._parallelism = Parallelism(self.threads)
        # Which batch path to take, per size class of batch (`_Paths`): a split's round trip and the checker's batch
        # set-up are costs per call, so a path's cost per configuration depends on the batch's size.
        self._paths: dict[int, _Paths] = {}
        # Processes a batch or a cell build's edges may be spread over: this one and its helpers, no more than the
        # machine's cores (more would only take turns on them).
        self.processes = max(1, min(self.threads, os.cpu_count() or 1))
        self._helpers = _Helpers(scene.recipe, self.processes - 1) if self.processes > 1 else None
        self._split_seconds = 0.0  # spent on batches large enough to split, until the helpers start
        self._lock = threading.RLock()  # held by every query on the shared Drake contexts
        # Configurations answered for every query since the oracle was made: for a progress display that watches
        # the oracle from another thread. A query's own count is its context's `checks`.
        self.answered = 0
        # Seconds spent answering geometric questions since the oracle was made, by kind: collision checks and
        # signed-distance queries (Drake's), workspace point queries (mostly numpy, app.checking.polytopes). A
        # benchmark takes the difference over a run to tell the share of its time that queries took from the share
        # that went to everything else.
        self.seconds = {"checks": 0.0, "distances": 0.0, "points": 0.0}

        # The checker takes ownership of the diagram; everything below goes through checker.model().
        self.checker = SceneGraphCollisionChecker(
            model=scene.diagram,
            robot_model_instances=scene.robot_instances,
            edge_step_size=scene.resolution,
            env_collision_padding=0.0,
            self_collision_padding=0.0,
        )
        self.model = self.checker.model()
        self.plant = self.model.plant()
        scene_graph = self.model.scene_graph()
        inspector = scene_graph.model_inspector()
        robot_bodies = [
            self.plant.get_body(b) for inst in scene.robot_instances for b in self.plant.GetBodyIndices(inst)
        ]
        self._robot_geometries = {g for body in robot_bodies for g in self.plant.GetCollisionGeometriesForBody(body)}

        # Unfiltered context: says *what* a configuration touches (environment, self) for diagnostics.
        self._diag_root = self.model.CreateDefaultContext()
        self._diag = self.plant.GetMyContextFromRoot(self._diag_root)
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
        self._inspector = inspector
        self._passage_frame = (
            self.plant.GetFrameByName(scene.passage_frame.name(), scene.passage_frame.model_instance())
            if scene.passage_frame is not None
            else None
        )
        # What `frame_positions` tracks: the passage frame, or without one (a custom scene) the robot's last body.
        last_body = self.plant.GetBodyIndices(scene.robot_instances[-1])[-1]
        self._tracked_frame = self._passage_frame or self.plant.get_body(last_body).body_frame()

    def policy_context(self):
        """A new root context of the model whose SceneGraph sees exactly the scene's collision pairs (the same
        pairs the checker is told to filter), for any Drake query that must agree with the oracle's answers."""
        from pydrake.geometry import CollisionFilterDeclaration, GeometrySet

        root = self.model.CreateDefaultContext()
        if not self.scene.self_collisions:
            scene_graph = self.model.scene_graph()
            scene_graph.collision_filter_manager(scene_graph.GetMyMutableContextFromRoot(root)).Apply(
                CollisionFilterDeclaration().ExcludeWithin(GeometrySet(list(self._robot_geometries)))
            )
        return root

    def context(self, budget: Budget | None = None, cancel=None) -> QueryContext:
        """A new QueryContext on this oracle: one query's counters, budget and cancel flag."""
        return QueryContext(self, budget, cancel)

    # ---- collision answers (uncounted: a QueryContext counts and bounds them) ---------------------------------
    def _raw_free(self, Q: np.ndarray) -> np.ndarray:
        """Free flags of configurations (n, dim) by HasCollisions, one by one. Drake's methods are bound once: this
        loop is the oracle's only per-configuration cost outside Drake (benchmark pages, "Time outside the
        checks")."""
        set_positions, evaluate, context = self.plant.SetPositions, self._query_port.Eval, self._ctx
        free = np.empty(len(Q), bool)
        for i, q in enumerate(self._positions(Q)):
            set_positions(context, q)
            free[i] = not evaluate(context).HasCollisions()
        return free

    def first_hits(self, Q: np.ndarray, owner: np.ndarray, hit: list, until_one: bool) -> tuple[int, int]:
        """Collision answers for configurations (n, dim), within bounds, in order: Q[i] is a point of edge owner[i],
        skipped once hit[owner[i]] is True (a point found colliding sets it). With until_one, stops after the first
        collision. Returns (points passed, configurations checked). The edge checks' loop (QueryContext.edges_status):
        one call for points that free_batch would take in a call per coarse-to-fine round."""
        set_positions, evaluate, context = self.plant.SetPositions, self._query_port.Eval, self._ctx
        positions, edges = self._positions(Q), owner.tolist()
        checked, passed = 0, len(edges)
        with self._lock:
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
        with self._lock:
            self.answered += 1
            start = time.perf_counter()
            free = bool(self._raw_free(np.asarray(q, float)[None])[0])
            self.seconds["checks"] += time.perf_counter() - start
            return free

    def free_batch(self, Q: np.ndarray) -> np.ndarray:
        """Free flags for configurations (n, dim), all within bounds, by the cheapest path so far (module
        docstring)."""
        Q = np.atleast_2d(np.asarray(Q, float))
        free = np.zeros(len(Q), bool)
        if not len(Q):
            return free
        with self._lock:
            self.answered += len(Q)
            if self.threads == 1 or len(Q) < _BATCH_MIN:
                path, choice = "raw", None
            else:
                self._follow_helpers()
                choice = self.paths_for(len(Q))
                path = choice.choose()
            start = time.perf_counter()
            if path == "raw":
                free = self._raw_free(Q)
            elif path == "split":
                free = self._helpers.free(Q, self._raw_free)
            else:
                free[:] = self.checker.CheckConfigsCollisionFree(
                    list(self._positions(Q)), parallelize=self._parallelism
                )
            spent = time.perf_counter() - start
            self.seconds["checks"] += spent
            if len(Q) >= _SPLIT_MIN and self._helpers is not None and self._helpers.state == "idle":
                self._split_seconds += spent
                if self._split_seconds >= _HELPERS_AFTER:
                    self._helpers.start()
            if choice is not None:
                choice.measured(path, spent / len(Q))
        return free

    def paths_for(self, n: int) -> _Paths:
        """The path choice for batches of n configurations (n >= _BATCH_MIN): one per power of two up to 4096."""
        size = min(n.bit_length(), 13)
        if size not in self._paths:
            split = self._helpers is not None and self._helpers.ready() and _splits(size)
            self._paths[size] = _Paths(("batch", "raw", "split") if split else ("batch", "raw"))
        return self._paths[size]

    def start_helpers(self) -> bool:
        """Start the helper processes now, not after half a second of batches, and wait until they are ready (or have
        failed: the oracle then answers alone). Whether they are ready."""
        if self._helpers is None:
            return False
        with self._lock:
            if self._helpers.state == "idle":
                self._helpers.start()
            self._helpers.wait()
            self._follow_helpers()
            return self._helpers.ready()

    def spread_edges(self, checker: QueryContext, Q1: np.ndarray, Q2: np.ndarray, resolution: float) -> np.ndarray:
        """Free flags of straight edges whose ends are free, checked by `checker` here and by the helpers (started
        and waited for if need be), their checks added to checker's. An edge's verdict and check count do not depend
        on which process checked it or with which other edges."""
        with self._lock:  # the pipes carry one conversation at a time
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
            if not np.array_equal(helpers.free(probe, self._raw_free), self._raw_free(probe)):
                helpers.give_up()
        if helpers.ready():
            for size, choice in self._paths.items():
                if _splits(size):
                    choice.cost.setdefault("split", None)
        else:
            for choice in self._paths.values():
                choice.cost.pop("split", None)

    # ---- geometry (not counted: these are measurements, not collision answers) ------------------------------
    def clearance(self, q: np.ndarray, max_distance: float = 10.0) -> float:
        """Signed distance from the robot to whatever counts under the scene's policy (negative: penetration).

        Pairs farther apart than `max_distance` are not computed, so the answer is capped there.
        """
        with self._lock:
            pairs = self.query_object(q).ComputeSignedDistancePairwiseClosestPoints(max_distance)
        return min((p.distance for p in pairs), default=float(max_distance))

    def contacts(self, q: np.ndarray, margin: float = 0.0) -> dict[str, bool]:
        """What the robot touches (or comes within `margin` of) at q, environment and self, whether or not the scene
        counts self-collision (pairs Drake or the SRDF filter are never reported)."""
        with self._lock:
            self.plant.SetPositions(self._diag, self._positions(np.asarray(q, float)))
            pairs = self._query_port.Eval(self._diag).ComputeSignedDistancePairwiseClosestPoints(max(margin, 1e-9))
        touched = {"environment": False, "self": False}
        for p in pairs:
            if p.distance > margin:
                continue
            a, b = p.id_A in self._robot_geometries, p.id_B in self._robot_geometries
            if a and b:
                touched["self"] = True
            elif a or b:
                touched["environment"] = True
        return touched

    def colliding_bodies(self, q: np.ndarray) -> list[tuple[str, str]]:
        """The body pairs (scoped names, sorted) in collision at q under the scene's policy; for error messages.
        Geometry anchored to the world (a custom scene's environment pieces) is named itself, not "world"."""
        with self._lock:
            query = self.query_object(q)
            try:
                pairs = [(p.id_A, p.id_B) for p in query.ComputePointPairPenetration()]
            except RuntimeError:  # a shape pair without penetration support: fall back to signed distances
                distances = query.ComputeSignedDistancePairwiseClosestPoints(0.0)
                pairs = [(p.id_A, p.id_B) for p in distances if p.distance < 0]
        return sorted({tuple(sorted((self._body_name(a), self._body_name(b)))) for a, b in pairs})

    def touching(self, q: np.ndarray, margin: float = CONTACT) -> list[tuple[str, str, float]]:
        """The body pairs under the scene's policy no farther apart than `margin` at q, as (name, name, signed
        distance), nearest first: a configuration whose geometry touches (distance 0, which HasCollisions calls
        free) can be left by no motion the certificate proves."""
        pairs = self.signed_distance_pairs(q, margin)
        named = {}
        for p in pairs:
            key = tuple(sorted((self._body_name(p.id_A), self._body_name(p.id_B))))
            named[key] = min(named.get(key, np.inf), p.distance)
        return sorted(((a, b, d) for (a, b), d in named.items() if d <= margin), key=lambda t: t[2])

    def _body_name(self, g) -> str:
        """A geometry's body, by scoped name; geometry anchored to the world (a custom scene's environment pieces)
        by its own name, not "world"."""
        frame = self._inspector.GetFrameId(g)
        if frame == self._inspector.world_frame_id():
            return self._inspector.GetName(g)
        return self.plant.GetBodyFromFrameId(frame).scoped_name().to_string()

    def frame_positions(self, Q: np.ndarray) -> np.ndarray:
        """World position of the passage frame's origin (no passage declared: the robot's last body's) for each
        configuration, (n, 3)."""
        Q = np.atleast_2d(np.asarray(Q, float))
        out = np.empty((len(Q), 3))
        with self._lock:
            for i, q in enumerate(Q):
                self.plant.SetPositions(self._ctx, self._positions(q))
                out[i] = self._tracked_frame.CalcPoseInWorld(self._ctx).translation()
        return out

    def in_passage(self, Q: np.ndarray) -> np.ndarray:
        """Whether each configuration puts the scene's passage frame inside a passage box."""
        Q = np.atleast_2d(np.asarray(Q, float))
        if self._passage_frame is None or not self.scene.passage_boxes or len(Q) == 0:
            return np.zeros(len(Q), bool)
        p = self.frame_positions(Q)
        return np.any([np.all((p >= lo) & (p <= hi), axis=1) for lo, hi in self.scene.passage_boxes], axis=0)

    def query_object(self, q: np.ndarray):
        """SceneGraph's QueryObject with the robot at q, under the scene's collision policy, for pictures and
        measurements that need Drake's own answers (not counted). Valid until the oracle's next query: one thread's
        use only."""
        with self._lock:
            self.plant.SetPositions(self._ctx, self._positions(np.asarray(q, float)))
            return self._query_port.Eval(self._ctx)

    def is_robot_geometry(self, geometry_id) -> bool:
        """Whether a SceneGraph geometry belongs to the robot (else to the environment)."""
        return geometry_id in self._robot_geometries

    def in_contact(self, q: np.ndarray) -> bool:
        """Whether a pair the scene's policy counts penetrates at q: HasCollisions, where the certificate needs no
        distances from Drake (it costs a third of signed_distance_pairs(q, 0) on a mesh robot); timed as a distance
        query."""
        with self._lock:
            start = time.perf_counter()
            hit = not self._raw_free(np.asarray(q, float)[None])[0]
            self.seconds["distances"] += time.perf_counter() - start
            return bool(hit)

    def pair_distances(self, q: np.ndarray, pairs: list) -> list:
        """SceneGraph's SignedDistancePair at q of each given pair of GeometryIds, however far apart (the
        certificate's direction for a pair it bounds itself); timed as a distance query."""
        with self._lock:
            start = time.perf_counter()
            query = self.query_object(q)
            found = [query.ComputeSignedDistancePairClosestPoints(a, b) for a, b in pairs]
            self.seconds["distances"] += time.perf_counter() - start
            return found

    def signed_distance_pairs(self, q: np.ndarray, max_distance: float) -> list:
        """SceneGraph's SignedDistancePairs at q of the pairs the scene's policy counts that lie within
        `max_distance` (farther pairs are left out)."""
        with self._lock:
            start = time.perf_counter()
            pairs = self.query_object(q).ComputeSignedDistancePairwiseClosestPoints(max_distance)
            self.seconds["distances"] += time.perf_counter() - start
            return pairs

    # ---- the workspace (not collision checks) --------------------------------------------------------------------
    @functools.cached_property
    def _robot_shapes(self) -> list:
        """(body, pose of the geometry in the body, geometry id) of each robot collision geometry, in a fixed order."""
        return [
            (self.plant.GetBodyFromFrameId(self._inspector.GetFrameId(g)), self._inspector.GetPoseInFrame(g), g)
            for g in sorted(self._robot_geometries, key=lambda g: g.get_value())
        ]

    @functools.cached_property
    def robot_kinematics(self):
        """Numpy forward kinematics of the robot's collision geometries, in `_robot_shapes` order
        (app.checking.kinematics), or None when a joint is not revolute, prismatic or weld."""
        from app.checking.kinematics import TreeKinematics

        return TreeKinematics.of(
            self.plant, [(body, X_BG) for body, X_BG, _ in self._robot_shapes], self.scene.position_map
        )

    def robot_geometry_centres(self, Q: np.ndarray, pieces: np.ndarray | None = None) -> np.ndarray:
        """World position of the centre of each robot collision geometry for each configuration, (n, G, 3); with
        `pieces` (n indices into that order), of that one piece of each configuration, (n, 3)."""
        Q = np.atleast_2d(np.asarray(Q, float))
        if self.robot_kinematics is not None:
            if pieces is None:
                return self.robot_kinematics.poses(Q)[1]
            return self.robot_kinematics.origins(Q, np.asarray(pieces, int))
        shapes = self._robot_shapes
        every = np.arange(len(shapes))
        out = np.empty((len(Q), len(shapes), 3))
        with self._lock:
            for i, q in enumerate(Q):
                self.plant.SetPositions(self._ctx, self._positions(q))
                for j in every if pieces is None else (int(pieces[i]),):
                    body, X_BG, _ = shapes[j]
                    out[i, j] = self.plant.EvalBodyPoseInWorld(self._ctx, body).multiply(X_BG.translation())
        return out if pieces is None else out[np.arange(len(Q)), np.asarray(pieces, int)]

    def robot_geometry_radii(self) -> np.ndarray:
        """Radius of the sphere about its centre that holds each robot collision geometry, (G,)."""
        return np.array(
            [np.linalg.norm(half_extent(self._inspector.GetShape(g), np.eye(3))) for _, _, g in self._robot_shapes]
        )

    @functools.cached_property
    def _environment(self) -> tuple[Polytopes, list, np.ndarray, np.ndarray]:
        """The environment, which does not move with the robot: its boxes and convex hulls as world-frame
        polytopes, and its other pieces (spheres, cylinders, ...) as geometry ids with the bounding spheres about
        their frames' origins, centres (k, 3) and radii (k,)."""
        from pydrake.geometry import Box, Convex, Mesh, Role

        faces, others = [], []
        with self._lock:
            query = self._query_port.Eval(self._ctx)
            for g in self._inspector.GetAllGeometryIds(Role.kProximity):
                if g in self._robot_geometries:
                    continue
                shape, X = self._inspector.GetShape(g), query.GetPoseInWorld(g)
                if isinstance(shape, Box):
                    loops = [
                        np.array(face) * (np.array([shape.width(), shape.depth(), shape.height()]) / 2)
                        for face in _BOX_FACES
                    ]
                elif isinstance(shape, (Convex, Mesh)):  # Drake's proximity engine uses a mesh's convex hull
                    vertices, data = hull_vertices(shape), shape.GetConvexHull().face_data()
                    loops, i = [], 0
                    while i < len(data):  # each face: its vertex count, then its vertices' indices
                        loops.append(vertices[np.asarray(data[i + 1 : i + 1 + data[i]], int)])
                        i += 1 + data[i]
                else:
                    others.append((g, X.translation(), np.linalg.norm(half_extent(shape, np.eye(3)))))
                    continue
                R, t = X.rotation().matrix(), X.translation()
                faces.append([loop @ R.T + t for loop in loops])
        centres = np.array([c for _, c, _ in others]).reshape(-1, 3)
        return Polytopes(faces), [g for g, _, _ in others], centres, np.array([r for _, _, r in others])

    def _point_distances(self, P: np.ndarray, reach: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The points (n, 3) and environment pieces within `reach` (n,) of each other: (point index, signed
        distance, unit gradient at the point), by point. Boxes and hulls in numpy, the same answers as SceneGraph's
        point queries at a fraction of their cost; other shapes by those queries, for the points their bounding
        spheres reach."""
        polytopes, others, centres, radii = self._environment
        found = polytopes.near(P, reach)
        if not others:
            return found
        ball = np.linalg.norm(P[:, None, :] - centres[None], axis=2) - radii
        asked = np.flatnonzero(np.any(ball <= reach[:, None] * (1 + 1e-9), axis=1))
        rows = []
        with self._lock:
            query = self._query_port.Eval(self._ctx)
            for i in asked.tolist():
                try:
                    answers = query.ComputeSignedDistanceToPoint(P[i], reach[i])
                except RuntimeError:
                    # Drake refuses a point query near some sliver hulls of decomposed meshes ("very sharp edge"):
                    # the other shapes near such a point go unseen; the gap search is a sampling heuristic.
                    continue
                rows += [(i, r.distance, r.grad_W) for r in answers if r.id_G in others]
        if not rows:
            return found
        points = np.concatenate([found[0], [i for i, _, _ in rows]]).astype(int)
        order = np.argsort(points, kind="stable")
        distance = np.concatenate([found[1], [d for _, d, _ in rows]])
        gradient = np.concatenate([found[2], np.array([g for _, _, g in rows]).reshape(-1, 3)])
        return points[order], distance[order], gradient[order]

    def environment_gaps(self, P: np.ndarray, width: float) -> np.ndarray:
        """Whether each workspace point (n, 3) lies free in a gap of the environment narrower than `width`: two
        obstacles on roughly opposite sides of it (their distance gradients more than 120 degrees apart) whose
        distances add up to less than `width` (`polytopes.gaps`).

        One of a gap's two obstacles lies within width/2 of the point, so the pieces within width/2 are found first;
        then, for a point free with one so near, those within `width` less the nearest distance (the farthest the
        other obstacle may be): the fewer pieces a point reaches, the less it costs."""
        P = np.atleast_2d(np.asarray(P, float))
        start = time.perf_counter()
        points, distance, _ = self._point_distances(P, np.full(len(P), width / 2))
        nearest = np.full(len(P), np.inf)
        np.minimum.at(nearest, points, distance)
        free = np.flatnonzero(np.isfinite(nearest) & (nearest > 0))
        points, distance, gradient = self._point_distances(P[free], width - nearest[free])
        gap = np.zeros(len(P), bool)
        gap[free] = gaps(points, distance, gradient, len(free), width)
        self.seconds["points"] += time.perf_counter() - start
        return gap


# The six faces of the box [-1, 1]^3, each a loop of corners around it.
_BOX_FACES = (
    [[(s, -1, -1), (s, 1, -1), (s, 1, 1), (s, -1, 1)] for s in (-1, 1)]
    + [[(-1, s, -1), (1, s, -1), (1, s, 1), (-1, s, 1)] for s in (-1, 1)]
    + [[(-1, -1, s), (1, -1, s), (1, 1, s), (-1, 1, s)] for s in (-1, 1)]
)


def half_extent(shape, rotation: np.ndarray) -> np.ndarray:
    """Half the size, along the world axes, of the box around a shape turned by `rotation` (3x3)."""
    from pydrake.geometry import Box, Capsule, Convex, Cylinder, Ellipsoid, Mesh, Sphere

    if isinstance(shape, Box):
        return np.abs(rotation) @ (np.array([shape.width(), shape.depth(), shape.height()]) / 2)
    if isinstance(shape, Sphere):
        return np.full(3, shape.radius())
    if isinstance(shape, (Cylinder, Capsule)):  # round about its z axis: a disc at each end (capsule: a sphere)
        axis = np.abs(rotation[:, 2])
        rim = np.sqrt(np.clip(1 - axis**2, 0, 1)) if isinstance(shape, Cylinder) else np.ones(3)
        return axis * shape.length() / 2 + rim * shape.radius()
    if isinstance(shape, Ellipsoid):
        return np.sqrt(rotation**2 @ np.array([shape.a(), shape.b(), shape.c()]) ** 2)
    if isinstance(shape, (Convex, Mesh)):
        points = hull_vertices(shape) @ rotation.T
        return np.abs(points).max(axis=0)
    return np.zeros(3)


def _splits(size: int) -> bool:
    """Whether batches of a size class (n.bit_length() == size) are large enough to split."""
    return 1 << (size - 1) >= _SPLIT_MIN


class _Paths:
    """The running cost per configuration of each batch path, for one size class of batch, and which path to take:
    the cheapest so far; each is tried first (_TRIES times), and the others are measured again in turn at the
    probe's calls (see _PROBE_FIRST)."""

    def __init__(self, paths):
        self.cost: dict[str, float | None] = dict.fromkeys(paths)
        self.tries: dict[str, int] = dict.fromkeys(paths, 0)
        self.calls = 0
        self.probes = 0
        self.probe_wait = _PROBE_FIRST  # calls from one probe to the next
        self.next_probe = _PROBE_FIRST  # the call that probes

    @property
    def settled(self) -> bool:
        """Every path has had its tries: calls from now on take the cheapest (but for probes)."""
        return all(self.tries.get(path, 0) >= _TRIES for path in self.cost)

    def choose(self) -> str:
        self.calls += 1
        for path in self.cost:
            if self.tries.get(path, 0) < _TRIES:
                return path
        best = min(self.cost, key=self.cost.get)
        if self.calls == self.next_probe:
            others = [path for path in self.cost if path != best]
            self.probes += 1
            return others[self.probes % len(others)]
        return best

    def measured(self, path: str, cost: float) -> None:
        """A call on `path` cost `cost` seconds per configuration. After a probe: wait twice as long for the next one
        if the probed path is still the dearer, else start probing over."""
        old, tries = self.cost.get(path), self.tries.get(path, 0)
        if old is None:
            self.cost[path] = cost
        else:  # (a slowed call is the usual outlier: the least of the tries)
            self.cost[path] = min(old, cost) if tries < _TRIES else 0.7 * old + 0.3 * cost
        self.tries[path] = tries + 1
        if self.calls == self.next_probe:
            dearer = self.cost[path] > min(self.cost.values())
            self.probe_wait = min(2 * self.probe_wait, _PROBE_MAX) if dearer else _PROBE_FIRST
            self.next_probe = self.calls + self.probe_wait


class _Helpers:
    """Processes, each with its own oracle of the same scene (`Scene.recipe`), that answer part of a batch by the raw
    loop while this process answers the rest: the raw loop's way onto more cores. Threads cannot share it (pydrake
    holds the GIL in HasCollisions), and Drake's threaded batch asks for signed distances
    (SceneGraphCollisionChecker's DoCheckContextConfigCollisionFree), which cost several times HasCollisions on mesh
    robots. They start in the background and are used once all are ready; one that fails (or dies) is given up, and
    this process answers alone. Their answers are the raw loop's, so the split changes no answer, only the time."""

    def __init__(self, recipe, count: int):
        self._recipe, self._count = recipe, count
        self._pipes: list = []
        self._processes: list = []
        self.state = "idle"  # then "starting", then "ready" or "failed"
        self.checked = False  # the oracle has held the ready helpers' answers to its own
        self._owner = os.getpid()  # the process that started them (set again by `start`)

    def start(self) -> None:
        import pickle
        import socket
        import subprocess
        import sys
        import weakref
        from multiprocessing.connection import Connection

        # A fresh interpreter, not multiprocessing's spawn: spawn runs the user's main script again in the child,
        # which a script without a `__main__` guard (most pydrake scripts) cannot survive. Its own session keeps a
        # terminal's Ctrl-C for the parent; a closed pipe (the parent gone) ends it.
        self._owner = os.getpid()
        try:
            for _ in range(self._count):
                ours, theirs = socket.socketpair()
                self._processes.append(
                    subprocess.Popen(
                        [sys.executable, "-c", f"from app.checking.oracle import _serve; _serve({theirs.fileno()})"],
                        pass_fds=(theirs.fileno(),),
                        stdin=subprocess.DEVNULL,
                        stdout=subprocess.DEVNULL,
                        stderr=subprocess.DEVNULL,
                        env={**os.environ, "PYTHONPATH": os.pathsep.join(path for path in sys.path if path)},
                        start_new_session=True,
                    )
                )
                theirs.close()
                self._pipes.append(Connection(ours.detach()))
                self._pipes[-1].send_bytes(pickle.dumps(self._recipe))
            self.state = "starting"
        except (OSError, pickle.PicklingError, AttributeError, TypeError):  # no processes here, or a recipe that
            self.give_up()  # does not pickle: the helpers started see their pipes close
        weakref.finalize(self, _stop, list(self._pipes), list(self._processes))

    def ready(self) -> bool:
        """Whether every helper has said it is ready (without waiting), and they are this process's: a forked copy of
        the parent must not talk on its pipes."""
        if self.state == "starting" and all(pipe.poll() for pipe in self._pipes):
            self.wait()
        return self.state == "ready" and os.getpid() == self._owner

    def wait(self) -> None:
        """Wait until every helper is ready or one has failed."""
        if self.state != "starting":
            return
        try:
            ok = all(pipe.recv_bytes() == b"ready" for pipe in self._pipes)
        except (EOFError, OSError):
            ok = False
        if ok:
            self.state = "ready"
        else:
            self.give_up()

    def free(self, Q: np.ndarray, raw_free) -> np.ndarray:
        """Free flags of Q (n, dim): the first part by raw_free here, the others in the helpers at the same time. A
        helper found gone has its part answered here, and the helpers are given up."""
        parts = np.array_split(np.arange(len(Q)), len(self._pipes) + 1)
        sent = []
        for pipe, part in zip(self._pipes, parts[1:]):
            try:
                pipe.send_bytes(_CONFIGURATIONS + np.ascontiguousarray(Q[part]).tobytes())
                sent.append(True)
            except OSError:
                sent.append(False)
        free = np.empty(len(Q), bool)
        free[parts[0]] = raw_free(Q[parts[0]])
        for pipe, part, ok in zip(self._pipes, parts[1:], sent):
            try:
                if not ok:
                    raise EOFError
                free[part] = np.frombuffer(pipe.recv_bytes(), bool)
            except (EOFError, OSError, ValueError):
                self.state = "failed"
                free[part] = raw_free(Q[part])
        if self.state == "failed":
            self.give_up()
        return free

    def edges_free(self, Q1: np.ndarray, Q2: np.ndarray, resolution: float, here) -> tuple[np.ndarray, int]:
        """Free flags of the edges Q1[i] -> Q2[i], in pieces handed to whoever is idle: the helpers, and
        `here(Q1, Q2)`, this process's own check. Returns (flags, the helpers' checks). A helper found gone has its
        pieces checked here, and the helpers are given up once every piece is in."""
        import pickle

        pieces = np.array_split(np.arange(len(Q1)), min(len(Q1), (len(self._pipes) + 1) * _PIECES))[::-1]
        free, checks = np.empty(len(Q1), bool), 0
        # Each helper's pieces in flight, oldest first: it holds the next while it checks one, so it does not idle
        # while this process finishes a piece of its own.
        busy: dict[int, list] = {i: [] for i in range(len(self._pipes))}

        def hand(i: int) -> None:
            piece = pieces.pop()
            try:
                self._pipes[i].send_bytes(_EDGES + pickle.dumps((Q1[piece], Q2[piece], resolution)))
            except OSError:
                self.state = "failed"
                pieces.append(piece)
            else:
                busy[i].append(piece)

        def collect(i: int) -> int:
            piece = busy[i].pop(0)
            try:
                free[piece], count = pickle.loads(self._pipes[i].recv_bytes())
                return count
            except (EOFError, OSError, pickle.UnpicklingError):
                self.state = "failed"
                pieces.append(piece)
                return 0

        try:
            while True:
                for i in busy:
                    while len(busy[i]) < _IN_FLIGHT and pieces and self.state == "ready":
                        hand(i)
                if pieces:
                    piece = pieces.pop()
                    free[piece] = here(Q1[piece], Q2[piece])
                elif any(busy.values()):
                    checks += collect(next(i for i in busy if busy[i]))  # nothing left here: wait for a helper
                else:
                    break
                for i in busy:
                    while busy[i] and self._pipes[i].poll():
                        checks += collect(i)
        finally:  # (here() may end the check early): every answer is read, so that the pipes stay in step
            for i in busy:
                while busy[i]:
                    collect(i)
            if self.state == "failed":
                self.give_up()
        return free, checks

    def give_up(self) -> None:
        """Never use the helpers again: their pipes close, which ends them."""
        self.state = "failed"
        for pipe in self._pipes:
            pipe.close()
        self._pipes = []


def _stop(pipes: list, processes: list) -> None:
    """End the helpers: a closed pipe ends a helper's loop; one that does not end within a second is killed."""
    import subprocess

    for pipe in pipes:
        pipe.close()
    for process in processes:
        try:
            process.wait(timeout=1.0)
        except subprocess.TimeoutExpired:
            process.kill()


def _serve(fd: int) -> None:
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
            if message[:1] == _CONFIGURATIONS:
                Q = np.frombuffer(message, offset=1).reshape(-1, oracle.space.dim)
                pipe.send_bytes(oracle._raw_free(Q).tobytes())
            else:
                Q1, Q2, resolution = pickle.loads(message[1:])
                checker = oracle.context()
                free = checker.edges_free(Q1, Q2, resolution, ends_free=True)
                pipe.send_bytes(pickle.dumps((free, checker.checks)))
    except Exception:  # the pipe closed, or the scene did not load here: the parent answers alone
        return
