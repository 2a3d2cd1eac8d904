"""The ``irlsim`` console script: the top of the layering, above ``pipelines`` (see
docs/design/layers.md). The command table and argument handling are :mod:`pipelines.commands`."""

from __future__ import annotations

import sys

from pipelines.commands import COMMANDS, build_parser, main

__all__ = ["COMMANDS", "build_parser", "main"]

if __name__ == "__main__":
    sys.exit(main())
