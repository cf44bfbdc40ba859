"""The exceptions behind every failure a user should see as one line: bad input, an invalid start or goal, no path;
and the warnings library code gives instead of printing (PlannerWarning, Note).

Each carries a stable `code` (MoveIt's error-code names where they fit), so a program reading `--json` answers, or
calling the API, can tell failures apart without parsing messages. What each means to a process (its exit code) is
the command line's business: `app.cli.EXIT_CODES`.
"""


class PlannerWarning(UserWarning):
    """Something about the user's input worth a line that does not stop the work (`warnings.warn(message,
    PlannerWarning)`): library code warns and never prints. The command line shows it as one line, "warning: ..."."""


class Note(PlannerWarning):
    """A PlannerWarning that changes nothing of the answer (what a model file holds that planning does not use): the
    command line shows it as "note: ..."."""


class UserError(Exception):
    """Bad input: unknown name, malformed file, wrong-length or non-finite numbers.

    Attributes:
        code: The failure's stable name, as a `--json` answer gives it: INVALID_INPUT here; each subclass says its
            own (MoveIt's error-code names where they fit).
    """

    code = "INVALID_INPUT"

    def __init__(self, message: str, code: str | None = None):
        super().__init__(message)
        if code is not None:
            self.code = code


class InvalidEndpoint(UserError):
    """Start or goal is in collision or out of bounds (START_STATE_IN_COLLISION, GOAL_IN_COLLISION,
    START_STATE_INVALID, GOAL_STATE_INVALID), or a goal pose has no collision-free inverse kinematics
    (NO_IK_SOLUTION)."""

    code = "START_STATE_INVALID"


class NoPath(UserError):
    """The planner spent its samples or its budget without connecting start and goal: PLANNING_FAILED, also when its
    check limit ran out; TIMED_OUT when its time limit did, PREEMPTED when it was cancelled. A planner's NoPath carries
    `details`: what the query spent (collision checks, distance queries, seconds per phase, rounds) and why it stopped
    ("stopped": "checks", "time", "cancelled" or None)."""

    code = "PLANNING_FAILED"


class SamplerBudgetExceeded(UserError):
    """A sampler spent its collision-check budget before it had k samples; `samples` holds those it had."""

    code = "PLANNING_FAILED"

    def __init__(self, message: str, samples=None):
        super().__init__(message)
        self.samples = samples
