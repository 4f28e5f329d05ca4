"""The errors a user can cause, each reported as one line with its exit status."""
import argparse


class UserError(Exception):
    """An error the user caused (bad input, option or scene); reported as one line, exit status 2."""


def raise_agreed(mpi, message):
    """Collective: the bad-input check of a rank's own data, raised on every rank alike. message: this rank's error
    line (None or "": none); every rank raises UserError(the lowest rank's message) where any rank has one (raised
    on that rank alone, the others would wait in their next collective call for ever). mpi: an mpi4py communicator,
    or None for one process."""
    if mpi is not None and mpi.size > 1:
        message = next((m for m in mpi.allgather(message or None) if m), None)
    if message:
        raise UserError(message)


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
