"""The ``irlsim`` command line. Each sub-command lives in a stage module of ``pipelines/``.

A stage module defines ``HELP: str``, ``add_arguments(parser)`` and ``run(args) -> int``. Only the module of
the command being run is imported (by name, below), so ``irlsim sim`` does not pay for importing torch.
``irlsim.cli`` is the console script's thin entry point over :func:`main`; ``irlsim demo`` calls
:func:`main` for each of its steps.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from typing import NoReturn

from irlsim.errors import IrlsimError
from irlsim.outputs import os_error_message

#: command name -> stage module
COMMANDS: dict[str, str] = {
    "net": "pipelines.net",
    "scenario": "pipelines.scenario",
    "sim": "pipelines.sim",
    "plot-cycle": "pipelines.plot_cycle",
    "collect": "pipelines.collect",
    "data": "pipelines.data_info",
    "train": "pipelines.train",
    "evaluate": "pipelines.evaluate",
    "drive": "pipelines.drive",
    "dagger": "pipelines.dagger",
    "bench": "pipelines.bench",
    "demo": "pipelines.demo",
}


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:
        # one line, what and how to fix, exit 2 (argparse's default prints usage first)
        self.exit(2, f"irlsim: error: {message} (see '{self.prog} --help')\n")


def build_parser(command: str | None) -> argparse.ArgumentParser:
    parser = _Parser(prog="irlsim", description="path-integral maximum-entropy deep IRL on SUMO roads")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for name, module_name in COMMANDS.items():
        if name == command:
            module = importlib.import_module(module_name)
            p = sub.add_parser(name, help=module.HELP, description=module.HELP)
            module.add_arguments(p)
            p.set_defaults(_run=module.run)
        else:
            sub.add_parser(name, help=f"see 'irlsim {name} --help'", add_help=False)
    return parser


#: numpy's BLAS on one thread unless the user says otherwise: irlsim runs in parallel by processes
#: (``--workers``, each on one thread), and a matrix product split over threads rounds otherwise than on
#: one, so a collection in this process (``--workers 1``) would not give a worker's bytes (measured on
#: dense traffic); set before the command's module imports numpy
BLAS_THREADS = ("OPENBLAS_NUM_THREADS", "1")


def main(argv: list[str] | None = None) -> int:
    os.environ.setdefault(*BLAS_THREADS)
    argv = list(sys.argv[1:] if argv is None else argv)
    command = next((a for a in argv if not a.startswith("-")), None)
    if command is not None and command not in COMMANDS:
        print(
            f"irlsim: error: unknown command '{command}' (choose from {', '.join(COMMANDS)})",
            file=sys.stderr,
        )
        return 2
    parser = build_parser(command)
    args = parser.parse_args(argv)
    if not getattr(args, "_run", None):
        parser.print_help()
        return 0 if not argv else 2
    try:
        return int(args._run(args) or 0)
    except IrlsimError as e:
        print(f"irlsim: error: {e}", file=sys.stderr)
        return 2
    except OSError as e:  # disk full, permissions, a vanished folder: one line naming the path, exit 1
        print(f"irlsim: error: {os_error_message(e)}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("irlsim: interrupted; finished files are kept, re-run the command to resume", file=sys.stderr)
        return 130
