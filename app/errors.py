"""The exceptions behind every failure a user should see as one line: bad input, an invalid start or goal, no path.

What each means to a process (its exit code) is the command line's business: `app.cli.EXIT_CODES`.
"""


class UserError(Exception):
    """Bad input: unknown name, malformed file, wrong-length or non-finite numbers."""


class InvalidEndpoint(UserError):
    """Start or goal is in collision or out of bounds."""


class NoPath(UserError):
    """The planner spent its budget without connecting start and goal."""


class SamplerBudgetExceeded(UserError):
    """A sampler spent its collision-check budget before it had k samples."""
