"""What a subcommand raises for a mistake of the user's (the CLI prints it without a traceback)."""


class UserError(Exception):
    """A mistake of the user's (bad argument, missing file): printed without a traceback."""
