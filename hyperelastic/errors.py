class UserError(Exception):
    """An error the user caused (bad input, option or scene); reported as one line, exit status 2."""


class SolveError(Exception):
    """The nonlinear solver failed; reported as one line, exit status 3."""
