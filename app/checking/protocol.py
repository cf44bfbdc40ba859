"""The door every stage after collision checking goes through: a `Checker`.

A Checker is a query's counted collision answers (in practice app.checking.context.QueryContext on a shared
CollisionOracle), each call bounded by the `Stop` it is given; beside them, uncounted workspace queries and
diagnostics, and the scene's facts the later stages read. Samplers, the roadmap and path shortcuts use a Checker alone
and never import Drake (an import contract says so); the certificate and timing also reach the Drake model behind it,
through `checker.oracle`, a `DistanceSource`. tests/toy_checker.py is a Checker on boxes in the plane, numpy alone,
that the fast tests run the samplers, the roadmap, smoothing and budgets on. `make test` type-checks these Protocols
against the classes that implement them (mypy).
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np

from app.checking.budget import Budget, Stop
from app.scene.cspace import ConfigurationSpace


class SceneFacts(Protocol):
    """What the stages after checking read of a scene (app.scene.model.Scene has it all)."""

    name: str
    start: Any  # (dim,)
    goal: Any  # (dim,), or (k, dim): any of k goals
    step: float | None  # the sampler step the scene's file sets, if any
    lower: Any  # (dim,) bounds
    upper: Any
    angular: Any  # (dim,) booleans: revolute coordinates
    weights: Any  # (dim,) the metric's weights
    self_collisions: bool  # whether the robot's collisions with itself count
    velocity_limits: Any  # (dim,)
    acceleration_limits: Any  # (dim,)
    position_map: Any  # mimic joints (app.scene.cspace.PositionMap), or None


class WorkspaceQueries(Protocol):
    """Where the robot's pieces and its passage frame are at configurations, and where the environment leaves narrow
    gaps (uncounted; a checker counts `environment_gaps` itself)."""

    def robot_geometry_centres(self, Q: np.ndarray, pieces: np.ndarray | None = None) -> np.ndarray: ...

    def robot_geometry_radii(self) -> np.ndarray: ...

    def frame_positions(self, Q: np.ndarray) -> np.ndarray: ...

    def in_passage(self, Q: np.ndarray) -> np.ndarray: ...

    def environment_gaps(self, P: np.ndarray, width: float) -> np.ndarray: ...


class Diagnostics(Protocol):
    """What a configuration touches, named: for the messages that refuse a start or goal (uncounted)."""

    def colliding_bodies(self, q: np.ndarray) -> list[tuple[str, str]]: ...

    def touching(self, q: np.ndarray, margin: float = ...) -> list[tuple[str, str, float]]: ...

    def clearance(self, q: np.ndarray, max_distance: float = ...) -> float: ...


class DistanceSource(Protocol):
    """The Drake model behind a checker and its uncounted answers, for the certificate and timing: the plant and
    diagram (kinematics, Toppra), SceneGraph's query object at a configuration, which geometries are the robot's,
    and the seconds spent in Drake by kind (benchmarks)."""

    scene: Any  # app.scene.model.Scene
    space: ConfigurationSpace
    plant: Any
    model: Any
    threads: int
    seconds: dict[str, float]

    def query_object(self, q: np.ndarray) -> Any: ...

    def of_scene(self, scene) -> Any: ...  # another source like this one, for another scene (a changed cell)

    def is_robot_geometry(self, geometry_id: Any) -> bool: ...


class Checker(Protocol):
    """Counted collision answers for one query: `checks` (configurations handed to Drake for an answer: the paper's
    gamma_c), `distance_queries` (the certificate's) and `point_queries` (workspace points) count what this checker
    was asked; every counted call takes the `stop` that bounds it (None: nothing does)."""

    space: ConfigurationSpace
    checks: int
    distance_queries: int
    point_queries: int

    @property
    def scene(self) -> SceneFacts: ...

    @property
    def oracle(self) -> DistanceSource: ...

    @property
    def threads(self) -> int: ...  # the cores a large k-nearest query may be spread over

    @property
    def workspace(self) -> WorkspaceQueries: ...

    @property
    def diagnostics(self) -> Diagnostics: ...

    def stop(self, budget: Budget | None = None, cancel: Any = None) -> Stop: ...

    def is_free(self, q: np.ndarray, stop: Stop | None = None) -> bool: ...

    def are_free(self, Q: np.ndarray, stop: Stop | None = None) -> np.ndarray: ...

    def edges_free(
        self,
        Q1: np.ndarray,
        Q2: np.ndarray,
        resolution: float | None = None,
        ends_free: bool = False,
        stop: Stop | None = None,
    ) -> np.ndarray: ...

    def edges_status(
        self,
        Q1: np.ndarray,
        Q2: np.ndarray,
        resolution: float | None = None,
        ends_free: bool = False,
        until_one_collides: bool = False,
        progress: np.ndarray | None = None,
        stop: Stop | None = None,
    ) -> tuple[np.ndarray, np.ndarray]: ...

    def edge_free(
        self, q1: np.ndarray, q2: np.ndarray, resolution: float | None = None, stop: Stop | None = None
    ) -> bool: ...

    def environment_gaps(self, P: np.ndarray, width: float, stop: Stop | None = None) -> np.ndarray: ...

    def signed_distances(self, q: np.ndarray, max_distance: float) -> list: ...

    def in_contact(self, q: np.ndarray) -> bool: ...

    def pair_distances(self, q: np.ndarray, pairs: list) -> list: ...

    def count_bounded(self, n: int) -> None: ...
