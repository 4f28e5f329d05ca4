class UserError(Exception):
    """An error the user caused (bad input, option or scene); reported as one line, exit status 2."""
