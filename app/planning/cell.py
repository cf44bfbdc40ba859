"""A roadmap built once per work cell and queried many times: the multi-query PRM (Kavraki et al., 1996).

`CellRoadmap.build(oracle, BuildSettings(...))` samples the cell's free space the way a query does (uniform samples,
the narrow-passage sampler's, placements in narrow workspace gaps: `Samples`) and decides every k-nearest edge
between them. `solve(start, goal)` then runs a query's phases (app.planning.planner.Query) on that graph: start and
goal join it, the search uses what is known, smoothing, the certificate and timing follow. `goal` may be several
configurations (every IK solution of a tool pose): the query reaches whichever it can.

Nothing a query learns is forgotten: an edge checked free or found colliding is never checked again (nor the points of
an edge a check found free before it stopped), an edge the certificate proved is never proved again (nor one it could
not prove tried again), and the samples a hard query had to add and joined to the roadmap by free edges stay for the
next one, with its start and goals, so a cell gets cheaper the more it is used. The samples it never joined leave (a
hard query draws thousands; kept, they made every later search dearer: benchmark pages), and a query that fails takes
all its samples away again, leaving its edge verdicts. OMPL's PRM keeps its graph across `clearQuery()` the same way.

`save(path)` writes one file; `CellRoadmap.load(path, oracle)` reads it back only into the cell it was built for: the
file holds a fingerprint of everything its verdicts depend on (`fingerprint`), and a file whose fingerprint differs
from the oracle's, or that is truncated or corrupt, is refused (UserError) rather than planned with.

The file is numpy's .npz, a zip of arrays read without pickle: nodes and edges are arrays, so a large roadmap loads
in milliseconds; loading a file from elsewhere cannot run code; and the zip's checksums reveal a damaged file. A
JSON header inside it holds the format version, the fingerprint and where the roadmap came from.

Building on several processes (`workers`, at most the oracle's `processes`): samples are drawn in this process and
each round's candidate edges are shared between it and the oracle's helper processes, each with its own oracle of
the same scene (`CollisionOracle.spread_edges`). An edge's verdict and its check count do not depend on which process
checked it or with which other edges, and the budget is looked at only between rounds, so the roadmap is the same
for any worker count.
"""

from __future__ import annotations

import hashlib
import importlib.metadata
import io
import json
import time
import zipfile
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from app.checking.budget import Budget
from app.errors import NoPath, SamplerBudgetExceeded, UserError
from app.io import write_atomically
from app.planning.planner import PlanResult, PlanSettings, Query, Samples, default_step
from app.scene.meshes import hull_vertices

# The roadmap graph pulls in scipy: imported when a cell roadmap is made, not when the package is.

FORMAT, FORMAT_VERSION = "narrow-passage-planner cell roadmap", 2
# The largest roadmap file read: far above any roadmap a cell needs (10^6 nodes of 9 coordinates are 70 MB).
MAX_FILE_BYTES = 2 << 30
# Samples drawn and connected per build round: the budget is looked at between rounds.
ROUND = 250
# The modules whose code decides a verdict (a collision answer, an edge check, a certificate): a roadmap saved by
# other code is not trusted.
_VERDICT_MODULES = (
    "checking/oracle.py",
    "checking/context.py",
    "checking/certify.py",
    "checking/kinematics.py",
    "scene/cspace.py",
)
FINGERPRINT_PARTS = ("robot", "environment", "collision pairs", "configuration space", "checker code")


