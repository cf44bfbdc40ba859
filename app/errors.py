"""The exit codes every command shares, as exceptions the CLI turns into one line on stderr."""


class UserError(Exception):
    """Bad input: unknown name, malformed file, wrong-length or non-finite numbers."""

    exit_code = 2


class InvalidEndpoint(UserError):
    """Start or goal is in collision or out of bounds."""

    exit_code = 3


class NoPath(UserError):
    """The planner spent its budget without connecting start and goal."""

    exit_code = 1
