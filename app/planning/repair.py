"""Repair a stored roadmap after its cell changed, instead of building it again (dynamic roadmaps: Leven and
Hutchinson 2002; Jaillet and Siméon 2004): only the verdicts a change can affect are set back to unknown.

What changed is told from the two cells themselves, not from the change's wording: their collision geometries are
compared by name, shape and placement (an obstacle in the world, a robot geometry on its body), so an obstacle
removed, added or moved, and an object attached to or detached from the robot, are all the same question.

Which verdicts a change can affect, by a conservative test on bounding volumes (no collision check):
- A robot geometry g moves along an edge by at most travel_g(|q_b - q_a| / 2) from where it is at the edge's
  midpoint (app.checking.motion_bound: a bound on every point of g per unit of each coordinate, anywhere in the
  space), so everything g sweeps along the edge lies in the ball about its centre there of its own radius plus that
  travel. A node's balls are the same with no travel.
- An edge decided free (or part-checked) can collide in the new cell only where a ball of the new robot reaches an
  obstacle added there, or where a robot geometry added (a payload) reaches anything it is checked against: an
  obstacle's box, or another robot geometry's ball. Those verdicts become unknown; a later query checks them again
  when its search needs them (lazily).
- An edge known to collide can be free in the new cell only where a ball of the old robot reached an obstacle
  removed, or where a robot geometry removed (a payload put down) reached anything: those become unknown too.
- A node whose balls reach an added obstacle, or which carries an added robot geometry at all, is checked again
  (one collision check each); a node that collides leaves the roadmap with its edges.
Obstacles are taken by their world-aligned bounding boxes (app.scene.shapes.half_extent), which hold them.

The balls are coarse where the arm is long and the edge is long, so the test resets more than the change needs, never
less. The certificate never rests on these verdicts (it proves every answer in the process that returns it).
"""

import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass

import numpy as np

from app.checking.motion_bound import motion_bound
from app.planning.roadmap_file import rounded, shape_bytes
from app.scene.shapes import half_extent

# How far a robot point may move along the shortest piece of an edge asked (m): its balls exceed what the robot
# sweeps along it by at most this.
PIECE_TRAVEL = 0.01
# The most parts a piece of an edge is cut into at once.
SPLIT_MAX = 8
# Pieces asked at once, so that a block's arrays stay in the processor's cache; blocks are spread over the oracle's
# threads (numpy's arithmetic leaves the interpreter lock).
BLOCK = 4096


@dataclass
class RepairRecord:
    """What a repair did: the change (as data), the verdicts it set back to unknown, the nodes it checked again and
    dropped, its collision checks and seconds."""

    change: list
    described: str
    edges_reset: int  # decided free (or part-checked), now unknown
    colliding_reset: int  # known to collide, now unknown
    nodes_checked: int
    nodes_dropped: int
    collision_checks: int
    seconds: float

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass
class _Geometry:
    """The collision geometries of a cell, by what they are, with what a repair needs of them."""

    robot: dict  # key -> geometry id (robot)
    environment: dict  # key -> geometry id (obstacle)


def _geometries(oracle) -> _Geometry:
    """The oracle's collision geometries keyed by name, shape and placement: an obstacle by its pose in the world,
    a robot geometry by its body and its pose on it."""
    from pydrake.geometry import Role

    inspector = oracle.model.scene_graph().model_inspector()
    query = oracle.query_object(oracle.scene.start)
    robot, environment = {}, {}
    for g in inspector.GetAllGeometryIds(Role.kProximity):
        shape = shape_bytes(inspector.GetShape(g))
        name = inspector.GetName(g).rpartition("::")[2]
        if oracle.is_robot_geometry(g):
            body = oracle.plant.GetBodyFromFrameId(inspector.GetFrameId(g)).scoped_name().to_string()
            robot[(body, name, shape, rounded(inspector.GetPoseInFrame(g).GetAsMatrix34()))] = g
        else:
            environment[(name, shape, rounded(query.GetPoseInWorld(g).GetAsMatrix34()))] = g
    return _Geometry(robot, environment)


