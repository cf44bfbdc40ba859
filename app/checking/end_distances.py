"""The distances the certificate (app.checking.certify) weighs against its motion bound at the ends of its pieces:
Drake's where it computes a pair's distance exactly, lower bounds of our own (app.checking.shape_gaps) for the
others, asked for many configurations at once and cached per configuration.

Distances at the ends. Where a pair of the kind Drake computes by GJK is not settled without Drake's direction, it is
bounded along the direction Drake last gave for it (ends of one motion are near each other; mesh scenes) and,
failing that, Drake's direction is asked for that pair alone. Every distance is lowered by a rounding allowance
(1e-9 of the resolution).

max_distance. A query reports only the pairs within its max_distance D, so an unreported pair is at least D apart
at that end. Each end is queried with D just above half the largest B_PQ of the pieces it bounds: a pair
unreported at both ends then passes, and Drake computes no more pairs than the test needs (pairs of the GJK kind
count as unreported when their own bound is at least D). Where no counted pair is of a kind Drake computes exactly,
the pairwise query is not asked at all: it has a fixed cost (some 60 us a configuration on the UR3, with nothing
within D), GJK on a mesh's hull costs time per vertex besides, and our bounds cover every pair anyway, Drake's
direction being asked per pair where needed. A pair in contact cannot pass a piece even then: its lower bound is at
most 0, and only a configuration with such a bound is asked whether it is in contact (HasCollisions), so that its
pieces fail at once. Distances are cached per configuration, so ends shared by adjacent pieces, and by rounds of a
caller that retries, are asked once.
"""

from __future__ import annotations

import weakref
from typing import NamedTuple

import numpy as np

from app.checking.budget import poll
from app.checking.kinematics import TreeKinematics
from app.checking.motion_bound import MAX_DISTANCE_MARGIN, motion_bound
from app.checking.protocol import Checker
from app.checking.shape_gaps import PAIR_KEY, Poses, shape_gaps

# Shape pairs Drake computes signed distance for in closed form.
_EXACT = {
    frozenset(pair)
    for pair in [("Box",), ("Sphere",), ("Box", "Sphere"), ("Sphere", "Capsule"), ("Sphere", "Cylinder")]
}


