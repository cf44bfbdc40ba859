"""The planner: one query on a lazy PRM whose key samples come from a narrow-passage sampler.

    endpoints checked -> the straight motion -> uniform samples, then, once they stall, narrow-passage samples too
    (the sampler's walks and placements in workspace gaps), in rounds until start and goal connect -> roadmap
    (k-nearest; lazy edge checks for a single query) -> shortest path -> smoothed, proved and repaired
    (app.planning.refine) -> timed along a blended curve (app.motion.timing)

`plan(oracle, PlanSettings(...))` runs one `Query` through those stages and returns a PlanResult
(app.planning.result). What its budget covers: app.planning.settings.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from app.checking.budget import MAX_SECONDS, BudgetSpent, Stop, spell_checks
from app.errors import NoPath, SamplerBudgetExceeded, UserError
from app.motion.path import path_length, verify
from app.motion.timing import check_duration, scaled_limits, time_path
from app.motion.trajectory import Trajectory
from app.planning.endpoints import check_endpoint, check_goals
from app.planning.refine import Refined, Refinement
from app.planning.result import Ledger, PlanResult, PlanStats, Smoothing
from app.planning.settings import NARROW_RAMP, POCKET_ROUNDS, PlanSettings, default_step
from app.planning.sources import Samples

# Pockets (`Query._expand_pockets`): a side of the query is shut in when its component holds under this share of the
# roadmap's nodes; it then grows by this many motions a round, recorded as the source EXPANSION.
POCKET_SHARE = 0.1
EXTENSIONS = 16
EXPANSION = "expansion"


def plan(oracle, settings: PlanSettings | None = None, *, start=None, goal=None, via=None, cancel=None) -> PlanResult:
    """Plan from start to goal (default: the scene's) with `settings` (default: PlanSettings()); `via`: waypoints
    of the easy route to try instead of the straight motion (an arm's tool line, app.planning.ik.tool_line).

    Returns a PlanResult; raises InvalidEndpoint for a bad start or goal, NoPath (with `.details`, Query.figures)
    when the samples or the budget run out before start and goal connect (code PREEMPTED when `cancel`, a
    threading.Event, was set from another thread; TIMED_OUT when the time limit ran out), UserError for bad
    parameters. A KeyboardInterrupt (Ctrl-C) while the query runs leaves it with the same `.details`."""
    return Query(oracle, settings or PlanSettings(), start=start, goal=goal, via=via, cancel=cancel).solve()


class Query:
    """One planning query in explicit stages, as OMPL splits its PRM (setup / grow / solve):

    setup (the constructor): endpoints checked, samplers made, start and goal put in the roadmap, the budget's stop
    started; `straight(stop)`: the easy route first -- the straight motion from start to goal (or the polyline
    through the caller's `via` points), checked at the resolution; `grow(narrow, uniform, stop)`: one round of
    samples, added and connected to their k nearest neighbours; `search(stop)`: the shortest roadmap path whose
    edges are free, or None while start and goal are apart; then the path is smoothed, proved and repaired
    (`refinement`, app.planning.refine) and timed (`time`); `solve()`: the loop that runs them and answers.

    How much narrow-passage effort a query spends is decided from what the roadmap shows. The straight motion is
    tried first. Then rounds of cheap uniform samples with lazy edges (nothing is checked until a candidate path
    uses it): they alone solve the open queries (the UR3's, most of the tunnel's, the Panda's everyday ones) for a
    few hundred checks. The narrow-passage sources -- their workspace-gap search and their walks cost several times
    a uniform round -- join only once the uniform rounds stall, which is measured after every round that leaves
    start and goal apart, on the graph of edges not known to collide (`_uniform_stalled`, `_pockets`):

    - both the start's and the goals' components hold POCKET_SHARE of the roadmap's nodes or more: each side has
      surroundings the rounds explored, and every candidate path between them collided. A passage uniform samples
      rarely hit is in the way (bar, maze, tunnel), and more of them only grow both sides: the narrow-passage
      sources join from the next round.
    - a side's component holds fewer (its candidate edges out collided): it is shut in a pocket, as the Panda's
      grasp poses in a shelf or box are, which uniform samples landing closer to it may open. Uniform rounds go on,
      up to POCKET_ROUNDS of them, then the narrow-passage sources join (the cage, window, welding pockets). Every
      round meanwhile, the pocket grows out as RRT grows a tree (`_expand_pockets`): motions from its nodes toward
      uniform samples, each checked, so the checks spent there decide edges.

    Once on, they join every round: narrow/NARROW_RAMP samples at first, doubling each round up to narrow/4, so a
    query that needs few pays for few and one that needs many spends at most twice what it needed. The tests count
    nodes and rounds, nothing timed, so a seed escalates at the same round on any machine.

    Three quarters of every narrow round (`workspace`) are placed rather than walked to: configurations with a piece
    of the robot in a narrow gap of the workspace (app.samplers.workspace). The walkers find a passage wherever
    obstacles leave one, but in a passage narrow in many dimensions they end on the obstacles' faces; placements go
    straight to the gap, and the walkers still cover passages with no workspace gap behind them (the maze's window).
    What each source adds: the ablation (`bench ablation`, docs/paper.md). With the sampler "adaptive", the narrow
    rounds' checks are shared among placements and the narrow-passage samplers in shares learned from what each
    one's samples achieve per check (app.planning.sources.Mixture; the reward: `_reward`).

    `full_roadmap` is the paper's protocol instead: one round of all `narrow` + `uniform` samples, every edge
    checked, then the query."""

    def __init__(
        self,
        oracle,
        settings: PlanSettings,
        *,
        start=None,
        goal=None,
        via=None,
        cancel=None,
        roadmap=None,
        certifier=None,
    ):
        # The roadmap and samplers pull in scipy: imported when a query is made, not at CLI start-up.
        from app.planning.roadmap import GOAL, START, Roadmap

        # The query's own counters on the shared oracle, and its budget, which runs from now: the endpoint checks
        # count against it, and it bounds every counted call from solve() on (handed to each as its `stop`).
        self.oracle, self.settings = oracle, settings
        self.checker = checker = oracle.context()
        self.stop = Stop(settings.budget, checker, cancel)
        self.ledger = Ledger(checker)
        self.step = oracle.space.check_step(default_step(oracle.scene) if settings.step is None else settings.step)

        self.clearance = settings.clearance
        self.start = check_endpoint(checker, oracle.scene.start if start is None else start, "start", self.clearance)
        self.goals = check_goals(checker, oracle.scene.goal if goal is None else goal, self.clearance)
        self.goal = self.goals[0]  # until the query has reached one of them
        self.ledger.checks.endpoints = self.ledger.elapsed()[1]
        if settings.timing:  # limits scaled so far down that even the straight motion would take days: refused now
            limits = scaled_limits(oracle.scene, settings.velocity_scale, settings.acceleration_scale)
            nearest = self.goals[np.argmin(oracle.space.distance(self.start, self.goals))]
            check_duration(oracle.space.unwrap(np.array([self.start, nearest])), *limits)
        # The easy route: the straight motion, or the polyline through `via`.
        via = [] if via is None or len(via) == 0 else np.atleast_2d(np.asarray(via, float))
        via = [oracle.space.check_configuration(q, "via point") for q in via]
        outside = [fault for q in via for fault in oracle.space.out_of_bounds(q)]
        if outside:
            raise UserError(f"via point out of bounds: {outside[0]}")
        self.via = via
        self.route = np.vstack([self.start, *via, self.goal])

        # On a stored roadmap the query draws the very samples a fresh query with its seed draws (drawn from a stream
        # of their own, its rounds once cost more than no roadmap: benchmark pages). A sample the roadmap holds
        # already (the same query again) is not added twice (`grow`).
        seeds = np.random.SeedSequence(settings.seed).spawn(5)
        workspace = 0.0 if settings.full_roadmap else settings.workspace  # a full roadmap places none
        self.samples = Samples(checker, settings.sampler, self.step, seeds, workspace, settings.sampler_params)
        self.rounds = 0
        # Narrow-passage samples from the round after the first one that left start and goal apart.
        self.narrow_from_round: int | None = 1 if settings.full_roadmap else None
        # A single query checks only the edges its candidate paths use; a full roadmap is checked whole. A persistent
        # roadmap (app.planning.cell) is handed in with every verdict it holds, and answers this query's checker.
        if roadmap is None:
            roadmap = Roadmap(
                checker, k=settings.k, skip_connected=settings.skip_connected, lazy=not settings.full_roadmap
            )
        roadmap.checker = checker
        self.roadmap = roadmap
        before = len(roadmap)
        self.start_node = roadmap.node(self.start, START)
        self.goal_nodes = [roadmap.node(g, GOAL) for g in self.goals]
        # Endpoints are connected with the first round's samples, or at once where the roadmap has nodes already.
        self._unconnected = list(dict.fromkeys([self.start_node, *self.goal_nodes]))
        self._searchable = before > 0
        # On a stored roadmap, the fresh query's roadmap beside it (`FreshShadow`): it decides when the query
        # escalates and where it grows out of pockets, and every edge it proposes or decides is the stored roadmap's
        # too, so the query connects no later than the fresh query would.
        self._shadow = FreshShadow(self, roadmap) if self._searchable else None
        self.refinement = Refinement(checker, roadmap, settings, self.ledger, seeds[2], certifier)
        # What a shared certifier had spent before this query: the answer reports only this query's share.
        self._certificate_before = certifier.seconds if certifier is not None else 0.0
        self.stopped: str | None = None  # why the query's work ended early: "time", "checks" or "cancelled"
        # Per node, the source that drew it ("" for nodes the query did not draw).
        self._source_of = np.full(len(roadmap), "", object)
        self._sides: tuple[np.ndarray, np.ndarray] | None = None  # see `_apart`
        self._expansion_rng = np.random.default_rng(seeds[4])
        self._expansion = {"samples": 0, "tried": 0, "checks": 0}  # what `_expand_pockets` drew and spent

    # ---- the easy route -----------------------------------------------------------------------------------------
    def straight(self, stop: Stop) -> bool:
        """Whether an easy route (the straight motion from start to a goal, or the polyline through `via`; the
        nearest goal first) is free at the resolution (one batched edge check each; the certificate then proves it
        between the checked points); it is then `route`, and its goal `goal`. Via points are checked too: only the
        endpoints are known free."""
        resolution = self.roadmap.resolution
        for g in self.goals[np.argsort(self.checker.space.distance(self.start, self.goals), kind="stable")]:
            R = np.vstack([self.start, *self.via, g])
            free = self.ledger.run(
                "search", self.checker.edges_free, R[:-1], R[1:], resolution, ends_free=len(R) == 2, stop=stop
            )
            if free.all():
                self.route, self.goal = R, g
                return True
        return False

    # ---- grow -------------------------------------------------------------------------------------------------------
    def round_sizes(self) -> tuple[int, int] | None:
        """How many narrow and uniform samples the next round draws, or None when the query may draw no more."""
        s = self.settings
        if s.full_roadmap:
            return (s.narrow, s.uniform) if self.rounds == 0 else None
        if s.narrow == 0 and s.uniform == 0:
            return None
        if self.narrow_from_round is None or self.rounds + 1 < self.narrow_from_round:
            return 0, math.ceil(s.uniform / 4)
        k = self.rounds + 1 - self.narrow_from_round
        return min(math.ceil(s.narrow / 4), math.ceil(s.narrow / NARROW_RAMP) * 2**k), math.ceil(s.uniform / 4)

    def grow(self, narrow: int, uniform: int, stop: Stop) -> np.ndarray:
        """One round: draw the samples, add them as nodes (the first round also connects start and goal) and
        connect the new nodes to their neighbours. Returns the new nodes."""
        self.rounds += 1
        try:
            drawn = self.ledger.run("sampling", self.samples.draw, narrow, uniform, stop)
        except SamplerBudgetExceeded as exc:
            raise self._failure(f"no path on {self.checker.scene.name}: {exc}", sampler=str(exc)) from None
        roadmap = self.roadmap
        added = [(source, roadmap.add(Q[roadmap.unseen(Q)], kind, connect=False)) for kind, source, Q in drawn]
        self._source_of = np.concatenate(
            [self._source_of, *(np.full(len(nodes), source, object) for source, nodes in added)]
        )
        new = np.concatenate([np.array(self._unconnected, int), *(nodes for _, nodes in added)])
        self._unconnected = []
        self.ledger.run("roadmap", self.roadmap.connect, new, stop)
        if self._shadow is not None:
            self._shadow.grow(drawn, stop)
        self._reward(new)
        return new

    # ---- search -----------------------------------------------------------------------------------------------------
    def search(self, stop: Stop) -> list[int] | None:
        """Node indices of the shortest start-goal path whose edges are checked free, or None while start and goal
        are apart. Once the certificate has refused a roadmap edge of a careful (fine-only) query, the path's edges
        are checked at the fine resolution too and those failing it are dropped: a cheap filter where many edges
        slip between checked points, work for nothing where the certificate proves them all (benchmark pages)."""
        roadmap, refinement = self.roadmap, self.refinement
        while True:
            nodes = self.ledger.run("search", roadmap.shortest_path, self.start_node, self.goal_nodes, stop)
            if nodes is None or not (refinement.fine_only and refinement.unproved_edges):
                return nodes
            ok = self.ledger.run("search", verify, self.checker, roadmap.Q[nodes], refinement.fine, stop)
            if ok.all():
                return nodes
            for i in np.flatnonzero(~ok):
                roadmap.remove_edge(nodes[i], nodes[i + 1])

    def search_and_refine(self, stop: Stop, proving: Stop, first: list[int] | None = None) -> Refined | None:
        """A roadmap path smoothed and proved (app.planning.refine) once start and goal connect, else None: the
        optimistic pass first; once the certificate has refused a roadmap path, careful (fine-only) passes, whose
        roadmap paths are proved before any smoothing is spent on them, and whose unprovable edges leave the
        roadmap while the search goes on. `first`: a path of edges checked free to try before searching."""
        refinement = self.refinement
        while True:
            nodes, first = (self.search(stop) if first is None else first), None
            if nodes is None:
                return None
            if not refinement.fine_only:
                path, shortcuts, repairs, certificate = refinement.smooth_and_prove(nodes, stop, proving)
                if certificate is not None:
                    return Refined(nodes, path, shortcuts, repairs, False, certificate)
                refinement.fine_only = True
                continue
            raw_proof = refinement.prove_roadmap_path(nodes, stop, proving)
            if raw_proof is None:
                continue
            path, shortcuts, repairs, certificate = refinement.smooth_and_prove(nodes, stop, proving, raw_proof)
            if certificate is None:  # the roadmap path is the answer
                return Refined(nodes, self.roadmap.Q[nodes], shortcuts, repairs, True, raw_proof)
            return Refined(nodes, path, shortcuts, repairs, False, certificate)

    # ---- time -------------------------------------------------------------------------------------------------------
    def time(self, path: np.ndarray, stop: Stop, proved: bool = False) -> Trajectory:
        """Toppra along the path with its corners blended where the blends can be proved (app.motion.timing);
        proved: the path's edges are certified already (by this query's certifier), so only the blends need to be,
        unless its blended curve is (certify_blends), whose radii are then used."""
        blends = self.refinement.blends
        if blends is None or blends.failed or not np.array_equal(blends.path, path):
            blends = None
        s = self.settings
        try:
            return self.ledger.run(
                "timing",
                time_path,
                self.checker,
                path,
                s.dt,
                certifier=self.refinement.certifier,
                edges_proved=proved and blends is None,
                proof=blends,
                clearance=self.clearance,
                velocity_scale=s.velocity_scale,
                acceleration_scale=s.acceleration_scale,
                stop=stop,
            )
        except (RuntimeError, ValueError) as exc:  # Toppra infeasible, or limits that are not positive
            raise self._failure(
                f"path found on {self.checker.scene.name} but not time-parameterized: {' '.join(str(exc).split())}"
            ) from None

    # ---- solve ------------------------------------------------------------------------------------------------------
    def solve(self) -> PlanResult:
        """The easy route (straight, or through `via`) if it is free and proved; else grow round by round until start
        and goal connect, then smooth, certify and time the path. The budget's time limit bounds all of it; its
        check limit bounds the search and smoothing, not the proof and timing (they ask for distances, not
        checks: the `proving` stop)."""
        stop = self.stop
        proving = stop.without_check_limit()
        try:
            found = self._find(stop, proving)
            if found is not None:
                return self.refinement.prove(self._result, found, proving)
        except BudgetSpent as spent:
            self.stopped = spent.reason
        except KeyboardInterrupt as interrupt:
            # Ctrl-C stays an interrupt (the command line answers PREEMPTED, exit code 130), carrying what the query
            # had spent, as a failure's NoPath.details does.
            interrupt.details = self.figures("interrupted").to_json()
            raise
        if self.refinement.proof_unfinished:
            raise self._failure(
                f"a path was found on {self.checker.scene.name} but proving and timing it did not finish within the "
                f"budget {self.settings.budget} ({self.stopped}): a larger time budget lets it finish"
            )
        raise self._not_connected()

    def _find(self, stop: Stop, proving: Stop) -> tuple[str, Refined] | None:
        """How the path was found ("straight" or "via", else "roadmap") and the path smoothed and proved, or None
        when the samples run out first; BudgetSpent when the budget does."""
        if self.straight(stop):
            path = self.route
            certificate = self.refinement.prove(self.refinement.certify, path, proving)
            if certificate.proved:  # else the roadmap may find a route it can prove
                nodes = [self.start_node, self.goal_nodes[self._goal_index(self.goal)]]
                return ("via" if self.via else "straight"), Refined(nodes, path, None, 0, False, certificate)
        found = None
        if self._searchable:  # a persistent roadmap: search what it holds before drawing any sample
            self.ledger.run("roadmap", self.roadmap.connect, np.array(self._unconnected, int), stop)
            self._unconnected = []
            found = self.search_and_refine(stop, proving)
        sizes = None if found is not None else self.round_sizes()
        while sizes is not None:
            self.grow(*sizes, stop)
            found = self._search_round(stop, proving)
            if found is not None:
                break
            self._apart()
            if self.narrow_from_round is None and self._uniform_stalled():
                self.narrow_from_round = self.rounds + 1
            self._expand_pockets(stop)
            sizes = self.round_sizes()
        return None if found is None else ("roadmap", found)

    def _search_round(self, stop: Stop, proving: Stop) -> Refined | None:
        """A round's search (`search_and_refine`); on a stored roadmap with the fresh query's beside it
        (`FreshShadow`), whose search runs every round. While the query is easy (no narrow samples yet), the stored
        roadmap's search goes first and the fresh query's only if it found nothing: a path through stored nodes is
        usually found for a few checks. Once narrow samples are on, the fresh query's goes first: the rounds are
        many and fail mostly, and the stored roadmap's search then takes what it decided rather than disproving
        the same candidate paths again; a path it found is tried first."""
        shadow = self._shadow
        if shadow is None:
            return self.search_and_refine(stop, proving)
        if self.narrow_from_round is not None and self.rounds >= self.narrow_from_round:
            return self.search_and_refine(stop, proving, shadow.search(stop))
        found = self.search_and_refine(stop, proving)
        if found is None:
            path = shadow.search(stop)
            if path is not None:  # rare: its edges are the stored roadmap's, whose search found none first
                found = self.search_and_refine(stop, proving, path)
        return found

    def _expand_pockets(self, stop: Stop) -> None:
        """After a search that left start and goal apart: grow the start's side, or the goals', where it is shut in
        a pocket -- its component of edges not known to collide holds under POCKET_SHARE of the roadmap -- as RRT
        grows a tree (OMPL's PRM has the same expand phase): EXTENSIONS times, from the side's node nearest a uniform
        sample, a motion of at most the sampler's step toward it, checked; a free one adds its end as a node, joined
        by that edge and offered lazy edges to its neighbours. A grasp pose deep in a shelf has every candidate edge
        blocked by the shelf, and samples rarely fall close enough to it to help: the tree walks out of the pocket
        (MotionBenchMaker's bookshelves), and the checks it spends each decide an edge."""
        from app.planning.roadmap import UNIFORM

        shadow, space = self._shadow, self.checker.space
        graph = self.roadmap if shadow is None else shadow.graph  # the roadmap that judges pockets
        before = self.checker.checks
        grown, stored = [], []  # the nodes grown, in `graph` and in the stored roadmap
        for members in self._pockets():
            targets = space.uniform(self._expansion_rng, EXTENSIONS)
            for target in targets:
                d = space.distance(graph.Q[members], target)
                near = int(members[np.argmin(d)])
                reach = min(1.0, self.step / max(float(d.min()), 1e-12))
                q = space.wrap(graph.Q[near] + reach * space.difference(graph.Q[near], target))
                self._expansion["tried"] += 1
                free = self.ledger.run(
                    "sampling", self.checker.edges_free, graph.Q[[near]], q[None], graph.resolution, stop=stop
                )
                if free[0]:
                    node = graph.extend(near, q, UNIFORM)
                    members = np.append(members, node)
                    grown.append(node)
                    stored.append(node if shadow is None else shadow.extended(near, node))
        self._expansion["checks"] += self.checker.checks - before
        if grown:
            self._expansion["samples"] += len(grown)
            self._source_of = np.concatenate([self._source_of, np.full(len(stored), EXPANSION, object)])
            self.ledger.run("roadmap", self.roadmap.connect, np.array(stored), stop)
            if shadow is not None:
                shadow.connect(np.array(grown), stop)

    def _uniform_stalled(self) -> bool:
        """After a round that left start and goal apart: whether uniform samples alone have stalled (the class
        docstring says why): neither start nor the goals are shut in a pocket (`_pockets`), or POCKET_ROUNDS rounds
        have passed with one of them shut in."""
        return self.rounds >= POCKET_ROUNDS or not self._pockets()

    def _pockets(self) -> list[np.ndarray]:
        """The nodes of each side of the query (the start's; the goals') shut in a pocket: its component of edges not
        known to collide holds under POCKET_SHARE of the roadmap's nodes, so its candidate edges out have collided.
        On a stored roadmap, judged on the fresh query's roadmap beside it, and given as its nodes."""
        if self._shadow is None:
            graph, start, goals = self.roadmap, self.start_node, self.goal_nodes
        else:
            graph, start, goals = self._shadow.graph, self._shadow.start, self._shadow.goals
        labels = graph.labels()
        sizes = np.bincount(labels)
        out = []
        for side in ([start], goals):
            mine = np.unique(labels[side])
            if sizes[mine].sum() < POCKET_SHARE * len(graph):
                out.append(np.flatnonzero(np.isin(labels, mine)))
        return out

    def _apart(self) -> None:
        """After a search that left start and goal apart: remember which nodes the start's and the goals' components
        of edges not known to collide hold, for the next round's rewards (`_reward`)."""
        if self.samples.mixture is None:
            return
        labels = self.roadmap.labels()
        self._sides = (labels == labels[self.start_node], np.isin(labels, labels[self.goal_nodes]))

    def _reward(self, new: np.ndarray) -> None:
        """Teach the mixture what a round's samples (`new`, just connected) achieved: a reward for each that lies
        between the start's side and a goal's, where the last search left them apart.

        Hybrid PRM rewards a sample that makes a new component or merges two: visibility a roadmap that checks every
        edge knows. A lazy one decides only the edges of the candidate paths it tries, and after a search that found
        no path, every candidate edge between the start's component and the goals' has been found to collide: the
        passage lies between them. A new sample with candidate edges to both sides lies in that gap of the roadmap,
        and the next search tries the paths through it; a sample with neighbours on one side only is one more in a
        region the roadmap already covers."""
        if self.samples.mixture is None or self._sides is None or not len(new):
            return
        start_side, goal_side = self._sides
        old = len(start_side)
        E = self.roadmap.edges()
        E = E[(E[:, 1] >= old) & (E[:, 0] < old)]  # new node (the larger index) to a node the last search knew
        near_start = np.zeros(len(self.roadmap), bool)
        near_goal = near_start.copy()
        near_start[E[start_side[E[:, 0]], 1]] = True
        near_goal[E[goal_side[E[:, 0]], 1]] = True
        between = np.flatnonzero(near_start & near_goal)
        sources, counts = np.unique(self._source_of[between], return_counts=True)
        self.samples.reward({str(s): float(c) for s, c in zip(sources, counts) if s})

    def _sources_on(self, nodes: list[int]) -> dict[str, int]:
        """How many of the path's nodes each source drew (nodes the query did not draw left out)."""
        drawn = [str(self._source_of[i]) for i in nodes if i < len(self._source_of) and self._source_of[i]]
        return {name: drawn.count(name) for name in sorted(set(drawn))}

    def _goal_index(self, q: np.ndarray) -> int:
        return int(np.argmin(self.checker.space.distance(q, self.goals)))

    # ---- answers ----------------------------------------------------------------------------------------------------
    def figures(self, stopped: str | None = None) -> PlanStats:
        """What the query has spent so far, counted as a success answer counts it; `stopped`: why it stopped (else
        the budget's reason: "time", "checks", "cancelled", or None)."""
        seconds, spent = self.ledger.elapsed()
        certifier = self.refinement.certifier
        return PlanStats(
            collision_checks=spent,
            distance_queries=self.checker.distance_queries,
            point_queries=self.checker.point_queries,
            checks=dataclasses.replace(self.ledger.checks),
            seconds=dataclasses.replace(self.ledger.seconds, total=seconds),
            certificate_seconds=0.0 if certifier is None else certifier.seconds - self._certificate_before,
            rounds=self.rounds,
            narrow_from_round=self.narrow_from_round,
            roadmap=self.roadmap.stats(),
            sampler_stats={
                **self.samples.record(),
                **({EXPANSION: dict(self._expansion)} if self._expansion["tried"] else {}),
            },
            budget=str(self.settings.budget),
            stopped=stopped or self.stopped,
        )

    def _failure(self, message: str, **details) -> NoPath:
        """NoPath with the query's figures in `details`. Its code says why: PREEMPTED when cancelled, TIMED_OUT when
        the time limit ended it (MoveIt's code for time), else PLANNING_FAILED -- a spent check limit too, whose
        details say stopped: "checks"."""
        code = {"cancelled": "PREEMPTED", "time": "TIMED_OUT"}.get(self.stopped)
        error = NoPath(message, code)
        error.details = {**self.figures().to_json(), **details}
        return error

    def _not_connected(self) -> NoPath:
        stats, s = self.roadmap.stats(), self.settings
        sizes = self.roadmap.component_sizes(self.start_node, *self.goal_nodes)
        seconds, spent = self.ledger.elapsed()
        if self.stopped == "cancelled":
            ending = ", cancelled"
        elif self.stopped == "checks":
            ending = (
                f"; budget of {s.budget.checks} collision check{'s' if s.budget.checks != 1 else ''} spent (stopped: "
                f"checks): a larger one may find a path, try --budget {s.budget.larger(seconds)}"
            )
        elif self.stopped == "time" and s.budget.checks is not None:
            ending = (
                f", stopped by the budget's {s.budget.seconds:g} s before its {s.budget.checks} checks were spent: "
                "on a faster or less loaded machine the same seed may get further; --budget "
                f"{spell_checks(s.budget.checks)},nolimit lets the checks alone decide"
            )
        elif self.stopped == "time":
            ending = (
                f"; time limit of {s.budget.seconds:g} s spent (stopped: time): try a longer one, e.g. --budget "
                f"{min(MAX_SECONDS, 10 * s.budget.seconds):g}s"
            )
        else:
            ending = "; the roadmap may not grow further"
        unproved = self.refinement.unproved_edges
        if unproved:
            ending += f"; {unproved} edge(s) checked free but not provably free were dropped"
        return self._failure(
            f"no path from start to goal on {self.checker.scene.name}: roadmap of {stats.nodes} nodes "
            f"({stats.narrow_nodes} narrow-passage samples from {s.sampler}, {stats.uniform_nodes} uniform), "
            f"start and goal not joined by edges checked free; {stats.edges_tried} edges decided, {spent} "
            f"collision checks, {seconds:.1f} s, {self.rounds} round(s)" + ending,
            components_of_start_goal=sizes,
            unproved_edges=unproved,
        )

    def _result(self, found: tuple[str, Refined], proving: Stop) -> PlanResult:
        from app.planning.roadmap import NARROW, WORKSPACE

        route, (nodes, path, shortcuts, repairs, dropped, certificate) = found
        roadmap, s = self.roadmap, self.settings
        raw = self.route if route != "roadmap" else roadmap.Q[nodes]
        self.goal = self.goals[self._goal_index(raw[-1])]
        smoothing = Smoothing(
            raw_length=path_length(self.checker, raw),
            length_after=path_length(self.checker, path),
            shortcuts=shortcuts,
            repairs=repairs,
            fine_only=self.refinement.fine_only,
            dropped=dropped,
        )
        certificate = dataclasses.replace(certificate, unproved_edges=self.refinement.unproved_edges)
        trajectory = self.time(path, proving, certificate.proved) if s.timing else None
        return PlanResult(
            scene=self.checker.scene.name,
            sampler=s.sampler,
            seed=int(s.seed),
            step=self.step,
            start=self.start,
            goal=self.goal,
            path=path,
            roadmap_path=raw,
            trajectory=trajectory,
            route=route,
            via=len(self.via),
            stats=self.figures(),
            smoothing=smoothing,
            certificate=certificate,
            narrow_on_path=int(sum(roadmap.kinds[i] == NARROW for i in nodes)),
            workspace_on_path=int(sum(roadmap.kinds[i] == WORKSPACE for i in nodes)),
            sources_on_path=self._sources_on(nodes),
            graph=roadmap,
            path_nodes=list(nodes),
            blends=self.refinement.blends if certificate.blended else None,
        )


class FreshShadow:
    """Beside a query on a stored roadmap, the roadmap the fresh query with the same seed grows: the same start,
    goals and samples (the query's own, drawn once), connected, searched and grown out of pockets as the fresh query
    does, with only its own verdicts. It decides what the query decides from the graph -- when narrow samples join
    (`Query._uniform_stalled`) and which pockets grow (`Query._pockets`) -- and every edge it proposes or decides is
    handed to the stored roadmap (`Roadmap.propose`, `Roadmap.learn`), whose search then holds the fresh query's
    graph and more in every round. So the query connects no later than the fresh query would, for at most the fresh
    query's checks plus its own searches through the stored nodes (its sampling is the fresh query's).

    Without it, a sample joined to its nearest among all nodes, mostly stored ones, misses the edges to the query's
    other samples that the fresh query's path uses, and pockets judged on the whole roadmap grow elsewhere (benchmark
    pages, "A stored roadmap against none"). Its search takes the stored roadmap's free verdicts
    (`Roadmap.free_elsewhere`), not its collisions: one known in advance steers the search off the paths it would
    check, and the pockets would differ."""

    def __init__(self, query: Query, stored):
        from app.planning.roadmap import GOAL, START, Roadmap

        s = query.settings
        self.query, self.stored = query, stored
        self.graph = Roadmap(query.checker, k=s.k, skip_connected=s.skip_connected, lazy=True)
        # Its search takes an edge the stored roadmap has checked free as checked: it was checked once.
        self.graph.free_elsewhere = lambda P: np.logical_and(*stored.known(self.stored_of[P]))
        self.stored_of = np.empty(0, np.int64)  # per node of `graph`, the stored roadmap's node at it
        self.start = self._node(query.start, START, query.start_node)
        self.goals = [self._node(g, GOAL, n) for g, n in zip(query.goals, query.goal_nodes)]
        self._unconnected = list(dict.fromkeys([self.start, *self.goals]))
        self._handed = np.zeros(0, bool)  # per pair of `graph`, whether its verdict went to the stored roadmap

    def _node(self, q: np.ndarray, kind: str, stored: int) -> int:
        size = len(self.graph)
        node = self.graph.node(q, kind)
        if len(self.graph) > size:
            self.stored_of = np.append(self.stored_of, stored)
        return node

    def grow(self, drawn: list, stop: Stop) -> None:
        """A round's samples (`Samples.draw`'s, already in the stored roadmap) added and connected."""
        added = []
        for kind, _, Q in drawn:
            Q = Q[self.graph.unseen(Q)]
            added.append(self.graph.add(Q, kind, connect=False))
            self.stored_of = np.concatenate([self.stored_of, self.stored.indices(Q)])
        new = np.concatenate([np.array(self._unconnected, int), *added])
        self._unconnected = []
        self.connect(new, stop)

    def connect(self, nodes: np.ndarray, stop: Stop) -> None:
        """Connect nodes as the fresh query does, and propose its new edges to the stored roadmap."""
        first = len(self.graph.pairs())
        self.query.ledger.run("roadmap", self.graph.connect, nodes, stop)
        self.stored.propose(self.stored_of[self.graph.pairs(first)])

    def search(self, stop: Stop) -> list[int] | None:
        """The fresh query's search of its roadmap, its verdicts handed to the stored roadmap: the path it found as
        the stored roadmap's nodes, or None (also where the stored roadmap holds one of its edges colliding: checked
        the other way round, or decided before this query)."""
        nodes = self.query.ledger.run("search", self.graph.shortest_path, self.start, self.goals, stop)
        decided, free = self.graph.verdicts()
        new = decided.copy()
        new[: len(self._handed)] &= ~self._handed
        self.stored.learn(self.stored_of[self.graph.pairs()[new]], free[new])
        self._handed = decided
        if nodes is None:
            return None
        path = self.stored_of[nodes]
        decided, free = self.stored.known(np.column_stack([path[:-1], path[1:]]))
        return path.tolist() if (decided & free).all() else None

    def extended(self, near: int, node: int) -> int:
        """The stored roadmap's node for `node`, which `Query._expand_pockets` grew in this graph from `near` by a
        free motion: added there too, joined the same way."""
        from app.planning.roadmap import UNIFORM

        stored = self.stored.extend(int(self.stored_of[near]), self.graph.Q[node], UNIFORM)
        self.stored_of = np.append(self.stored_of, stored)
        return stored
