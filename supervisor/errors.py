"""Errors that end a `sabo` command with a message and an exit code."""
from __future__ import annotations


class SaboError(Exception):
    """A failure to report to the user as one message, then exit with `exit_code`."""

    def __init__(self, message: str, exit_code: int = 1) -> None:
        super().__init__(message)
        self.exit_code = exit_code


# Exit codes of `./sabo`.
EXIT_OK = 0
EXIT_FAILED = 1        # the run (or a setup step) failed
EXIT_BAD_INPUT = 2     # wrong command line, scene errors, run folder refused
EXIT_INTERRUPTED = 130  # stopped by Ctrl-C / SIGTERM