class EndDistances:
    """The certificate's distances at configurations of one checker's oracle (the ends of its pieces), kept across
    calls (and across queries: a caller may hand it another query's checker, whose `distance_queries` it then counts
    in). A Certifier is one."""

    # Most (configuration, pair) rows one call to the gaps works on, to keep its arrays small.
    BATCH_ROWS = 1 << 17

    def __init__(self, checker: Checker):
        oracle = checker.oracle
        self.checker = checker
        self.bound = motion_bound(oracle)
        self._cache = {}  # configuration bytes -> PairDistances, or None where it collides
        self._rounding = 1e-9 * oracle.space.resolution
        geometry = _geometry(oracle)
        self._index_of_value, self._ids, self._rows, self._exact, self._gaps, self._ask_all = geometry[:6]
        self._robot, self._slot, self._kinematics, self._R, self._centres = geometry[6:]
        # The direction Drake last gave for each pair of the gaps (world frame), NaN before it gave one.
        self._recent = np.full((len(self._gaps.pairs), 3), np.nan)

    def at_ends(
        self,
        Q: np.ndarray,
        ends: list,
        by_end: np.ndarray,
        travel: np.ndarray,
        stop=None,
        reach: float = 1.0,
        local=None,
    ):
        """{s: its PairDistances, or None where it collides} for the ends (s, at Q) of the pieces (piece p's ends are
        Q[by_end[2p]] and Q[by_end[2p + 1]], its pair bounds travel[p]): each end asked at the largest max_distance of
        the pieces it bounds, and each pair there bounded until it reaches the largest of its bounds on those pieces
        (shared ends once) -- all `reach` times farther, for margins beyond the test's (Certifier.MARGIN_ASK), but with
        Drake's help only up to the test's own (see _bound_again). local: the motion bound's kinematics at Q
        (MotionBound.local), whose poses of the robot's shapes are then not computed again."""
        rows = np.argsort(by_end, kind="stable")
        ordered = by_end[rows]
        first = np.flatnonzero(np.concatenate([[len(rows) > 0], ordered[1:] != ordered[:-1]]))
        asked = by_end[rows[first]]
        limits, need = np.zeros(0), None
        if len(rows):
            pairs = self._rows[self._gaps.pairs]
            limits = np.maximum.reduceat(np.repeat(self.bound.max_distance(travel * reach), 2)[rows], first)
            if not self._ask_all:  # where Drake's query is cheap, settling pairs early saves nothing measurable
                from app.checking import kernels  # loads numba on first use (see there)

                need = kernels.largest_per_end(travel, rows // 2, first, pairs)
        poses = None
        if local is not None:
            robot_rows = self._rows[self._rows >= 0]
            poses = list(zip(local.rotations[asked][:, robot_rows], local.centres[asked][:, robot_rows]))
        found = self._distances(list(Q[asked]), limits.tolist(), need, stop, reach, poses)
        return dict(zip([ends[j] for j in asked.tolist()], found))

    def distances(self, q: np.ndarray, max_distance: float, pair_travel: np.ndarray | None = None) -> dict | None:
        """The distances the certificate uses at q, {frozenset of the pair's two GeometryIds: distance}, for the
        pairs closer than max_distance (those left out are at least that far apart); None if q collides. With
        pair_travel (rows, rows: the pieces' bounds, see _distances) a pair's bound stops where it reaches that."""
        pairs = self._rows[self._gaps.pairs]
        need = None if pair_travel is None else pair_travel[None, pairs[:, 0], pairs[:, 1]]
        end = self._distances([q], [max_distance], need)[0]
        if end is None:
            return None
        return {
            frozenset((self._ids[k // PAIR_KEY], self._ids[k % PAIR_KEY])): d
            for k, d in zip(end.keys.tolist(), end.distance.tolist())
        }

    def _distances(
        self, Q: list, limits: list, pair_travel: np.ndarray | None = None, stop=None, reach: float = 1.0, poses=None
    ) -> list:
        """For each configuration, the pairs within its limit (a PairDistances), from the cache when it was asked at
        a limit at least as large; None if it collides or lies outside the bounds. pair_travel[k, pair] (pairs of the
        gaps): the largest bound on the pair's change over the pieces configuration k ends; a pair's lower bound
        that reaches it at this end is enough for those pieces, given any positive one at their other end (so no
        tighter bound is sought); without it every pair below the limit is bounded as tightly as the certificate
        can. reach: how much farther than pair_travel bounds are sought, without Drake's help (see at_ends). stop:
        polled before each batch (a proof keeps to its query's time limit: among many pieces a batch is dear).
        poses: per configuration, the rotations and centres of the robot's shapes, where the caller has them."""
        keys = [np.asarray(q, float).tobytes() for q in Q]
        todo = []
        for k, (key, q, limit) in enumerate(zip(keys, Q, limits)):
            cached = self._cache.get(key, False)
            if cached is False or (cached is not None and cached.limit < limit):
                travel = None if pair_travel is None else pair_travel[k]
                todo.append((key, np.asarray(q, float), limit, travel, None if poses is None else poses[k]))
        per_batch = max(1, self.BATCH_ROWS // max(1, len(self._gaps.pairs)))
        for first in range(0, len(todo), per_batch):
            poll(stop)
            self._ends(todo[first : first + per_batch], reach)
        return [self._cache[key] for key in keys]

    def _ends(self, todo: list, reach: float = 1.0) -> None:
        """Into the cache: the certificate's distances at each (key, q, limit, pair travel, robot poses or None) of
        `todo` -- Drake's for the pairs it computes exactly, our lower bound for the others (a pair left out is at
        least `limit` apart); None where q is out of bounds or in contact. reach: see _distances."""
        for key, *_ in todo:
            self._cache[key] = None
        inside = self.checker.space.within_bounds(np.array([q for _, q, *_ in todo]))
        todo = [item for item, keep in zip(todo, inside.tolist()) if keep]
        reported = self._reported(todo)
        if reported is None:
            return
        drake = [todo[k] for k in reported.kept.tolist()]
        limits = np.array([limit for _, _, limit, *_ in drake])
        Q = np.array([q for _, q, *_ in drake])
        # What settles each pair (see _distances): its bound over the pieces, with room for the rounding allowance.
        if drake[0][3] is None:
            travel, reach = np.repeat(limits[:, None], len(self._gaps.pairs), axis=1), 1.0
        else:
            travel = np.array([item[3] for item in drake]).reshape(len(drake), -1)
        need, helped = (travel * factor * MAX_DISTANCE_MARGIN + 2 * self._rounding + 1e-12 for factor in (reach, 1))
        poses = self._poses_at(Q, [item[4] for item in drake])
        near_k, near_pair, bounds = self._gaps.near(poses, reported.nhat, limits, need)
        self._bound_again(Q, near_k, near_pair, bounds, reported.nhat, need, helped, poses)
        # A configuration in contact stays None: its pieces fail at once (a bound at or below 0 could only fail them
        # by cutting them down to the floor).
        doubtful = np.unique(near_k[bounds <= 0]).tolist()
        in_contact = {k for k in doubtful if self.checker.in_contact(Q[k])}
        self._store(drake, reported, near_k, near_pair, bounds, limits, in_contact)

    def _reported(self, todo: list) -> _Reported | None:
        """What Drake reports at the configurations of `todo` (see _ends), those it finds in contact left out; None
        where it finds all of them in contact. Drake's pairs of every configuration as rows (configuration, first,
        second geometry, distance); reading a GeometryId costs more than the distance, so each is read once and
        mapped through its integer value. Without the pairwise query Drake is asked nothing yet: where every pair's
        lower bound comes out positive nothing touches, and only a configuration with a bound at or below 0 is asked
        about contact (at the end of _ends)."""
        if not self._ask_all:
            self.checker.count_bounded(len(todo))
            none = np.zeros(0, np.int64)
            nhat = np.full((len(todo), len(self._gaps.pairs), 3), np.nan)
            return _Reported(np.arange(len(todo)), none, none.reshape(0, 2), none, none.astype(bool), none * 0.0, nhat)
        answers = [self.checker.signed_distances(q, limit) for _, q, limit, *_ in todo]
        value = self._index_of_value
        found = np.array(
            [(value[p.id_A.get_value()], value[p.id_B.get_value()], p.distance) for pairs in answers for p in pairs],
            float,
        ).reshape(-1, 3)
        config = np.repeat(np.arange(len(answers)), [len(pairs) for pairs in answers])
        touching = np.zeros(len(answers), bool)
        touching[config[found[:, 2] <= 0]] = True
        kept = np.flatnonzero(~touching)
        if not len(kept):
            return None
        # Renumber the configurations left, 0..len(kept)-1.
        renumber = np.full(len(answers), -1)
        renumber[kept] = np.arange(len(kept))
        position = np.flatnonzero(renumber[config] >= 0)
        config, found = renumber[config[position]], found[position]
        index = found[:, :2].astype(np.int64)
        swapped = index[:, 0] > index[:, 1]
        index.sort(axis=1)  # a pair is the same whichever geometry Drake names first
        keys = index[:, 0] * PAIR_KEY + index[:, 1]
        exact = self._exact[index[:, 0], index[:, 1]]
        # Drake's separating directions, for the pairs of the gaps only.
        flat = [p for pairs in answers for p in pairs]
        directions = np.array([flat[j].nhat_BA_W for j in position[~exact].tolist()], float).reshape(-1, 3)
        nhat = self._directions(len(kept), config[~exact], keys[~exact], swapped[~exact], directions)
        return _Reported(kept, config, index, keys, exact, found[:, 2], nhat)

    def _poses_at(self, Q: np.ndarray, given: list) -> Poses:
        """The poses of every geometry of the gaps in configurations Q: the environment's rotations from the start,
        the robot's per configuration (given: the robot shapes' rotations and centres per configuration, or None
        where the caller has none), and every shape's centre (see ShapeGaps.offset), not its frame's origin."""
        robot = self._slot >= 0
        centres = np.repeat(self._centres[None], len(Q), axis=0)
        if all(pose is not None for pose in given):
            rotations = np.array([R for R, _ in given])
            centres[:, robot] = [c for _, c in given]
        else:
            rotations, origins = self._robot_poses(Q)
            centres[:, robot] = origins + np.einsum("nrij,rj->nri", rotations, self._gaps.offset[robot])
        return Poses(centres, self._R, np.ascontiguousarray(rotations), self._slot)

    def _bound_again(self, Q, near_k, near_pair, bounds, nhat, need, helped, poses: Poses) -> None:
        """Raises `bounds` (rows near_k, near_pair of the gaps, in place) where Drake gave no direction and they do
        not reach `need`. A pair Drake's query left out is farther apart than the limit by Drake's reckoning, but
        without Drake's direction our bound can fall far below that: alternating projections converge slowly
        between long shapes side by side (the UR3's upper arm and torch 9.8 mm apart were bounded at -2.4 mm), and
        such a pair fails every piece down to the floor. So those pairs not settled are bounded again: along the
        direction Drake last gave for the pair (ends of one motion are near each other, and any direction gives a
        lower bound), then, where that is not enough either, along Drake's direction for the pair alone -- asked
        only below `helped`, the test's own need, which `need` exceeds where margins are sought: a margin is worth
        a bound of our own, not a Drake query (on the welding cell they were 30 % of its pair queries)."""

        def tighten(rows, directions):
            """Bound rows again along these directions; the rows still short of what Drake is asked for."""
            k, pair = near_k[rows], near_pair[rows]
            bounds[rows] = np.maximum(bounds[rows], self._gaps.along(k, pair, poses, directions))
            return rows[bounds[rows] < helped[k, pair]]

        rows = np.flatnonzero(np.isnan(nhat[near_k, near_pair, 0]) & (bounds < need[near_k, near_pair]))
        known = np.isfinite(self._recent[near_pair[rows], 0]) if not self._ask_all else np.zeros(len(rows), bool)
        rows = np.concatenate([tighten(rows[known], self._recent[near_pair[rows[known]]]), rows[~known]])
        rows = rows[bounds[rows] < helped[near_k[rows], near_pair[rows]]]
        if len(rows):
            asked = np.empty((len(rows), 3))
            for k in np.unique(near_k[rows]).tolist():
                mine = np.flatnonzero(near_k[rows] == k)
                pairs = self._gaps.pairs[near_pair[rows[mine]]].tolist()
                replies = self.checker.pair_distances(Q[k], [(self._ids[i], self._ids[j]) for i, j in pairs])
                for r, (i, _), answer in zip(mine.tolist(), pairs, replies):
                    # Drake's direction from the pair's second geometry to its first, in our order.
                    direction = answer.nhat_BA_W if answer.id_A == self._ids[i] else -answer.nhat_BA_W
                    asked[r] = self._recent[near_pair[rows[r]]] = direction
            tighten(rows, asked)

    def _store(self, drake: list, reported: _Reported, near_k, near_pair, bounds, limits, in_contact: set) -> None:
        """Into the cache, for each configuration of `drake` (the items of _ends' todo that Drake's query kept) not
        in contact, its PairDistances: Drake's exact distances and our bounds below the limit, sorted by key."""
        below = bounds < limits[near_k]
        near_k, near_pair, bounds = near_k[below], near_pair[below], bounds[below]
        exact = reported.exact
        config = np.concatenate([reported.config[exact], near_k])
        index = np.concatenate([reported.index[exact], self._gaps.pairs[near_pair]])
        keys = np.concatenate([reported.keys[exact], self._gaps.keys[near_pair]])
        distance = np.concatenate([reported.distance[exact], bounds]) - self._rounding
        order = np.lexsort((keys, config))
        rows = self._rows[index[order]]
        keys, distance, row_a, row_b = keys[order], distance[order], rows[:, 0].copy(), rows[:, 1].copy()
        bounds = np.concatenate([[0], np.cumsum(np.bincount(config, minlength=len(drake)))]).tolist()
        for k, (key, _, limit, *_) in enumerate(drake):
            if k not in in_contact:
                part = slice(bounds[k], bounds[k + 1])
                self._cache[key] = PairDistances(limit, keys[part], distance[part], row_a[part], row_b[part])

    def _robot_poses(self, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rotations (n, robots, 3, 3) and centres (n, robots, 3) of the robot geometries at configurations Q."""
        if self._kinematics is not None:
            return self._kinematics.poses(Q)
        rotations, centres = [], []
        for q in Q:
            query = self.checker.oracle.query_object(q)
            poses = [query.GetPoseInWorld(g) for g in self._robot]
            # Copied now: Drake's poses are views into the query's cache, which the next configuration overwrites.
            rotations.append(np.array([X.rotation().matrix() for X in poses]))
            centres.append(np.array([X.translation() for X in poses]))
        return np.reshape(rotations, (len(Q), -1, 3, 3)), np.reshape(centres, (len(Q), -1, 3))

    def _directions(self, configurations: int, config, keys, swapped, directions) -> np.ndarray:
        """Drake's separating directions (nhat_BA_W) of the GJK-kind pairs it reported -- rows of (configuration,
        pair key, whether Drake named the pair's geometries the other way round, direction) -- as (configurations,
        pairs of the gaps, 3), turned to point from the pair's second geometry to its first in our order; NaN where
        not reported."""
        at = np.searchsorted(self._gaps.keys, keys)  # the gaps' keys are sorted (pairs in lexicographic order)
        if np.any(at >= len(self._gaps.keys)) or np.any(self._gaps.keys[at.clip(max=len(self._gaps.keys) - 1)] != keys):
            raise RuntimeError("Drake reported a pair the certificate does not count (collision policy mismatch)")
        nhat = np.full((configurations, len(self._gaps.keys), 3), np.nan)
        nhat[config, at] = np.where(swapped[:, None], -1.0, 1.0) * directions
        return nhat


class PairDistances(NamedTuple):
    """Distances at one end of a piece: the pairs within `limit`, by key, sorted."""

    limit: float
    keys: np.ndarray
    distance: np.ndarray
    row_a: np.ndarray
    row_b: np.ndarray

    def nearest(self) -> float:
        """The least distance of a pair here (the limit if none is reported)."""
        return min(float(self.distance.min()), self.limit) if len(self.distance) else self.limit


class _Reported(NamedTuple):
    """What Drake's query reported at the configurations it did not find in contact (kept: their indices in the
    query, renumbered 0.. in that order): a row a pair -- its configuration, geometry indices (smaller first), key,
    whether Drake computes its distance exactly, and the distance; and Drake's directions for the pairs of the
    gaps, (configurations, pairs, 3), NaN where it gave none."""

    kept: np.ndarray
    config: np.ndarray
    index: np.ndarray
    keys: np.ndarray
    exact: np.ndarray
    distance: np.ndarray
    nhat: np.ndarray


class _Geometry(NamedTuple):
    """What EndDistances knows of an oracle's geometries, the same for every certifier on it (see _geometry)."""

    index_of_value: dict  # a small integer per geometry, by its GeometryId's value (cheaper to hash than the id)
    ids: list
    rows: np.ndarray  # the motion bound's row per geometry, -1: environment
    exact: np.ndarray  # (geometries, geometries): whether Drake computes the pair's distance exactly
    gaps: object  # the ShapeGaps of the other counted pairs
    ask_all: bool  # whether Drake's pairwise query is asked (see _geometry)
    robot: list  # the robot's geometries, in robot slots
    slot: np.ndarray  # per geometry, its robot slot (-1: environment)
    kinematics: TreeKinematics | None  # the robot geometries' poses
    R: np.ndarray  # every geometry's rotation at the start (the environment's never change)
    centres: np.ndarray  # and its shape's centre (see ShapeGaps.offset)


# Per shared oracle, its _Geometry, made once (a certifier is made per query); gone with the oracle.
_per_oracle: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _geometry(oracle) -> _Geometry:
    """The oracle's _Geometry, made once per oracle."""
    if oracle in _per_oracle:
        return _per_oracle[oracle]
    from pydrake.geometry import Role

    bound = motion_bound(oracle)
    inspector = oracle.model.scene_graph().model_inspector()
    geometries = inspector.GetAllGeometryIds(Role.kProximity)
    rows = np.array([bound.row(g) for g in geometries], np.int64)
    kinds = [type(inspector.GetShape(g)).__name__ for g in geometries]
    exact = np.array([[frozenset((a, b)) in _EXACT for b in kinds] for a in kinds], bool)
    gaps = shape_gaps(oracle, geometries, rows >= 0, exact)
    # Whether Drake's pairwise query is asked, for every pair within the limit with its direction: where a counted
    # pair is of a kind Drake computes exactly (its distance is used). Otherwise most pairs are settled by our bounds
    # alone, and Drake is asked for the direction of the others, one pair at a time, and where a bound comes out at
    # or below 0 whether anything is in contact (see the module doc and EndDistances._ends).
    robot = rows >= 0
    counted = np.triu(robot[:, None] | robot[None, :], 1) & exact
    if not oracle.scene.self_collisions:
        counted &= ~(robot[:, None] & robot[None, :])
    ask_all = any(not inspector.CollisionFiltered(geometries[i], geometries[j]) for i, j in zip(*np.nonzero(counted)))
    # Shape poses for the gaps: the environment's never change; the robot's are taken per configuration, in robot
    # slots (slot -1: environment).
    robot_geometries = [g for g, r in zip(geometries, rows.tolist()) if r >= 0]
    slot = np.full(len(geometries), -1)
    slot[robot] = np.arange(len(robot_geometries))
    plant = oracle.plant
    kinematics = TreeKinematics.of(
        plant,
        [(plant.GetBodyFromFrameId(inspector.GetFrameId(g)), inspector.GetPoseInFrame(g)) for g in robot_geometries],
        oracle.scene.position_map,
    )
    query = oracle.query_object(oracle.scene.start)
    poses = [query.GetPoseInWorld(g) for g in geometries]
    R = np.array([X.rotation().matrix() for X in poses]).reshape(-1, 3, 3)
    p = np.array([X.translation() for X in poses]).reshape(-1, 3)
    centres = p + np.einsum("gij,gj->gi", R, gaps.offset)
    geometry = _Geometry(
        {g.get_value(): i for i, g in enumerate(geometries)},
        list(geometries),
        rows,
        exact,
        gaps,
        ask_all,
        robot_geometries,
        slot,
        kinematics,
        R,
        centres,
    )
    _per_oracle[oracle] = geometry
    return geometry
