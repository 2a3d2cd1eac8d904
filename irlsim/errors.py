"""User-facing errors: one line that says what is wrong and how to fix it."""


class IrlsimError(Exception):
    """An error caused by input (config, file, option) rather than a bug.

    The CLI prints ``irlsim: error: <message>`` and exits with status 2, without a traceback.
    Messages should name the problem and the fix, e.g.
    ``dataset data/x has schema version 1, this irlsim reads 2: re-run 'irlsim collect'``.
    """
