"""The ``energy-margin`` command line: a registry of commands, one module each.

Every command module under :mod:`energy_margin.cli` has ``NAME``, a one-line ``SUMMARY``,
``EXAMPLES``, ``add_arguments(parser)`` and ``run(args) -> int``. Adding a command is adding a
module and naming it in :data:`COMMANDS`; no other command changes.

A library function refuses a bad keyword argument with
:class:`~energy_margin.errors.InvalidParameterError`, whose message starts with the argument's
name, and names other arguments inside a message in backticks (```overwrite=True```); the error
line names the command's flags instead (``--objects must be a positive integer, got 0``, ``pass
--overwrite``). :func:`flag_for` is the one mapping: the flag of an argument is the option whose
argparse ``dest`` is its name (``workers`` is ``--workers``), or, for a name that differs, the
option of the ``dest`` that :data:`PARAMETER_DESTS` gives (``n_objects`` is ``--objects``), or the
one a command module's optional ``PARAMETER_FLAGS`` table gives for that command.
"""

from __future__ import annotations

import argparse
import errno
import os
import re
import signal
import sys
from collections.abc import Sequence
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from energy_margin.sim.mujoco_audit import WarningLog

from energy_margin._version import __version__
from energy_margin.cli import (
    analyze,
    budget,
    calibrate,
    check,
    control,
    design,
    evaluate,
    generate,
    import_reference,
    learn,
    monitor,
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
from energy_margin.errors import EnergyMarginError, InvalidParameterError
from energy_margin.runs.progress import close_all

__all__ = [
    "COMMANDS",
    "PARAMETER_DESTS",
    "build_parser",
    "error_message",
    "flag_for",
    "main",
    "parameter_flags",
]

#: The commands in the order ``--help`` lists them (the order data flows).
COMMANDS: tuple[ModuleType, ...] = (
    scene,
    generate,
    record,
    import_reference,
    check,
    analyze,
    evaluate,
    calibrate,
    monitor,
    perturb,
    budget,
    study,
    sweep,
    design,
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
        sub.set_defaults(run=command.run, parameter_flags=parameter_flags(sub, command))
    return parser


#: Keyword arguments of the library whose option has another ``dest``: name -> ``dest``. A name
#: maps to the flag only in the commands that have that ``dest``.
PARAMETER_DESTS = {
    "n_objects": "objects",
    "n_trajectories": "trajectories",
    "n_frames": "frames",
    "trajectory_counts": "counts",
    "scene_file": "scene",
    "file_format": "format",
    "frame_index": "frame",
    "config": "set",
    "design": "set",
}


def parameter_flags(parser: argparse.ArgumentParser, command: ModuleType) -> dict[str, str]:
    """The flag of each keyword argument a command passes on: ``dest`` -> ``--option``, then the tables.

    Each option's ``dest`` maps to its first long option string (``likelihood_lambda`` ->
    ``--lambda``); :data:`PARAMETER_DESTS` adds the names that differ from their ``dest``
    (``n_objects`` -> ``--objects``) where the command has that ``dest``; a command module's own
    ``PARAMETER_FLAGS``, when it has one, adds or overrides names last.
    """
    flags: dict[str, str] = {}
    for action in parser._actions:
        long = [option for option in action.option_strings if option.startswith("--")]
        if long and action.dest not in (argparse.SUPPRESS, "help"):
            flags.setdefault(action.dest, long[0])
    for name, dest in PARAMETER_DESTS.items():
        if dest in flags:
            flags.setdefault(name, flags[dest])
    flags.update(getattr(command, "PARAMETER_FLAGS", {}))
    return flags


def flag_for(command: str, parameter: str) -> str | None:
    """The option of ``command`` that sets the keyword argument ``parameter``; ``None`` if none does."""
    parser = build_parser()
    subparsers = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    flags: dict[str, str] = subparsers.choices[command].get_default("parameter_flags")
    return flags.get(parameter)


#: A keyword argument named inside a message: ```name``` or ```name=value```.
_NAMED = re.compile(r"`([A-Za-z_][A-Za-z0-9_]*)(?:=([^`]*))?`")


def error_message(error: EnergyMarginError, flags: dict[str, str]) -> str:
    """The one line of ``error``: each keyword argument it names becomes the command's flag for it.

    The argument an :class:`InvalidParameterError` starts with, and every ```name``` or
    ```name=value``` inside the message, become ``--flag`` or ``--flag value`` (``name=True``:
    ``--flag``). A name the command has no flag for keeps its own spelling.
    """
    if isinstance(error, InvalidParameterError) and error.parameter in flags:
        text = f"{flags[error.parameter]} {error.reason}"
    else:
        text = str(error)

    def flag(match: re.Match[str]) -> str:
        name, value = match.group(1), match.group(2)
        if name not in flags:
            return match.group(0)
        return flags[name] if value is None or value == "True" else f"{flags[name]} {value}"

    return one_line(_NAMED.sub(flag, text))


def _joined_camera(argv: list[str]) -> list[str]:
    """``--camera -135,-35`` as ``--camera=-135,-35``: argparse would read a negative azimuth as an option."""
    joined: list[str] = []
    for token in argv:
        if joined and joined[-1] == "--camera" and token.startswith("-") and "," in token:
            joined[-1] = f"--camera={token}"
        else:
            joined.append(token)
    return joined


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; return the exit status (0, 1 unexpected error, 2 bad input, 130 interrupted)."""
    args = build_parser().parse_args(_joined_camera(sys.argv[1:] if argv is None else list(argv)))
    from energy_margin.sim.mujoco_audit import WarningLog

    with WarningLog() as log:
        status = _run(args, argv)
    _keep_warnings(log, args, status)
    return status


def _keep_warnings(log: WarningLog, args: argparse.Namespace, status: int) -> None:
    """MuJoCo's warnings of the command into its output directory, never the working directory.

    Without an output directory, a command that succeeded says how often MuJoCo warned in one
    line on stderr; a failed one has said why in its error line.
    """
    if not log.messages:
        return
    for name in ("out", "dataset"):
        value = getattr(args, name, None)
        if isinstance(value, str | os.PathLike):
            path = log.write(Path(value))
            if path is not None:
                return
    if status != 0:
        return
    print(f"{PROG}: MuJoCo warned {len(log.messages)} time(s), the first: {one_line(log.messages[0])}", file=sys.stderr)


def _run(args: argparse.Namespace, argv: Sequence[str] | None) -> int:
    """Run the parsed command; map every error to its exit status."""
    try:
        return int(args.run(args))
    except EnergyMarginError as error:
        close_all()
        print(f"{PROG}: error: {error_message(error, getattr(args, 'parameter_flags', {}))}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        if argv is None:
            # This process is the command (console script, python -m): `timeout -s INT` signals
            # it and then its group, so a second SIGINT may arrive while the worker pool shuts
            # down at exit. The user has been heard; later ones are ignored. (Not when main() is
            # called from Python with arguments: children would inherit the ignored SIGINT.)
            signal.signal(signal.SIGINT, signal.SIG_IGN)
        close_all()
        print(f"{PROG}: interrupted; run the same command again to resume", file=sys.stderr)
        return 130
    except OSError as error:
        if error.errno not in _ENVIRONMENT_ERRORS or os.environ.get("ENERGY_MARGIN_DEBUG"):
            return _unexpected(error)
        # A full disk or quota is the machine's state, not a defect: what finished is on disk.
        close_all()
        where = f" writing {error.filename}" if error.filename else ""
        reason = os.strerror(error.errno).lower()
        print(f"{PROG}: error: {reason}{where}; make room and run the same command again to resume", file=sys.stderr)
        return 2
    except Exception as error:
        return _unexpected(error)


#: OSError numbers that say the machine cannot take the results now (one line, exit status 2).
_ENVIRONMENT_ERRORS = {errno.ENOSPC, errno.EDQUOT}


def _unexpected(error: Exception) -> int:
    """Report a defect in one line, exit status 1; re-raise it when ENERGY_MARGIN_DEBUG is set."""
    if os.environ.get("ENERGY_MARGIN_DEBUG"):
        raise error
    close_all()
    message = one_line(f"{type(error).__name__}: {error}")
    print(f"{PROG}: error: {message} (set ENERGY_MARGIN_DEBUG=1 for details)", file=sys.stderr)
    return 1
