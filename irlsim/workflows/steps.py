"""Chains of workflows (``irlsim demo``, DAgger rounds): one step's exit status as ``irlsim`` gives it."""

from __future__ import annotations

import sys
from collections.abc import Callable

from irlsim.errors import IrlsimError
from irlsim.outputs import os_error_message


def exit_status(step: Callable[[], bool]) -> int:
    """Run ``step`` (True: done, False: it failed after saying why) and return the exit status the
    equivalent ``irlsim`` command would: 0, 1 (a failure, or an OS error), 2 (an
    :class:`~irlsim.errors.IrlsimError`), 130 (Ctrl-C). Errors are printed as the command line prints
    them, one line, so a chain can name its failed step after it."""
    try:
        return 0 if step() else 1
    except IrlsimError as e:
        print(f"irlsim: error: {e}", file=sys.stderr)
        return 2
    except OSError as e:  # disk full, permissions, a vanished folder: one line naming the path
        print(f"irlsim: error: {os_error_message(e)}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("irlsim: interrupted; finished files are kept, re-run the command to resume", file=sys.stderr)
        return 130
