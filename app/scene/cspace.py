"""The configuration space: bounds, metric and straight motions, in numpy alone (no Drake).

Coordinates are a robot's joint positions. Each has a weight -- the lever arm it swings, so that metres and radians
compare -- and an angle without joint limits is *continuous*: it lives on a circle, wraps into [-pi, pi), and
differences take the short way round. Every distance, step and interpolation in the project is measured here, so
samplers, roadmap, path and timing agree on what "straight" and "how far" mean.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np

from app.errors import UserError


@dataclass(frozen=True, eq=False)
class ConfigurationSpace:
    """A scene's coordinates: their bounds, the weighted metric, and straight motions between configurations
    (`oracle.space`, `ConfigurationSpace.of(scene)`).

    Attributes:
        lower: (dim,) lower bounds; continuous angles get -pi for sampling.
        upper: (dim,) upper bounds; continuous angles get pi.
        weights: (dim,) positive metric weight per coordinate: the lever arm it swings.
        angular: (dim,) bool: revolute coordinates.
        continuous: (dim,) bool: angles without limits, which wrap.
        resolution: The edge-check step in the weighted metric.
        names: Coordinate names, for messages.
    """

    lower: np.ndarray
    upper: np.ndarray
    weights: np.ndarray
    angular: np.ndarray
    continuous: np.ndarray
    resolution: float
    names: list[str] = field(default_factory=list)

    def __post_init__(self):
        # Continuous angles may take any finite value: huge finite bounds let one comparison serve every coordinate
        # and still reject inf and NaN.
        object.__setattr__(self, "_lo", np.where(self.continuous, -1e300, self.lower))
        object.__setattr__(self, "_hi", np.where(self.continuous, 1e300, self.upper))

    @classmethod
    def of(cls, scene) -> ConfigurationSpace:
        """The space a Scene (or a custom scene) declares."""
        return cls(
            lower=np.asarray(scene.lower, float),
            upper=np.asarray(scene.upper, float),
            weights=np.asarray(scene.weights, float),
            angular=np.asarray(scene.angular, bool),
            continuous=np.asarray(scene.continuous, bool),
            resolution=float(scene.resolution),
            names=list(scene.coordinate_names),
        )

    @property
    def dim(self) -> int:
        """The number of coordinates."""
        return len(self.lower)

    # ---- points ---------------------------------------------------------------------------------------------
    def uniform(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """n configurations uniform in the bounds."""
        return rng.uniform(self.lower, self.upper, size=(n, self.dim))

    def wrap(self, Q: np.ndarray) -> np.ndarray:
        """Continuous angles into [-pi, pi); other coordinates untouched (a copy)."""
        Q = np.array(Q, float, copy=True)
        Q[..., self.continuous] = (Q[..., self.continuous] + np.pi) % (2 * np.pi) - np.pi
        return Q

    def within_bounds(self, Q: np.ndarray) -> np.ndarray:
        """Inside the bounds and finite, per configuration."""
        Q = np.atleast_2d(Q)
        return ((Q >= self._lo) & (Q <= self._hi)).all(axis=1)

    @functools.cached_property
    def edge_table(self) -> tuple[np.ndarray, np.ndarray]:
        """What a compiled edge check needs of the space (app.checking.kernels.edge_points): the bounds
        `within_bounds` compares with, and the weights, as rows of one array; and the continuous angles' indices."""
        return np.vstack([self._lo, self._hi, self.weights]), np.flatnonzero(self.continuous)

    def out_of_bounds(self, q: np.ndarray) -> list[str]:
        """Each coordinate of q outside its bounds, as 'name=value not in [lo, hi]'."""
        q = np.asarray(q, float)
        return [
            f"{self._name(i)}={q[i]:g} not in [{self.lower[i]:g}, {self.upper[i]:g}]"
            for i in range(self.dim)
            if not (self._lo[i] <= q[i] <= self._hi[i])
        ]

    def check_configuration(self, q, what: str = "configuration") -> np.ndarray:
        """A user-supplied configuration as a float vector of the right length, or a UserError naming the fault."""
        try:
            q = np.asarray(q, float).reshape(-1)
        except (TypeError, ValueError):
            raise UserError(f"{what} must be {self.dim} numbers") from None
        if q.shape != (self.dim,):
            raise UserError(f"{what} has {q.shape[0]} values; the robot needs {self.dim}")
        if not np.all(np.isfinite(q)):
            raise UserError(f"{what} has a value that is not a finite number")
        return q

    def check_step(self, step: float) -> float:
        """A sampler's base step, or a UserError: positive, finite and no longer than the bounds' weighted diagonal
        (a walk of longer steps leaves the bounds at every step and never ends)."""
        step = float(step)
        diagonal = float(np.linalg.norm((self.upper - self.lower) * self.weights))
        if not step > 0:
            raise UserError(f"step must be a positive number, got {step:g}")
        if step > diagonal:
            raise UserError(f"step {step:g} is longer than the scene's diagonal ({diagonal:g})")
        return step

    # ---- metric -----------------------------------------------------------------------------------------------
    def difference(self, q1: np.ndarray, q2: np.ndarray) -> np.ndarray:
        """q2 - q1, taking the short way round on continuous angles (broadcasts)."""
        d = np.asarray(q2, float) - np.asarray(q1, float)
        d[..., self.continuous] = (d[..., self.continuous] + np.pi) % (2 * np.pi) - np.pi
        return d

    def distance(self, q1: np.ndarray, q2: np.ndarray) -> np.ndarray:
        """Weighted configuration distance (broadcasts over leading axes)."""
        return np.linalg.norm(self.difference(q1, q2) * self.weights, axis=-1)

    # ---- straight motions ---------------------------------------------------------------------------------------
    def segments(self, Q1: np.ndarray, Q2: np.ndarray, resolution: float | None = None) -> np.ndarray:
        """How many pieces each edge Q1[i] -> Q2[i] is cut into so that points are at most `resolution` apart."""
        return self.pieces(self.difference(np.atleast_2d(Q1), np.atleast_2d(Q2)), resolution)

    def pieces(self, D: np.ndarray, resolution: float | None = None) -> np.ndarray:
        """`segments` of edges given by their differences D (n, dim)."""
        d = D * self.weights
        # Squares summed coordinate by coordinate, as the compiled edge check sums them (app.checking.kernels): the
        # same count of pieces there, and on any machine (einsum's SIMD order depends on the CPU).
        squares = np.zeros(len(d))
        for column in d.T:
            squares += column * column
        return np.maximum(1, np.ceil(np.sqrt(squares) / (resolution or self.resolution))).astype(int)

    def interpolate(self, q1: np.ndarray, q2: np.ndarray, resolution: float | None = None) -> np.ndarray:
        """Points from q1 to q2 (both included) no more than `resolution` apart in the weighted metric."""
        n = int(self.segments(q1, q2, resolution)[0])
        t = (np.arange(n + 1) / n)[:, None]  # the same fractions an edge check looks at
        return self.wrap(np.asarray(q1, float) + t * self.difference(q1, q2))

    def unwrap(self, P: np.ndarray) -> np.ndarray:
        """Waypoints with continuous angles unwrapped along the path: each step is the short-way difference, so a
        trajectory through them moves exactly along the checked edges (no 2*pi jumps). Starts at P[0]."""
        P = np.atleast_2d(np.asarray(P, float))
        if len(P) < 2:
            return P.copy()
        steps = self.difference(P[:-1], P[1:])
        return P[0] + np.vstack([np.zeros((1, P.shape[1])), np.cumsum(steps, axis=0)])

    def _name(self, i: int) -> str:
        return self.names[i] if i < len(self.names) and self.names[i] else f"q[{i}]"