@dataclass(frozen=True)
class BuildSettings:
    """How a cell roadmap is built. nodes: the samples it holds when the build ends (the budget may end it first);
    narrow: the share of each round's samples from the narrow-passage sampler (with `workspace` of those placed in
    workspace gaps; the rest uniform); sampler, step, sampler_params, workspace: as in PlanSettings; k: neighbours
    per node (None: k-PRM*'s); seed; budget: what the build may spend, looked at between rounds."""

    nodes: int = 1500
    narrow: float = 0.25
    sampler: str = "lfbs"
    step: float | None = None
    sampler_params: dict = field(default_factory=dict)
    workspace: float = 0.75
    k: int | None = None
    seed: int = 0
    budget: Budget = Budget(checks=3_000_000)

    def __post_init__(self):
        # PlanSettings validates the fields the two share (sampler, step, k, seed, workspace, budget).
        PlanSettings(
            sampler=self.sampler,
            step=self.step,
            k=self.k,
            seed=self.seed,
            workspace=self.workspace,
            budget=self.budget,
            sampler_params=self.sampler_params,
        )
        if isinstance(self.nodes, bool) or not isinstance(self.nodes, (int, np.integer)) or self.nodes < 2:
            raise UserError(f"nodes must be a whole number of at least 2, got {self.nodes!r}")
        if isinstance(self.narrow, bool) or not isinstance(self.narrow, (int, float)) or not 0 <= self.narrow <= 1:
            raise UserError(f"narrow must be a share from 0 to 1, got {self.narrow!r}")


