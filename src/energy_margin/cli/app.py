"""The ``energy-margin`` command line: a registry of commands, one module each.

Every command module under :mod:`energy_margin.cli` has ``NAME``, a one-line ``SUMMARY``,
``EXAMPLES``, ``add_arguments(parser)`` and ``run(args) -> int``. Adding a command is adding a
module and naming it in :data:`COMMANDS`; no other command changes.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
from collections.abc import Sequence
from types import ModuleType

from energy_margin._version import __version__
from energy_margin.cli import (
    analyze,
    budget,
    check,
    control,
    evaluate,
    generate,
    import_reference,
    learn,
    perturb,
    record,
    render,
    reproduce,
    scene,
    study,
    sweep,
    view,
)
from energy_margin.cli.common import PROG, HelpFormatter, Parser, one_line
from energy_margin.errors import EnergyMarginError

#: The commands in the order ``--help`` lists them (the order data flows).
COMMANDS: tuple[ModuleType, ...] = (
    scene,
    generate,
    record,
    import_reference,
    check,
    analyze,
    evaluate,
    perturb,
    budget,
    study,
    sweep,
    learn,
    control,
    view,
    render,
    reproduce,
)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of every command."""
    parser = Parser(
        prog=PROG,
        description="Energy-margin robustness of multi-object manipulation.",
        epilog=f"Run `{PROG} COMMAND --help` for a command's options and examples.",
    )
    parser.add_argument("--version", action="version", version=f"{PROG} {__version__}")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND", parser_class=Parser)
    for command in COMMANDS:
        examples = "\n".join(f"  {line}" for line in command.EXAMPLES)
        sub = commands.add_parser(
            command.NAME,
            help=command.SUMMARY,
            description=command.SUMMARY[0].upper() + command.SUMMARY[1:] + ".",
            epilog=f"example{'s' if len(command.EXAMPLES) > 1 else ''}:\n{examples}",
            formatter_class=HelpFormatter,
        )
        command.add_arguments(sub)
        sub.set_defaults(run=command.run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; return the exit status (0, 1 unexpected error, 2 bad input, 130 interrupted)."""
    args = build_parser().parse_args(argv)
    try:
        return int(args.run(args))
    except EnergyMarginError as error:
        print(f"{PROG}: error: {one_line(str(error))}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        if argv is None:
            # This process is the command (console script, python -m): `timeout -s INT` signals
            # it and then its group, so a second SIGINT may arrive while the worker pool shuts
            # down at exit. The user has been heard; later ones are ignored. (Not when main() is
            # called from Python with arguments: children would inherit the ignored SIGINT.)
            signal.signal(signal.SIGINT, signal.SIG_IGN)
        print(f"{PROG}: interrupted; run the same command again to resume", file=sys.stderr)
        return 130
    except Exception as error:
        if os.environ.get("ENERGY_MARGIN_DEBUG"):
            raise
        message = one_line(f"{type(error).__name__}: {error}")
        print(f"{PROG}: error: {message} (set ENERGY_MARGIN_DEBUG=1 for details)", file=sys.stderr)
        return 1
