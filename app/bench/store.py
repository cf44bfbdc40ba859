"""The results store: every trial is one row in an SQLite file, keyed by what defines it.

A trial's key is a hash of its experiment, scene, method, step, seed and parameters, so a sweep that is killed and
started again skips exactly the rows already written and runs the rest (never a lost trial); there is one row per
key (never a duplicate). Each row is committed as it arrives; SQLite's journal keeps a killed write from leaving a
half row. Reports are built from the store, not from memory.

Reuse and code versions. The key leaves out the code version, but every row records the version that wrote it
(`code_version()`: the git commit, plus a hash of the uncommitted changes). A sweep reuses each stored row of its
trials, whatever version wrote it, and `reuse()` says how many it reuses and from which versions, so a command can
say so (and warn when they are not the current version). With fresh=True, rows written by another version are not
reused: those trials run again and their new rows replace the old ones (the store keeps no history); rows of the
current version are still reused, so a killed fresh sweep started again resumes instead of starting over. To
measure the same code again, use another store (or delete this one).

The file records its schema version (SQLite's user_version). A store of another version is refused rather than
read: rows are never reinterpreted, so the code that reads them needs no branch for how older code wrote them.
"""

import hashlib
import json
import sqlite3
import subprocess
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

from app.errors import UserError
from app.io import check_input
from app.scene.files import ROOT

# 1: stores from before the version was recorded (user_version 0); "prm" and "ur3" rows may lack full_roadmap.
# 2: every "prm" and "ur3" row's params hold full_roadmap.
SCHEMA_VERSION = 2
SCHEMA = f"""
BEGIN;
CREATE TABLE IF NOT EXISTS trials (
    key TEXT PRIMARY KEY,
    experiment TEXT NOT NULL,
    scene TEXT NOT NULL,
    method TEXT NOT NULL,
    step REAL NOT NULL,
    seed INTEGER NOT NULL,
    params TEXT NOT NULL,
    metrics TEXT NOT NULL,
    code_version TEXT NOT NULL,
    finished REAL NOT NULL
);
CREATE INDEX IF NOT EXISTS trials_by_cell ON trials (experiment, scene, method, step);
PRAGMA user_version = {SCHEMA_VERSION};
COMMIT;
"""


@dataclass(frozen=True)
class TrialSpec:
    """What defines one trial. `params` holds everything else that changes the result (k, roadmap sizes...)."""

    experiment: str
    scene: str
    method: str
    step: float
    seed: int
    params: dict = field(default_factory=dict, hash=False, compare=False)

    @property
    def key(self) -> str:
        text = json.dumps(
            [self.experiment, self.scene, self.method, float(self.step), int(self.seed), self.params], sort_keys=True
        )
        return hashlib.sha256(text.encode()).hexdigest()[:24]


def _plain(value):
    """json.dumps fallback for numpy scalars and arrays, which trials return naturally."""
    import numpy as np

    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"not JSON-serialisable: {type(value).__name__}")


def code_version() -> str:
    """The git commit, with '+dirty.HASH' (a hash of the uncommitted changes to tracked files) when the tree differs
    from it; the package version outside a checkout. Changes under results/ do not count: they are what the benches
    write (a resumed `bench paper` rewrites the committed report and trials), not code."""
    try:
        commit = subprocess.run(
            ["git", "rev-parse", "--short=12", "HEAD"], cwd=ROOT, capture_output=True, text=True, timeout=10, check=True
        ).stdout.strip()
        changes = subprocess.run(
            ["git", "diff", "HEAD", "--binary", "--", ".", ":(exclude)results"],
            cwd=ROOT,
            capture_output=True,
            timeout=30,
            check=True,
        ).stdout
        return commit + (f"+dirty.{hashlib.sha256(changes).hexdigest()[:8]}" if changes else "")
    except (OSError, subprocess.SubprocessError):
        from importlib.metadata import PackageNotFoundError, version

        try:
            return version("narrow-passage-planner")
        except PackageNotFoundError:
            return "unknown"


@dataclass(frozen=True)
class Reuse:
    """What a sweep takes from its store instead of running: `reused` of its `trials`, written by `versions`
    (sorted) while the code is at `current`."""

    store: str
    trials: int
    reused: int
    versions: tuple[str, ...]
    current: str

    @property
    def other_versions(self) -> tuple[str, ...]:
        return tuple(v for v in self.versions if v != self.current)

    def message(self) -> str:
        return (
            f"reused {self.reused} of {self.trials} trials from {self.store} (code version {', '.join(self.versions)})"
        )

    def warning(self) -> str | None:
        """Said when reused rows were written by other code than the current one."""
        if not self.other_versions:
            return None
        return (
            f"the reused trials of code version {', '.join(self.other_versions)} may not match this code "
            f"({self.current}); --fresh runs them again"
        )

    def to_json(self) -> dict:
        return {**asdict(self), "versions": list(self.versions), "warning": self.warning()}


def _is_sqlite(path: Path) -> bool:
    with open(path, "rb") as f:
        return f.read(16) == b"SQLite format 3\x00"


def is_results_store(path: Path) -> bool:
    """Whether `path` is a results store (a SQLite file with the trials table), asked read-only."""
    path = Path(path)
    if not path.is_file() or not _is_sqlite(path):
        return False
    try:
        db = sqlite3.connect(f"{path.absolute().as_uri()}?mode=ro", uri=True)
        try:
            return bool(db.execute("SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = 'trials'").fetchone())
        finally:
            db.close()
    except sqlite3.Error:
        return False