class CellRoadmap:
    """A persistent roadmap of one cell (one scene): build it once, `solve` many queries, `save` and `load` it.

    Not for two threads at once (a query changes the graph); one oracle may serve it and other queries."""

    def __init__(self, oracle, graph=None, provenance: dict | None = None):
        from app.planning.roadmap import Roadmap

        self.oracle = oracle
        self.graph = graph if graph is not None else Roadmap(oracle.context(), k=None, skip_connected=False, lazy=True)
        self.provenance = provenance or {"builds": [], "queries": 0}
        self._certifier = None  # the certificate's cached distances, shared by the queries

    def __len__(self) -> int:
        return len(self.graph)

    # ---- building -------------------------------------------------------------------------------------------------
    @classmethod
    def build(cls, oracle, settings: BuildSettings | None = None, *, workers: int = 1, progress=None) -> CellRoadmap:
        """A new roadmap of the oracle's cell (see `grow`)."""
        cell = cls(oracle)
        cell.grow(settings or BuildSettings(), workers=workers, progress=progress)
        return cell

    def grow(self, settings: BuildSettings, *, workers: int = 1, progress=None) -> dict:
        """Add samples in rounds until the roadmap holds `settings.nodes` (or the budget is spent), deciding every
        new k-nearest edge. progress(nodes, target, checks), if given, is called after each round. Returns what the
        build spent and why it ended; the same record joins `provenance`."""
        graph, oracle = self.graph, self.oracle
        if settings.k is not None:
            graph.k = settings.k
        checker = oracle.context()
        graph.checker = checker
        step = oracle.space.check_step(default_step(oracle.scene) if settings.step is None else settings.step)
        seeds = np.random.SeedSequence(settings.seed, spawn_key=(len(graph),) if len(graph) else ()).spawn(4)
        samples = Samples(checker, settings.sampler, step, seeds, settings.workspace, settings.sampler_params)
        clock, ended = time.perf_counter(), "nodes"
        while len(graph) < settings.nodes:
            if settings.budget.spent(time.perf_counter() - clock, checker.checks):
                ended = "budget"
                break
            count = min(ROUND, settings.nodes - len(graph))
            narrow = round(settings.narrow * count)
            try:
                drawn = samples.draw(narrow, count - narrow)
            except SamplerBudgetExceeded:
                ended = "sampler"  # the sampler found no more samples within its own cap
                break
            new = np.concatenate([graph.add(Q, kind, connect=False) for kind, Q in drawn])
            P = graph.candidates(new)
            A, B = graph.Q[P[:, 0]], graph.Q[P[:, 1]]
            if workers > 1:
                graph.record(P, oracle.spread_edges(checker, A, B, graph.resolution))
            else:
                graph.record(P, checker.edges_free(A, B, graph.resolution, ends_free=True))
            if progress is not None:
                progress(len(graph), settings.nodes, checker.checks)
        record = {
            "settings": {**asdict(settings), "budget": str(settings.budget)},
            "workers": int(min(workers, oracle.processes)),
            "ended": ended,
            "nodes": len(graph),
            "collision_checks": int(checker.checks),
            "seconds": time.perf_counter() - clock,
        }
        self.provenance["builds"].append(record)
        return record

    # ---- queries --------------------------------------------------------------------------------------------------
    def solve(
        self, start=None, goal=None, settings: PlanSettings | None = None, *, via=None, cancel=None
    ) -> PlanResult:
        """Plan from start to goal (default: the scene's; `goal` may be several configurations, any of which will
        do) on this roadmap, with `settings` (default: PlanSettings()). What the query learns stays in the roadmap:
        its verdicts on edges, its start and goals, and the samples it joined to other nodes by edges decided free.
        Its samples never joined leave again, and when it fails every node it added does: a query that spends its
        whole budget where no path is found adds thousands of samples there, and every later search would pay for
        them. Raises as app.plan does."""
        size = len(self.graph)
        query = Query(
            self.oracle,
            settings or PlanSettings(),
            start=start,
            goal=goal,
            via=via,
            cancel=cancel,
            roadmap=self.graph,
            certifier=self._certifier,
        )
        try:
            result = query.solve()
        except NoPath:
            self.graph.truncate(size)
            raise
        finally:
            self._certifier = query.certifier
            self.provenance["queries"] += 1
        # Of the nodes an answered query added, its start and goals stay (few, and where queries go: often the hard
        # region), and the samples it joined by edges decided free; the samples it never joined (nearly all of a
        # hard query's thousands) leave: every later search would pay for them and try their edges again.
        if len(self.graph) > size:
            from app.planning.roadmap import GOAL, START

            keep = self.graph.joined_nodes() | np.isin(self.graph.kinds, [START, GOAL])
            keep[:size] = True
            result.path_nodes = self.graph.keep_nodes(keep)[result.path_nodes].tolist()
        return result

    # ---- saving and loading ---------------------------------------------------------------------------------------
    def save(self, path) -> Path:
        """Write the roadmap to `path` (.npz; atomically: the file appears whole or not at all)."""
        header = {
            "format": FORMAT,
            "version": FORMAT_VERSION,
            "scene": self.oracle.scene.name,
            "fingerprint": fingerprint(self.oracle),
            "provenance": self.provenance,
        }
        buffer = io.BytesIO()
        np.savez_compressed(buffer, header=np.array(json.dumps(header)), **self.graph.arrays())
        return write_atomically(path, buffer.getvalue())

    @classmethod
    def load(cls, path, oracle) -> CellRoadmap:
        """The roadmap saved at `path`, for the oracle's cell. UserError when the file is not a whole roadmap file
        or was built for another cell (robot, environment, collision pairs, bounds or resolution, checker code)."""
        header, arrays = read(path)
        theirs, ours = header["fingerprint"], fingerprint(oracle)
        changed = [part for part in FINGERPRINT_PARTS if theirs.get(part) != ours[part]]
        if changed:
            raise UserError(
                f"roadmap {path} was built for another cell than {oracle.scene.name}: its {', '.join(changed)} "
                f"{'differs' if len(changed) == 1 else 'differ'}; build it again for this cell (roadmap build)"
            )
        from app.planning.roadmap import Roadmap

        graph = Roadmap.from_arrays(oracle.context(), arrays)
        return cls(oracle, graph, header["provenance"])

    def info(self) -> dict:
        """Sizes, verdict counts and provenance, as `roadmap info` prints them."""
        header = {
            "scene": self.oracle.scene.name,
            "fingerprint": fingerprint(self.oracle),
            "provenance": self.provenance,
        }
        return summary(self.graph.arrays(), header)


