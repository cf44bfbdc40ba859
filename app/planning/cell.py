"""A roadmap built once per work cell and queried many times: the multi-query PRM (Kavraki et al., 1996).

`CellRoadmap.build(oracle, BuildSettings(...))` samples the cell's free space the way a query does (uniform samples,
the narrow-passage sampler's, placements in narrow workspace gaps: `Samples`) and decides every k-nearest edge
between them. `solve(start, goal)` then runs a query's phases (app.planning.query.Query) on that graph: start and
goal join it, the search uses what is known, smoothing, the certificate and timing follow. `goal` may be several
configurations (every IK solution of a tool pose): the query reaches whichever it can. A query on the roadmap draws
the samples a fresh query with its seed draws, on top of what the roadmap holds, and runs the fresh query's roadmap
beside it (app.planning.query.FreshShadow), whose edges and verdicts it takes: it connects start and goal no later
than the fresh query would, for at most the fresh query's checks and its own searches through the stored nodes.
`roadmap build` then answers the scene's own query and its jobs on the new roadmap (app.jobs.cover), so that the
hard regions are in it before anyone asks.

Nothing a query learns is forgotten: an edge checked free or found colliding is never checked again (nor the points of
an edge a check found free before it stopped), and the samples a hard query had to add and joined to the roadmap by
free edges stay for the next one, with its start and goals, so a cell gets cheaper the more it is used. The samples it
never joined leave (a hard query draws thousands; kept, they made every later search dearer: benchmark pages), and a
query that fails takes all its samples away again, leaving its edge verdicts. OMPL's PRM keeps its graph across
`clearQuery()` the same way. Proofs are kept within a process (an edge the certificate proved is not proved again
there), but never taken from a file: the file's `proved` column records what the process that wrote it proved
(`roadmap info` shows it) and is not read on load. A stored verdict only steers the search -- `checked` says where it
need not check again -- and every certificate a query reports is made in the process that returns the path, so a
file written by anyone (an edge row through a wall marked checked and proved) can cost a query time but never stands
in for a proof.

`save(path)` writes one file; `CellRoadmap.load(path, oracle)` reads it back only into the cell it was built for: the
file holds a fingerprint of everything its verdicts depend on, and a file whose fingerprint differs from the oracle's
is refused (UserError) rather than planned with. So is a file that is not whole or not sound, in one line and before
anything is planned. The file's format, how it is read and checked, and the fingerprint are
app.planning.roadmap_file's.

A cell that changes (app.scene.changes: obstacles added, moved or removed, objects attached to the robot):
`changed(changes)` is the roadmap repaired for the new cell instead of built again -- only the verdicts the changes
can reach are set back to unknown (app.planning.repair) -- and its file records the changes; `open(path, oracle)`
loads a file into the oracle's scene as the file's recorded changes leave it, and repairs it for more if asked.

Two processes updating one file: `save` to the file a roadmap was loaded from writes it only if it is still the
revision loaded (else UserError: the other process's update would be lost), holding the file's lock
(`app.io.exclusive`, on FILE.lock beside it); `plan --roadmap FILE --update` holds that lock from before it reads the
file until it has written it back, so a second such process waits, then loads the first one's result and adds its
own. A process that only reads the file takes no lock: a save replaces the file whole (a rename), never part of it.

Building on several processes (`workers`, at most the oracle's `processes`): samples are drawn in this process and
each round's candidate edges are shared between it and the oracle's helper processes, each with its own oracle of
the same scene (`CollisionOracle.spread_edges`). An edge's verdict and its check count do not depend on which process
checked it or with which other edges, and the budget is looked at only between rounds, so the roadmap is the same
for any worker count.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import time
import uuid
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from app.checking.budget import Budget
from app.errors import NoPath, SamplerBudgetExceeded, UserError
from app.io import exclusive, write_atomically
from app.planning.query import Query
from app.planning.result import PlanResult
from app.planning.roadmap_file import (
    FINGERPRINT_PARTS,
    FORMAT,
    FORMAT_VERSION,
    MAX_K,
    check_cell,
    fingerprint,
    read,
    stored_revision,
    summary,
)
from app.planning.settings import PlanSettings, default_step
from app.planning.sources import Samples

# The roadmap graph pulls in scipy: imported when a cell roadmap is made, not when the package is.

# The fingerprint's parts a cell change alters (app.scene.changes): a file that differs only in these may be repaired.
CELL_PARTS = {"robot", "environment", "collision pairs"}
# Samples drawn and connected per build round: the budget is looked at between rounds.
ROUND = 250
# A round's new edges are decided in parts of about PART_SECONDS each, progress reported after each part: deciding
# them takes nearly all of a round, which in a cell of many obstacles takes minutes. The first part holds FIRST_PART
# edges, each next one as many as the pace of the last fits in PART_SECONDS (a part per call to the helper processes
# costs their hand-over, so parts are sized by time, not fixed in number). An edge's verdict and checks do not
# depend on the edges decided with it, so the roadmap is the same whatever the parts.
PART_SECONDS = 1.0
FIRST_PART = 64


@dataclass(frozen=True)
class BuildSettings:
    """How a cell roadmap is built (`CellRoadmap.build`), validated once when built (a bad value raises UserError).

    Attributes:
        nodes: The samples the roadmap holds when the build ends (the budget may end it first).
        narrow: The share of each round's samples from the narrow-passage sampler (with `workspace` of those placed
            in workspace gaps); the rest are uniform.
        sampler: As in PlanSettings ("adaptive" learns from a query's searches; a build runs none, so its mixed
            sources share the narrow checks evenly).
        step: As in PlanSettings.
        sampler_params: As in PlanSettings.
        workspace: As in PlanSettings.
        k: Neighbours per node (None: k-PRM*'s).
        seed: The random seed.
        budget: What the build may spend, looked at between rounds (no time limit unless it says `seconds=...`).
    """

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
        if self.k is not None and self.k > MAX_K:
            raise UserError(f"k must be from 1 to {MAX_K} (a roadmap file holds no more), got {self.k!r}")
        if isinstance(self.nodes, bool) or not isinstance(self.nodes, (int, np.integer)) or self.nodes < 2:
            raise UserError(f"nodes must be a whole number of at least 2, got {self.nodes!r}")
        if isinstance(self.narrow, bool) or not isinstance(self.narrow, (int, float)) or not 0 <= self.narrow <= 1:
            raise UserError(f"narrow must be a share from 0 to 1, got {self.narrow!r}")


class CellRoadmap:
    """A persistent roadmap of one cell (one scene): build it once, `solve` many queries, `save` and `load` it.

    Not for two threads at once (a query changes the graph); one oracle may serve it and other queries.

    Attributes:
        oracle: The cell's CollisionOracle.
        provenance: Its builds (each one's settings, workers, why it ended, nodes, collision checks, seconds) and
            the number of queries answered with it, as saved in its file and shown by `roadmap info`.
    """

    def __init__(self, oracle, graph=None, provenance: dict | None = None):
        from app.planning.roadmap import Roadmap

        self.oracle = oracle
        self.graph = graph if graph is not None else Roadmap(oracle.context(), k=None, skip_connected=False, lazy=True)
        self.provenance = provenance or {"builds": [], "queries": 0}
        self._certifier = None  # the certificate's cached distances, shared by the queries
        self._source: tuple[Path, str | None] | None = None  # the file it was loaded from, and that file's revision

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
        new k-nearest edge. progress(nodes, target, checks), if given, is called as each round's edges are decided,
        about every PART_SECONDS (nodes: those of the rounds before, and the round's in proportion to its edges
        decided).
        Returns what the build spent and why it ended; the same record joins `provenance`."""
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
            new = np.concatenate([graph.add(Q, kind, connect=False) for kind, _, Q in drawn])
            P = graph.candidates(new)
            free, before, done, size = np.zeros(len(P), bool), len(graph) - len(new), 0, FIRST_PART
            while True:
                rows, started = np.arange(done, min(done + size, len(P))), time.perf_counter()
                A, B = graph.Q[P[rows, 0]], graph.Q[P[rows, 1]]
                if workers > 1:
                    free[rows] = oracle.spread_edges(checker, A, B, graph.resolution)
                else:
                    free[rows] = checker.edges_free(A, B, graph.resolution, ends_free=True)
                done += len(rows)
                if progress is not None:
                    share = done / len(P) if len(P) else 1.0
                    progress(before + round(len(new) * share), settings.nodes, checker.checks)
                if done >= len(P):
                    break
                pace = (time.perf_counter() - started) / len(rows)
                size = max(FIRST_PART, int(PART_SECONDS / pace) if pace > 0 else len(P))
            graph.record(P, free)  # the round's edges in one go, so the rows keep their order whatever the parts
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
            self._certifier = query.refinement.certifier
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
        """Write the roadmap to `path` (.npz; atomically: the file appears whole or not at all). To the file it was
        loaded from, only while that file is still the revision loaded, checked and written under the file's lock
        (`app.io.exclusive`): UserError if another process has written it since, whose update would be lost."""
        source, revision = self._source, uuid.uuid4().hex
        back = source is not None and _same_file(source[0], path)
        with exclusive(path) if back else contextlib.nullcontext():
            if back and stored_revision(path) != source[1]:
                raise UserError(
                    f"roadmap {path} has been written (by another process?) since this roadmap was loaded from it: not "
                    "written over (that update would be lost); load it again and repeat the query"
                )
            header = {
                "format": FORMAT,
                "version": FORMAT_VERSION,
                "scene": self.oracle.scene.name,
                "fingerprint": fingerprint(self.oracle),
                "provenance": self.provenance,
                "revision": revision,
            }
            buffer = io.BytesIO()
            np.savez_compressed(buffer, header=np.array(json.dumps(header)), **self.graph.arrays())
            written = write_atomically(path, buffer.getvalue())
        self._source = (Path(path), revision)
        return written

    @classmethod
    def load(cls, path, oracle) -> CellRoadmap:
        """The roadmap saved at `path`, for the oracle's cell. UserError when the file is not a whole and sound
        roadmap file (app.planning.roadmap_file.read), was built for another cell (robot, environment, collision
        pairs, bounds or resolution, checker code), or holds what this cell cannot have (`check_cell`)."""
        return cls._of(path, *read(path), oracle)

    @classmethod
    def open(cls, path, oracle, changes: list = ()) -> CellRoadmap:
        """The roadmap saved at `path` for the oracle's cell as it is now: in the cell the file was last repaired
        for (the oracle's scene after the changes its provenance records, on an oracle like it) and, if `changes`
        are given, repaired for those too (`changed`). Refused as `load` refuses."""
        from app.scene.changes import changed_scene

        header, arrays = read(path)
        recorded = recorded_changes(header)
        if recorded:
            oracle = oracle.of_scene(changed_scene(oracle.scene, recorded))
        cell = cls._of(path, header, arrays, oracle)
        return cell.changed(list(changes)) if changes else cell

    @classmethod
    def _of(cls, path, header: dict, arrays: dict, oracle) -> CellRoadmap:
        theirs, ours = header["fingerprint"], fingerprint(oracle)
        changed = [part for part in FINGERPRINT_PARTS if theirs.get(part) != ours[part]]
        if changed:
            raise UserError(
                f"roadmap {path} was built for another cell than {oracle.scene.name}: its {', '.join(changed)} "
                f"{'differs' if len(changed) == 1 else 'differ'}; build it again for this cell (roadmap build)"
                + (", or repair it for what changed (roadmap update --change)" if set(changed) <= CELL_PARTS else "")
            )
        from app.planning.roadmap import Roadmap

        graph = Roadmap.from_arrays(oracle.context(), check_cell(path, arrays, oracle.space))
        cell = cls(oracle, graph, header["provenance"])
        cell._source = (Path(path), header.get("revision"))
        return cell

    # ---- a changed cell -------------------------------------------------------------------------------------------
    def changed(self, changes: list) -> CellRoadmap:
        """This roadmap repaired for the cell its own becomes after `changes` (app.scene.changes.CellChange, in
        order): only the verdicts the changes can affect are set back to unknown, and the nodes they can reach are
        checked again (app.planning.repair). Returns a roadmap of the new cell, whose file will hold the new cell's
        fingerprint and, in its provenance, every change since the build; this one stays as it was.
        UserError for a change that cannot be applied; InvalidEndpoint (START_STATE_IN_COLLISION) when the scene's
        start collides in the new cell (an object put where the robot is, a payload through the arm)."""
        from app.planning.endpoints import check_endpoint
        from app.planning.repair import timed_repair
        from app.planning.roadmap import Roadmap
        from app.scene.changes import changed_scene

        scene = changed_scene(self.oracle.scene, changes)
        oracle = self.oracle.of_scene(scene)
        context = oracle.context()
        check_endpoint(context, scene.start, "start")
        arrays, keep, record = timed_repair(self.graph.arrays(), self.oracle, oracle, context, changes)
        graph = Roadmap.from_arrays(oracle.context(), arrays)
        graph.keep_nodes(keep)
        provenance = json.loads(json.dumps(self.provenance))
        provenance.setdefault("changes", []).append(record.to_dict())
        cell = CellRoadmap(oracle, graph, provenance)
        cell._source = self._source
        return cell

    def info(self) -> dict:
        """Sizes, verdict counts and provenance, as `roadmap info` prints them."""
        header = {
            "scene": self.oracle.scene.name,
            "fingerprint": fingerprint(self.oracle),
            "provenance": self.provenance,
        }
        return summary(self.graph.arrays(), header)


def recorded_changes(header: dict) -> list:
    """The cell changes a roadmap file's header records since its build, in order (app.scene.changes.CellChange):
    the cell it was last repaired for is its scene after these."""
    from app.scene.changes import change_from_dict

    return [change_from_dict(c) for record in header["provenance"].get("changes", []) for c in record["change"]]


def _same_file(a, b) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:  # one of them is not there (any more)
        return os.path.abspath(a) == os.path.abspath(b)