class ResultStore:
    def __init__(self, path: Path):
        self.path = Path(path)
        # SQLite takes a short file of any content for an empty database, and would overwrite it.
        if self.path.exists() and check_input(self.path, "results store").stat().st_size and not _is_sqlite(self.path):
            raise UserError(f"cannot use {self.path} as a results store: it is not a SQLite file; name another")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._db = sqlite3.connect(self.path)
        try:
            self._check_schema()
        except sqlite3.DatabaseError as exc:  # a damaged file, or one SQLite cannot lock
            self._db.close()
            raise UserError(f"cannot use {self.path} as a results store: {exc}") from None
        except BaseException:
            self._db.close()
            raise
        self.version = code_version()  # the current code's, written into each row added

    def _check_schema(self) -> None:
        # One statement, so both facts come from one snapshot: another process may be creating the store (the
        # table and the version are written in one transaction).
        version, has_trials, tables = self._db.execute(
            "SELECT (SELECT user_version FROM pragma_user_version), "
            "EXISTS (SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = 'trials'), "
            "(SELECT count(*) FROM sqlite_master WHERE type = 'table')"
        ).fetchone()
        if not has_trials and version == 0:
            if tables:  # another program's database: adding our table to it would change the user's file
                raise UserError(f"cannot use {self.path} as a results store: it is another program's SQLite database")
            self._db.executescript(SCHEMA)  # a new store
            return
        found = version or 1
        if found != SCHEMA_VERSION:
            raise UserError(
                f"results store {self.path} has schema {found}, this code writes {SCHEMA_VERSION}: "
                f"move it away and run again"
            )

    def close(self) -> None:
        self._db.close()

    def _versions(self) -> dict[str, str]:
        """key -> the code version of its row."""
        return dict(self._db.execute("SELECT key, code_version FROM trials"))

    def _reusable(self, specs: list[TrialSpec], fresh: bool) -> dict[str, str]:
        """key -> code version of the stored rows of `specs` a sweep reuses (module docstring)."""
        wanted = {s.key for s in specs}
        return {
            key: version
            for key, version in self._versions().items()
            if key in wanted and (not fresh or version == self.version)
        }

    def pending(self, specs: list[TrialSpec], fresh: bool = False) -> list[TrialSpec]:
        """The specs a sweep runs: those without a reusable row."""
        reusable = self._reusable(specs, fresh)
        return [s for s in specs if s.key not in reusable]

    def reuse(self, specs: list[TrialSpec], fresh: bool = False) -> Reuse:
        """What a sweep of `specs` would take from this store (before it runs)."""
        reusable = self._reusable(specs, fresh)
        return Reuse(
            store=str(self.path.resolve()),
            trials=len({s.key for s in specs}),
            reused=len(reusable),
            versions=tuple(sorted(set(reusable.values()))),
            current=self.version,
        )

    def add(self, spec: TrialSpec, metrics: dict) -> None:
        with self._db:  # one transaction per row: a kill loses at most the row being written
            self._db.execute(  # a trial run again (fresh) replaces its old row
                "INSERT OR REPLACE INTO trials VALUES (?,?,?,?,?,?,?,?,?,?)",
                (
                    spec.key,
                    spec.experiment,
                    spec.scene,
                    spec.method,
                    float(spec.step),
                    int(spec.seed),
                    json.dumps(spec.params, sort_keys=True, default=_plain),
                    json.dumps(metrics, default=_plain),
                    self.version,
                    time.time(),
                ),
            )

    def import_rows(self, rows: list[dict]) -> int:
        """Add rows as `rows()` returns them (e.g. read back from an export), each keeping the code version that wrote
        it; a trial the store already holds keeps its own row. Returns how many were added."""
        before = self.count()
        with self._db:
            self._db.executemany(
                "INSERT OR IGNORE INTO trials VALUES (?,?,?,?,?,?,?,?,?,?)",
                [
                    (
                        TrialSpec(r["experiment"], r["scene"], r["method"], r["step"], r["seed"], r["params"]).key,
                        r["experiment"],
                        r["scene"],
                        r["method"],
                        float(r["step"]),
                        int(r["seed"]),
                        json.dumps(r["params"], sort_keys=True, default=_plain),
                        json.dumps(r["metrics"], default=_plain),
                        r["code_version"],
                        time.time(),
                    )
                    for r in rows
                ],
            )
        return self.count() - before

    def rows_for(self, specs: list[TrialSpec]) -> list[dict]:
        """The stored rows of exactly these trials (a store may hold other sweeps, or other parameters)."""
        wanted = {s.key for s in specs}
        return [
            r
            for r in self.rows()
            if TrialSpec(r["experiment"], r["scene"], r["method"], r["step"], r["seed"], r["params"]).key in wanted
        ]

    def rows(self, experiment: str | None = None) -> list[dict]:
        query = "SELECT experiment, scene, method, step, seed, params, metrics, code_version FROM trials"
        args = ()
        if experiment:
            query += " WHERE experiment = ?"
            args = (experiment,)
        out = []
        for experiment_, scene, method, step, seed, params, metrics, version in self._db.execute(
            query + " ORDER BY experiment, scene, method, step, seed", args
        ):
            out.append(
                {
                    "experiment": experiment_,
                    "scene": scene,
                    "method": method,
                    "step": step,
                    "seed": seed,
                    "params": json.loads(params),
                    "metrics": json.loads(metrics),
                    "code_version": version,
                }
            )
        return out

    def finished(self) -> dict[str, float]:
        """key -> when its row was written (seconds since the epoch): a table made from rows can date them."""
        return dict(self._db.execute("SELECT key, finished FROM trials"))

    def count(self) -> int:
        return self._db.execute("SELECT COUNT(*) FROM trials").fetchone()[0]