def read(path) -> tuple[dict, dict]:
    """(header, arrays) of a roadmap file, checked to be whole and consistent; UserError otherwise."""
    path = Path(path)
    try:
        size = path.stat().st_size
    except OSError as exc:
        raise UserError(f"cannot read roadmap {path}: {exc.strerror or exc}") from None
    if size > MAX_FILE_BYTES:
        raise UserError(f"roadmap {path} is {size / 2**20:.0f} MiB, over the {MAX_FILE_BYTES >> 20} MiB limit")
    try:
        with open(path, "rb") as head:
            zipped = head.read(4) == b"PK\x03\x04"
    except OSError as exc:
        raise UserError(f"cannot read roadmap {path}: {exc.strerror or exc}") from None
    if not zipped:  # numpy would take any other file for a pickle and say so
        raise UserError(f"{path} is not a roadmap file of this planner (not an .npz archive)")
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {name: data[name] for name in data.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise UserError(f"roadmap {path} is not a whole roadmap file (truncated or corrupt?): {exc}") from None
    try:
        header = json.loads(str(arrays.pop("header")))
    except (KeyError, ValueError):
        header = None
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        raise UserError(f"{path} is not a roadmap file of this planner")
    if header.get("version") != FORMAT_VERSION:
        raise UserError(
            f"roadmap {path} has format version {header.get('version')}, this planner reads {FORMAT_VERSION}"
        )
    provenance = header.get("provenance")
    whole = isinstance(provenance, dict) and isinstance(provenance.get("builds"), list)
    if not isinstance(header.get("fingerprint"), dict) or not whole or not isinstance(provenance.get("queries"), int):
        raise UserError(f"roadmap {path} lacks its fingerprint or provenance: not a whole roadmap file")
    _check_arrays(path, arrays)
    return header, arrays


def _check_arrays(path, arrays: dict) -> None:
    """The arrays a roadmap file must hold, with shapes that agree: a file altered by hand or by a bug is refused
    here rather than failing somewhere in a query."""
    needed = {
        "Q",
        "kind_names",
        "kinds",
        "ends",
        "alive",
        "checked",
        "proved",
        "progress",
        "k",
        "resolution",
        "counters",
    }
    missing = needed - set(arrays)
    if missing:
        raise UserError(f"roadmap {path} lacks {', '.join(sorted(missing))}")
    Q, ends = arrays["Q"], arrays["ends"]
    n, m = len(Q), len(ends)
    fine = (
        Q.ndim == 2
        and np.isfinite(Q).all()
        and arrays["kinds"].shape == (n,)
        and (n == 0 or 0 <= arrays["kinds"].min() <= arrays["kinds"].max() < len(arrays["kind_names"]))
        and ends.shape == (m, 2)
        and (m == 0 or (ends.min() >= 0 and ends.max() < n and (ends[:, 0] < ends[:, 1]).all()))
        and all(arrays[key].shape == (m,) and arrays[key].dtype == bool for key in ("alive", "checked", "proved"))
        and arrays["progress"].shape == (m,)
        and arrays["progress"].dtype.kind in "iu"
        and (m == 0 or arrays["progress"].min() >= 0)
    )
    if not fine:
        raise UserError(f"roadmap {path} is inconsistent (its nodes, kinds and edges do not agree)")


def summary(arrays: dict, header: dict) -> dict:
    """What a roadmap holds: nodes by kind, edges by verdict, and where it came from."""
    names = [str(n) for n in arrays["kind_names"]]
    kinds = np.bincount(arrays["kinds"], minlength=len(names)) if len(arrays["kinds"]) else np.zeros(len(names), int)
    alive, checked, proved = arrays["alive"], arrays["checked"], arrays["proved"]
    return {
        "scene": header.get("scene"),
        "nodes": int(len(arrays["Q"])),
        "dimension": int(arrays["Q"].shape[1]) if arrays["Q"].ndim == 2 else 0,
        "nodes_by_kind": {name: int(count) for name, count in zip(names, kinds)},
        "edges": {
            "certified": int((alive & proved).sum()),
            "free": int((alive & checked & ~proved).sum()),
            "unchecked": int((alive & ~checked).sum()),
            "colliding_or_unprovable": int((~alive).sum()),
        },
        "k": int(arrays["k"]) or None,
        "resolution": float(arrays["resolution"]),
        "fingerprint": header.get("fingerprint"),
        "provenance": header.get("provenance"),
    }


# ---- the fingerprint ----------------------------------------------------------------------------------------------
def fingerprint(oracle) -> dict[str, str]:
    """Hashes (hex) of everything a stored verdict depends on, in parts, so that a refusal can say what changed:
    the robot's and the environment's collision geometry (shapes and their placement in the world at a fixed set of
    configurations: joint kinematics included), the pairs that are checked (self-collision, SRDF), the configuration
    space (bounds, metric, resolution), and the code that answers collision and certificate questions."""
    from pydrake.geometry import Role

    space = oracle.space
    inspector = oracle.model.scene_graph().model_inspector()
    geometries = sorted(
        inspector.GetAllGeometryIds(Role.kProximity),
        key=lambda g: (inspector.GetName(inspector.GetFrameId(g)), inspector.GetName(g)),
    )
    probes = np.vstack(
        [space.lower, space.upper, (space.lower + space.upper) / 2, space.uniform(np.random.default_rng(0), 5)]
    )
    placed = [[oracle.query_object(q).GetPoseInWorld(g).GetAsMatrix34() for g in geometries] for q in probes]
    parts = {}
    for part, robot in (("robot", True), ("environment", False)):
        digest = hashlib.sha256()
        for j, g in enumerate(geometries):
            if oracle.is_robot_geometry(g) != robot:
                continue
            digest.update(repr((inspector.GetName(inspector.GetFrameId(g)), inspector.GetName(g))).encode())
            digest.update(_shape_bytes(inspector.GetShape(g)))
            for poses in placed:
                digest.update(_rounded(poses[j]))
        parts[part] = digest.hexdigest()
    pairs = np.asarray(oracle.checker.GetFilteredCollisionMatrix())
    parts["collision pairs"] = _hash(pairs.astype(np.int64).tobytes(), repr(oracle.scene.self_collisions).encode())
    parts["configuration space"] = _hash(
        *(_rounded(a) for a in (space.lower, space.upper, space.weights, np.array([space.resolution]))),
        space.angular.tobytes(),
        space.continuous.tobytes(),
    )
    root = Path(__file__).resolve().parents[1]
    parts["checker code"] = _hash(
        *((root / module).read_bytes() for module in _VERDICT_MODULES),
        importlib.metadata.version("drake").encode(),
    )
    return parts


def _hash(*chunks: bytes) -> str:
    digest = hashlib.sha256()
    for chunk in chunks:
        digest.update(len(chunk).to_bytes(8, "little"))
        digest.update(chunk)
    return digest.hexdigest()


def _rounded(a) -> bytes:
    """Numbers to 1e-9 (-0 as 0), so that the same cell hashes alike however its numbers were computed."""
    return (np.round(np.asarray(a, float), 9) + 0.0).tobytes()


def _shape_bytes(shape) -> bytes:
    """A shape's kind and size; a mesh by the vertices of the convex hull Drake checks it as."""
    from pydrake.geometry import Box, Capsule, Convex, Cylinder, Ellipsoid, HalfSpace, Mesh, Sphere

    kind = type(shape).__name__.encode()
    if isinstance(shape, Box):
        size = [shape.width(), shape.depth(), shape.height()]
    elif isinstance(shape, Sphere):
        size = [shape.radius()]
    elif isinstance(shape, (Cylinder, Capsule)):
        size = [shape.radius(), shape.length()]
    elif isinstance(shape, Ellipsoid):
        size = [shape.a(), shape.b(), shape.c()]
    elif isinstance(shape, HalfSpace):
        size = []
    elif isinstance(shape, (Convex, Mesh)):
        size = hull_vertices(shape)
    else:  # a shape this list does not know: its description, which names its kind and size
        return kind + repr(shape).encode()
    return kind + _rounded(size)
