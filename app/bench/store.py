"""The results store: every trial is one row in an SQLite file, keyed by what defines it.

A trial's key is a hash of its experiment, scene, method, step, seed and parameters, so a sweep that is killed and
started again skips exactly the rows already written (INSERT OR IGNORE: never a duplicate) and runs the rest
(never a lost trial). Each row is committed as it arrives; SQLite's journal keeps a killed write from leaving a
half row. Reports are built from the store, not from memory.

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
from app.scene import ROOT

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
    """The git commit (with '+dirty' for uncommitted changes), or the package version outside a checkout."""
    try:
        commit = subprocess.run(
            ["git", "rev-parse", "--short=12", "HEAD"], cwd=ROOT, capture_output=True, text=True, timeout=10, check=True
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=10,
        ).stdout.strip()
        return commit + ("+dirty" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        from importlib.metadata import PackageNotFoundError, version

        try:
            return version("narrow-passage-planner")
        except PackageNotFoundError:
            return "unknown"


def _is_sqlite(path: Path) -> bool:
    with open(path, "rb") as f:
        return f.read(16) == b"SQLite format 3\x00"


class ResultStore:
    def __init__(self, path: Path):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        # SQLite takes a short file of any content for an empty database, and would overwrite it.
        if self.path.is_file() and self.path.stat().st_size and not _is_sqlite(self.path):
            raise UserError(f"cannot use {self.path} as a results store: it is not a SQLite file; name another")
        self._db = sqlite3.connect(self.path)
        try:
            self._check_schema()
        except BaseException:
            self._db.close()
            raise
        self._version = code_version()

    def _check_schema(self) -> None:
        # One statement, so both facts come from one snapshot: another process may be creating the store (the
        # table and the version are written in one transaction).
        version, has_trials = self._db.execute(
            "SELECT (SELECT user_version FROM pragma_user_version), "
            "EXISTS (SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = 'trials')"
        ).fetchone()
        if not has_trials and version == 0:  # a new store
            self._db.executescript(SCHEMA)
            return
        found = version or 1
        if found != SCHEMA_VERSION:
            raise UserError(
                f"results store {self.path} has schema {found}, this code writes {SCHEMA_VERSION}: "
                f"move it away and run again"
            )

    def close(self) -> None:
        self._db.close()

    def done_keys(self) -> set[str]:
        return {row[0] for row in self._db.execute("SELECT key FROM trials")}

    def pending(self, specs: list[TrialSpec]) -> list[TrialSpec]:
        done = self.done_keys()
        return [s for s in specs if s.key not in done]

    def add(self, spec: TrialSpec, metrics: dict) -> None:
        with self._db:  # one transaction per row: a kill loses at most the row being written
            self._db.execute(
                "INSERT OR IGNORE INTO trials VALUES (?,?,?,?,?,?,?,?,?,?)",
                (
                    spec.key,
                    spec.experiment,
                    spec.scene,
                    spec.method,
                    float(spec.step),
                    int(spec.seed),
                    json.dumps(spec.params, sort_keys=True, default=_plain),
                    json.dumps(metrics, default=_plain),
                    self._version,
                    time.time(),
                ),
            )

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

    def count(self) -> int:
        return self._db.execute("SELECT COUNT(*) FROM trials").fetchone()[0]


def spec_dict(spec: TrialSpec) -> dict:
    return asdict(spec)
