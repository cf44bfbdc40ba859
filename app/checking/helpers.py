"""Helper processes, each with its own oracle of the same scene, that answer part of the oracle's batches (and a cell
build's edges) by the raw loop while the oracle answers the rest: the raw loop's way onto more cores (see Helpers).
"""

from __future__ import annotations

import os

import numpy as np

# A helper's messages: a batch of configurations (their bytes), or a piece of edges to check (pickled).
CONFIGURATIONS, _EDGES = b"Q", b"E"
# Pieces per process a call's edges are cut into and handed out as each process finishes its last (a piece with
# colliding edges is quick, and no process should wait long on another).
_PIECES = 8
# Pieces a helper holds at once (one it checks, the next waiting).
_IN_FLIGHT = 2


class Helpers:
    """Processes, each with its own oracle of the same scene (`Scene.recipe`), that answer part of a batch by the raw
    loop while this process answers the rest: the raw loop's way onto more cores. Threads cannot share it (pydrake
    holds the GIL in HasCollisions), and Drake's threaded batch asks for signed distances
    (SceneGraphCollisionChecker's DoCheckContextConfigCollisionFree), which cost several times HasCollisions on mesh
    robots. They start in the background and are used once all are ready; one that fails (or dies) is given up, and
    this process answers alone. Their answers are the raw loop's, so the split changes no answer, only the time."""

    def __init__(self, recipe, count: int):
        self._recipe, self._count = recipe, count
        self._pipes: list = []
        self._processes: list = []
        self.state = "idle"  # then "starting", then "ready" or "failed"
        self.checked = False  # the oracle has held the ready helpers' answers to its own
        self._owner = os.getpid()  # the process that started them (set again by `start`)

    def start(self) -> None:
        import pickle
        import socket
        import subprocess
        import sys
        import weakref
        from multiprocessing.connection import Connection

        # A fresh interpreter, not multiprocessing's spawn: spawn runs the user's main script again in the child,
        # which a script without a `__main__` guard (most pydrake scripts) cannot survive. Its own session keeps a
        # terminal's Ctrl-C for the parent; a closed pipe (the parent gone) ends it.
        self._owner = os.getpid()
        try:
            for _ in range(self._count):
                ours, theirs = socket.socketpair()
                self._processes.append(
                    subprocess.Popen(
                        [sys.executable, "-c", f"from app.checking.oracle import serve; serve({theirs.fileno()})"],
                        pass_fds=(theirs.fileno(),),
                        stdin=subprocess.DEVNULL,
                        stdout=subprocess.DEVNULL,
                        stderr=subprocess.DEVNULL,
                        env={**os.environ, "PYTHONPATH": os.pathsep.join(path for path in sys.path if path)},
                        start_new_session=True,
                    )
                )
                theirs.close()
                self._pipes.append(Connection(ours.detach()))
                self._pipes[-1].send_bytes(pickle.dumps(self._recipe))
            self.state = "starting"
        except (OSError, pickle.PicklingError, AttributeError, TypeError):  # no processes here, or a recipe that
            self.give_up()  # does not pickle: the helpers started see their pipes close
        weakref.finalize(self, _stop, list(self._pipes), list(self._processes))

    def ready(self) -> bool:
        """Whether every helper has said it is ready (without waiting), and they are this process's: a forked copy of
        the parent must not talk on its pipes."""
        if self.state == "starting" and all(pipe.poll() for pipe in self._pipes):
            self.wait()
        return self.state == "ready" and os.getpid() == self._owner

    def wait(self) -> None:
        """Wait until every helper is ready or one has failed."""
        if self.state != "starting":
            return
        try:
            ok = all(pipe.recv_bytes() == b"ready" for pipe in self._pipes)
        except (EOFError, OSError):
            ok = False
        if ok:
            self.state = "ready"
        else:
            self.give_up()

    def free(self, Q: np.ndarray, raw_free) -> np.ndarray:
        """Free flags of Q (n, dim): the first part by raw_free here, the others in the helpers at the same time. A
        helper found gone has its part answered here, and the helpers are given up."""
        parts = np.array_split(np.arange(len(Q)), len(self._pipes) + 1)
        sent = []
        for pipe, part in zip(self._pipes, parts[1:]):
            try:
                pipe.send_bytes(CONFIGURATIONS + np.ascontiguousarray(Q[part]).tobytes())
                sent.append(True)
            except OSError:
                sent.append(False)
        free = np.empty(len(Q), bool)
        free[parts[0]] = raw_free(Q[parts[0]])
        for pipe, part, ok in zip(self._pipes, parts[1:], sent):
            try:
                if not ok:
                    raise EOFError
                free[part] = np.frombuffer(pipe.recv_bytes(), bool)
            except (EOFError, OSError, ValueError):
                self.state = "failed"
                free[part] = raw_free(Q[part])
        if self.state == "failed":
            self.give_up()
        return free

    def edges_free(self, Q1: np.ndarray, Q2: np.ndarray, resolution: float, here) -> tuple[np.ndarray, int]:
        """Free flags of the edges Q1[i] -> Q2[i], in pieces handed to whoever is idle: the helpers, and
        `here(Q1, Q2)`, this process's own check. Returns (flags, the helpers' checks). A helper found gone has its
        pieces checked here, and the helpers are given up once every piece is in."""
        import pickle

        pieces = np.array_split(np.arange(len(Q1)), min(len(Q1), (len(self._pipes) + 1) * _PIECES))[::-1]
        free, checks = np.empty(len(Q1), bool), 0
        # Each helper's pieces in flight, oldest first: it holds the next while it checks one, so it does not idle
        # while this process finishes a piece of its own.
        busy: dict[int, list] = {i: [] for i in range(len(self._pipes))}

        def hand(i: int) -> None:
            piece = pieces.pop()
            try:
                self._pipes[i].send_bytes(_EDGES + pickle.dumps((Q1[piece], Q2[piece], resolution)))
            except OSError:
                self.state = "failed"
                pieces.append(piece)
            else:
                busy[i].append(piece)

        def collect(i: int) -> int:
            piece = busy[i].pop(0)
            try:
                free[piece], count = pickle.loads(self._pipes[i].recv_bytes())
                return count
            except (EOFError, OSError, pickle.UnpicklingError):
                self.state = "failed"
                pieces.append(piece)
                return 0

        try:
            while True:
                for i in busy:
                    while len(busy[i]) < _IN_FLIGHT and pieces and self.state == "ready":
                        hand(i)
                if pieces:
                    piece = pieces.pop()
                    free[piece] = here(Q1[piece], Q2[piece])
                elif any(busy.values()):
                    checks += collect(next(i for i in busy if busy[i]))  # nothing left here: wait for a helper
                else:
                    break
                for i in busy:
                    while busy[i] and self._pipes[i].poll():
                        checks += collect(i)
        finally:  # (here() may end the check early): every answer is read, so that the pipes stay in step
            for i in busy:
                while busy[i]:
                    collect(i)
            if self.state == "failed":
                self.give_up()
        return free, checks

    def give_up(self) -> None:
        """Never use the helpers again: their pipes close, which ends them."""
        self.state = "failed"
        for pipe in self._pipes:
            pipe.close()
        self._pipes = []


def _stop(pipes: list, processes: list) -> None:
    """End the helpers: a closed pipe ends a helper's loop; one that does not end within a second is killed."""
    import subprocess

    for pipe in pipes:
        pipe.close()
    for process in processes:
        try:
            process.wait(timeout=1.0)
        except subprocess.TimeoutExpired:
            process.kill()