def _boxes(oracle, ids) -> tuple[np.ndarray, np.ndarray]:
    """World-aligned boxes (lo, hi), (k, 3) each, that hold the obstacles `ids`."""
    inspector = oracle.model.scene_graph().model_inspector()
    query = oracle.query_object(oracle.scene.start)
    lo, hi = [], []
    for g in ids:
        X = query.GetPoseInWorld(g)
        half = half_extent(inspector.GetShape(g), X.rotation().matrix())
        lo.append(X.translation() - half)
        hi.append(X.translation() + half)
    return np.reshape(lo, (-1, 3)), np.reshape(hi, (-1, 3))


class _Sweeps:
    """Balls that hold each robot geometry of one cell, at configurations or along edges."""

    def __init__(self, oracle):
        workspace = oracle.workspace
        self.ids = [g for _, _, g in workspace.robot_shapes]
        self.radii = workspace.robot_geometry_radii()
        bound = motion_bound(oracle)
        self.rates = bound.rates[[bound.row(g) for g in self.ids]]  # (G, dim), in `ids` order
        # A geometry no coordinate moves (a cart, a base) meets a change nowhere or everywhere: not along an edge.
        # (Everywhere would put the scene's start in collision, which `CellRoadmap.changed` refuses first.)
        self.moving = self.rates.any(axis=1)
        self._workspace, self.space = workspace, oracle.space

    def balls(self, A: np.ndarray, B: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(centres (n, G, 3), radii (n, G)) of balls holding each robot geometry at configurations A, or all along
        the edges A[i] -> B[i]."""
        if B is None or not len(A):
            return self._workspace.robot_geometry_centres(A).reshape(len(A), -1, 3), np.tile(self.radii, (len(A), 1))
        half = self.space.difference(A, B) / 2
        middle = self.space.wrap(A + half)
        return self._workspace.robot_geometry_centres(middle), self.radii + np.abs(half) @ self.rates.T

    def travel(self, D: np.ndarray) -> np.ndarray:
        """The farthest any robot point moves along motions of differences D (n, dim): (n,)."""
        return (np.abs(D) @ self.rates.T).max(axis=1, initial=0.0)


def _box_distances(centres, lo, hi) -> np.ndarray:
    """The distance from each point (n, G) to the nearest box (k): (n, G), infinite with no box."""
    nearest = np.full(centres.shape[:2], np.inf)
    for a, b in zip(lo, hi):
        nearest = np.minimum(nearest, np.linalg.norm(np.maximum(0.0, np.maximum(a - centres, centres - b)), axis=-1))
    return nearest


def _checked_pairs(oracle, ids: list) -> np.ndarray:
    """checked[i, j]: whether the robot geometries ids[i] and ids[j] are checked against each other."""
    inspector = oracle.model.scene_graph().model_inspector()
    matrix = np.asarray(oracle.checker.GetFilteredCollisionMatrix())
    body = [int(oracle.plant.GetBodyFromFrameId(inspector.GetFrameId(g)).index()) for g in ids]
    checked = matrix[np.ix_(body, body)] == 0
    np.fill_diagonal(checked, False)
    return checked


class _Side:
    """One cell's side of a change: its robot's balls, which of its robot geometries the other cell lacks, the boxes
    of its obstacles the other cell lacks and of all its obstacles."""

    def __init__(self, oracle, own: _Geometry, other: _Geometry, pool: ThreadPoolExecutor):
        self.sweeps, self._pool = _Sweeps(oracle), pool
        index = {g: i for i, g in enumerate(self.sweeps.ids)}
        self.robot_only = [index[g] for key, g in own.robot.items() if key not in other.robot]
        self.only = _boxes(oracle, [g for key, g in own.environment.items() if key not in other.environment])
        self.every = _boxes(oracle, list(own.environment.values()))
        checked = _checked_pairs(oracle, self.sweeps.ids)
        # The robot geometries this side lacks on the other, each with those it is checked against.
        self.pairs = [(p, h) for p in self.robot_only for h in np.flatnonzero(checked[p])]
        bound = motion_bound(oracle)
        rows = [bound.row(g) for g in self.sweeps.ids]
        self.pair_rates = np.array([bound.pair_rates[rows[p], rows[h]] for p, h in self.pairs]).reshape(
            len(self.pairs), oracle.space.dim
        )

    def reaches(self, A: np.ndarray, B: np.ndarray | None = None) -> np.ndarray:
        """Whether what this side has and the other lacks can touch the robot at configurations A (or along edges
        A -> B). An edge is asked with one ball per geometry first; where those reach, it is cut into pieces and
        they are asked, and so on until the pieces that still reach are so short that no robot point moves more than
        PIECE_TRAVEL along them (a long edge's ball is mostly travel; its pieces hug what it sweeps, near the change
        only). A piece is cut into as many parts as its balls' travel exceeds their room at its middle (2 to
        SPLIT_MAX), so that its parts mostly pass at once where halving would take several rounds. A piece whose
        balls come within PIECE_TRAVEL of the change at its middle, with no travel, settles its edge at once: the
        pieces about that point would come as near."""
        if B is None:
            return self._blocks(A, None)[0]
        hit = np.zeros(len(A), bool)
        D = self.sweeps.space.difference(A, B)
        edge, t0, t1 = np.arange(len(A)), np.zeros(len(A)), np.ones(len(A))
        while len(edge):
            P0, P1 = A[edge] + t0[:, None] * D[edge], A[edge] + t1[:, None] * D[edge]
            near, there, shortfall = self._blocks(P0, P1)
            short = self.sweeps.travel(P1 - P0) <= PIECE_TRAVEL
            hit[edge[there | (near & short)]] = True
            split = near & ~short & ~hit[edge]
            parts = np.clip(np.ceil(shortfall[split]), 2, SPLIT_MAX).astype(int)
            edge, t0, t1 = np.repeat(edge[split], parts), np.repeat(t0[split], parts), np.repeat(t1[split], parts)
            k = np.arange(len(edge)) - np.repeat(np.cumsum(parts) - parts, parts)
            parts = np.repeat(parts, parts)
            t0, t1 = t0 + (t1 - t0) * k / parts, np.where(k + 1 == parts, t1, t0 + (t1 - t0) * (k + 1) / parts)
        return hit

    def _blocks(self, A: np.ndarray, B: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """`_reaches`, asked BLOCK rows at a time over the pool's threads: the same answers row by row."""
        if len(A) <= BLOCK:
            return self._reaches(A, B)
        blocks = [slice(i, i + BLOCK) for i in range(0, len(A), BLOCK)]
        answers = self._pool.map(lambda b: self._reaches(A[b], None if B is None else B[b]), blocks)
        return tuple(np.concatenate(column) for column in zip(*answers))

    def _reaches(self, A: np.ndarray, B: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """`reaches` with one ball per robot geometry and configuration or edge (its middle): (with the travel
        along the edge, within PIECE_TRAVEL at the middle alone, by what factor the travel exceeds the room)."""
        if not len(A):
            return np.zeros(0, bool), np.zeros(0, bool), np.zeros(0)
        centres, grown = self.sweeps.balls(A, B)
        rest = np.broadcast_to(self.sweeps.radii, grown.shape)
        moving = self.sweeps.moving
        own = [g for g in self.robot_only if moving[g]]
        # How far each ball's centre is from what it must not reach; a pair's distance is between the balls' surfaces.
        distance = np.full(grown.shape, np.inf)
        distance[:, moving] = _box_distances(centres[:, moving], *self.only)
        distance[:, own] = np.minimum(distance[:, own], _box_distances(centres[:, own], *self.every))
        if self.pairs:
            # A pair's distance changes along the piece by no more than its relative travel (the joints the two
            # chains share move both alike), far less than the two geometries' travels in the world.
            p, h = np.array(self.pairs).T
            half = np.zeros_like(A) if B is None else np.abs(self.sweeps.space.difference(A, B)) / 2
            gap = np.linalg.norm(centres[:, p] - centres[:, h], axis=-1) - rest[:, p] - rest[:, h]
            distance = np.hstack([distance, gap])
            rest, grown = np.hstack([rest, np.zeros_like(gap)]), np.hstack([grown, half @ self.pair_rates.T])
        near = np.any(distance <= grown, axis=1)
        there = np.any(distance <= rest + PIECE_TRAVEL, axis=1)
        room = distance - rest
        with np.errstate(divide="ignore", invalid="ignore"):
            shortfall = np.max(np.where(room > 0, (grown - rest) / room, np.inf), axis=1, initial=0.0)
        return near, there, shortfall

    @property
    def changed(self) -> bool:
        return bool(self.robot_only) or len(self.only[0]) > 0


def repair(arrays: dict, old_oracle, new_oracle, context) -> tuple[dict, np.ndarray, dict]:
    """The roadmap `arrays` (Roadmap.arrays) of old_oracle's cell repaired for new_oracle's (the same robot's
    coordinates): (arrays with the verdicts a change can affect set back to unknown, the mask of nodes that stay,
    counts). Nodes are checked again through `context` (a new_oracle context, which counts them)."""
    old_geometry, new_geometry = _geometries(old_oracle), _geometries(new_oracle)
    with ThreadPoolExecutor(new_oracle.threads) as pool:
        gone = _Side(old_oracle, old_geometry, new_geometry, pool)
        come = _Side(new_oracle, new_geometry, old_geometry, pool)
        return _repaired(arrays, gone, come, context)


def _repaired(arrays: dict, gone: _Side, come: _Side, context) -> tuple[dict, np.ndarray, dict]:
    """`repair` with each cell's side of the change."""
    Q, ends = arrays["Q"], arrays["ends"]
    alive, checked, progress = arrays["alive"], arrays["checked"], arrays["progress"]
    A, B = Q[ends[:, 0]], Q[ends[:, 1]]
    free_like = alive & (checked | (progress > 0))
    dead = ~alive
    reset_free, reset_dead = np.zeros(len(ends), bool), np.zeros(len(ends), bool)
    if come.changed and free_like.any():
        rows = np.flatnonzero(free_like)
        reset_free[rows] = come.reaches(A[rows], B[rows])
    if gone.changed and dead.any():
        rows = np.flatnonzero(dead)
        reset_dead[rows] = gone.reaches(A[rows], B[rows])
    keep = np.ones(len(Q), bool)
    asked = np.flatnonzero(come.reaches(Q)) if come.changed else np.empty(0, int)
    if len(asked):
        keep[asked] = context.are_free(Q[asked])
    repaired = dict(arrays)
    repaired["alive"] = alive | reset_dead
    repaired["checked"] = checked & ~(reset_free | reset_dead)
    repaired["progress"] = np.where(reset_free | reset_dead, 0, progress)
    repaired["proved"] = arrays["proved"] & ~(reset_free | reset_dead)
    counts = {
        "edges_reset": int(reset_free.sum()),
        "colliding_reset": int(reset_dead.sum()),
        "nodes_checked": len(asked),
        "nodes_dropped": int((~keep).sum()),
    }
    return repaired, keep, counts


def timed_repair(arrays, old_oracle, new_oracle, context, changes) -> tuple[dict, np.ndarray, RepairRecord]:
    """`repair`, with its record: the changes, what was reset, checks and seconds."""
    started, checks = time.perf_counter(), context.checks
    repaired, keep, counts = repair(arrays, old_oracle, new_oracle, context)
    record = RepairRecord(
        change=[c.to_dict() for c in changes],
        described="; ".join(c.describe() for c in changes),
        collision_checks=int(context.checks - checks),
        seconds=time.perf_counter() - started,
        **counts,
    )
    return repaired, keep, record
