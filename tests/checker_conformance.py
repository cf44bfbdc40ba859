"""Static checks, read by mypy in `make test` and never run: the classes behind the checker door are what the
Protocols of app.checking.protocol say (a method renamed, a parameter dropped or a member missing fails the build)."""

from app.checking.context import QueryContext
from app.checking.diagnostics import Diagnostics as OracleDiagnostics
from app.checking.oracle import CollisionOracle
from app.checking.protocol import Checker, Diagnostics, DistanceSource, SceneFacts, WorkspaceQueries
from app.checking.workspace import Workspace
from app.scene.checker_scene import CheckerScene
from app.scene.model import Scene
from toy_checker import ToyScene, toy_checker


def query_context_is_a_checker(context: QueryContext) -> Checker:
    return context


def the_toy_is_a_checker() -> Checker:
    return toy_checker()


def the_oracle_is_a_distance_source(oracle: CollisionOracle) -> DistanceSource:
    return oracle


def the_workspace_answers_workspace_queries(workspace: Workspace) -> WorkspaceQueries:
    return workspace


def the_diagnostics_are_diagnostics(diagnostics: OracleDiagnostics) -> Diagnostics:
    return diagnostics


def a_scene_has_the_facts(scene: Scene) -> SceneFacts:
    return scene


def the_toy_scene_has_the_facts(scene: ToyScene) -> SceneFacts:
    return scene


def a_scene_from_a_users_checker_has_the_facts(scene: CheckerScene) -> SceneFacts:
    return scene
