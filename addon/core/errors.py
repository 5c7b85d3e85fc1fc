"""The one error type users see: a message that names the input and what to do."""


class UserError(Exception):
    """Bad input or an unusable environment. The command line prints it on one line and
    exits with status 2; operators report it as an ERROR."""


class Cancelled(Exception):
    """The user cancelled a job (a signal, or the add-on's Cancel). The command line exits
    with status 130; every output finished so far is kept whole."""