@dataclass(frozen=True, eq=False)
class PositionMap:
    """The plant's joint positions from the planned coordinates, positions = matrix @ q + offset: a mimic joint (URDF
    <mimic joint= multiplier= offset=>) is no coordinate of its own but follows the joint it mimics, and a held joint
    (a MoveIt request's joints outside its planning group) is none either: it stays at its position. Every planned
    joint is one coordinate (its row of `matrix` a unit vector); a mimic joint's row holds its multiplier in the
    column of the coordinate it follows; a held joint's row is zero and its offset its position. A scene without
    mimic or held joints has no map (None): positions are q."""

    matrix: np.ndarray  # (positions, coordinates)
    offset: np.ndarray  # (positions,)
    names: list[str]  # every position's name, the mimic joints' included, in the plant's order
    planned: np.ndarray  # (coordinates,) the position index of each coordinate

    @classmethod
    def of(
        cls, names: list[str], mimics: list[tuple[str, str, float, float]], held: dict[str, float] | None = None
    ) -> PositionMap | None:
        """The map for positions `names` whose mimics are (joint, followed joint, multiplier, offset) and whose `held`
        joints stay at their given positions; None without either. A mimic of a mimic joint, of itself or of an
        unknown joint, an unknown held joint or a held mimic joint is a UserError; a mimic joint of a held joint is
        held where it follows it."""
        held = dict(held or {})
        if not mimics and not held:
            return None
        index = {name: i for i, name in enumerate(names)}
        followed = {}
        for joint, leader, multiplier, offset in mimics:
            for name in (joint, leader):
                if name not in index:
                    raise UserError(f"mimic joint '{joint}': no joint named '{name}' among {', '.join(names)}")
            if joint in followed:
                raise UserError(f"joint '{joint}' mimics two joints")
            if not (np.isfinite(multiplier) and np.isfinite(offset)) or multiplier == 0:
                raise UserError(f"mimic joint '{joint}': multiplier must be finite and non-zero, offset finite")
            followed[joint] = (leader, float(multiplier), float(offset))
        for joint, (leader, _, _) in followed.items():
            if leader in followed:
                raise UserError(f"mimic joint '{joint}' follows '{leader}', which is itself a mimic joint")
        for joint, position in held.items():
            if joint not in index:
                raise UserError(f"held joint '{joint}': no joint of that name among {', '.join(names)}")
            if joint in followed:
                raise UserError(f"joint '{joint}' mimics '{followed[joint][0]}': hold that joint instead")
            if not np.isfinite(position):
                raise UserError(f"held joint '{joint}': its position must be a finite number")
        for joint, (leader, multiplier, shift) in list(followed.items()):
            if leader in held:  # it cannot follow a joint that does not move: it is held where it follows it
                held[joint] = multiplier * held[leader] + shift
                del followed[joint]
        planned = np.array([i for i, name in enumerate(names) if name not in followed and name not in held], int)
        if not len(planned):
            raise UserError("every joint is held or mimics another: nothing is left to plan")
        column = {int(p): c for c, p in enumerate(planned)}
        matrix, offset = np.zeros((len(names), len(planned))), np.zeros(len(names))
        matrix[planned, np.arange(len(planned))] = 1.0
        for joint, (leader, multiplier, shift) in followed.items():
            matrix[index[joint], column[index[leader]]] = multiplier
            offset[index[joint]] = shift
        for joint, position in held.items():
            offset[index[joint]] = float(position)
        return cls(matrix, offset, list(names), planned)

    @property
    def mimics(self) -> list[tuple[int, int, float, float]]:
        """(position, coordinate it follows, multiplier, offset) of each mimic joint."""
        rows = [p for p in np.setdiff1d(np.arange(len(self.names)), self.planned) if self.matrix[p].any()]
        columns = np.argmax(self.matrix[rows] != 0, axis=1)
        return [(int(p), int(c), float(self.matrix[p, c]), float(self.offset[p])) for p, c in zip(rows, columns)]

    @property
    def held(self) -> dict[str, float]:
        """The held joints' positions by name."""
        rows = [p for p in np.setdiff1d(np.arange(len(self.names)), self.planned) if not self.matrix[p].any()]
        return {self.names[p]: float(self.offset[p]) for p in rows}

    def equalities(self) -> tuple[np.ndarray, np.ndarray]:
        """(A, b): the mimic and held joints' relations as linear equalities A @ positions = b (one row per joint
        that is no coordinate), for solvers whose variables are the plant's positions."""
        rows = np.setdiff1d(np.arange(len(self.names)), self.planned)
        A = -self.matrix[rows] @ np.eye(len(self.names))[self.planned]
        A[np.arange(len(rows)), rows] += 1.0
        return A, self.offset[rows]

    def positions(self, Q: np.ndarray) -> np.ndarray:
        """Plant positions of configurations Q (..., coordinates)."""
        return np.asarray(Q, float) @ self.matrix.T + self.offset

    def rates(self, V: np.ndarray) -> np.ndarray:
        """Joint velocities (or accelerations) of coordinate velocities V (..., coordinates)."""
        return np.asarray(V, float) @ self.matrix.T

    def coordinates(self, P: np.ndarray) -> np.ndarray:
        """The planned coordinates of plant positions P (..., positions)."""
        return np.asarray(P, float)[..., self.planned]

    def check_held(self, lower: np.ndarray, upper: np.ndarray) -> None:
        """A UserError naming the first held joint whose position is outside its limits (lower, upper per position)."""
        for name, position in self.held.items():
            i = self.names.index(name)
            if not lower[i] - 1e-9 <= position <= upper[i] + 1e-9:  # (a position read back from a file may round)
                raise UserError(
                    f"held joint '{name}' at {position:g} is outside its limits [{lower[i]:g}, {upper[i]:g}]"
                )

    def coordinate_limits(self, lower: np.ndarray, upper: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The limits (lo, hi) per coordinate that keep every mimic joint within its own position limits (lower,
        upper per position); -inf, inf where no mimic joint limits a coordinate."""
        lo, hi = np.full(len(self.planned), -np.inf), np.full(len(self.planned), np.inf)
        for p, c, multiplier, shift in self.mimics:
            ends = sorted(((lower[p] - shift) / multiplier, (upper[p] - shift) / multiplier))
            lo[c], hi[c] = max(lo[c], ends[0]), min(hi[c], ends[1])
        return lo, hi

    def coordinate_speeds(self, limits: np.ndarray) -> np.ndarray:
        """The speed (or acceleration) limit per coordinate that keeps every mimic joint within its own (`limits` per
        position): a mimic joint moves |multiplier| times as fast as its coordinate; inf where none limits it."""
        out = np.full(len(self.planned), np.inf)
        for p, c, multiplier, _ in self.mimics:
            if limits[p] > 0:  # (a model's 0 means no limit given)
                out[c] = min(out[c], limits[p] / abs(multiplier))
        return out

    def position_bounds(self, lower: np.ndarray, upper: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The range of each position over the coordinate box [lower, upper]."""
        centre, half = self.positions(0.5 * (lower + upper)), np.abs(self.matrix) @ (0.5 * (upper - lower))
        return centre - half, centre + half
