"""The errors a user can cause, each reported as one line with its exit status."""
import argparse


class UserError(Exception):
    """An error the user caused (bad input, option or scene); reported as one line, exit status 2."""


class SolveError(Exception):
    """The nonlinear solver failed; reported as one line, exit status 3."""


class Interrupted(Exception):
    """SIGINT/SIGTERM arrived: the run stopped cleanly at a frame, with a checkpoint written."""

    def __init__(self, message, signum):
        super().__init__(message)
        self.signum = signum


class ArgParser(argparse.ArgumentParser):
    """argparse that reports a bad argument as one UserError line instead of usage + exit 2."""

    def error(self, message):
        raise UserError(f"{self.prog}: {message}")
