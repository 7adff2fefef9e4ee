"""What every command shares: one-line argument errors, argument types and a progress bar."""

from __future__ import annotations

import argparse
import json
import os
import sys
from typing import Any, NoReturn

from energy_margin.errors import EnergyMarginError

__all__ = [
    "PROG",
    "DeprecatedAlias",
    "HelpFormatter",
    "Parser",
    "ProgressBar",
    "add_engine",
    "add_old_spelling",
    "add_overwrite",
    "add_seed",
    "add_set",
    "analyzer_default",
    "non_negative_float",
    "non_negative_int",
    "one_line",
    "positive_float",
    "positive_int",
    "print_json",
    "require_matplotlib",
    "say_notes",
    "scene_task_config",
    "task_overrides",
]

PROG = "energy-margin"


class Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line."""

    def error(self, message: str) -> NoReturn:
        """Exit with status 2 and one line on standard error."""
        self.exit(2, f"{self.prog}: error: {message}\n")


class HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """Keeps the example lines of a command's epilog as written; shows defaults where given."""


def non_negative_int(text: str) -> int:
    """An integer >= 0."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {value}")
    return value


def positive_int(text: str) -> int:
    """An integer >= 1."""
    value = non_negative_int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {value}")
    return value


def non_negative_float(text: str) -> float:
    """A finite number >= 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not value >= 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"expected a finite number >= 0, got {text}")
    return value


def positive_float(text: str) -> float:
    """A finite number > 0."""
    value = non_negative_float(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"expected a finite number > 0, got {text}")
    return value


def analyzer_default(name: str) -> Any:
    """The default of :class:`~energy_margin.analysis.frame.AnalyzerConfig`'s field ``name``.

    Every command that sets an analyzer field takes its default from here, so the command line
    and Python cannot differ.
    """
    from energy_margin.analysis.frame import AnalyzerConfig
    from energy_margin.errors import field_default

    return field_default(AnalyzerConfig, name)


def add_engine(parser: argparse.ArgumentParser, *, records: bool = False) -> None:
    """The ``--engine`` option, with the engines as its choices (``records``: those that record roll-outs)."""
    from energy_margin.sim import ENGINES, recording_engines

    choices = recording_engines() if records else ENGINES
    parser.add_argument(
        "--engine", choices=choices, default="mujoco", help=f"physics engine: {', '.join(choices)} (default mujoco)"
    )


def add_seed(parser: argparse.ArgumentParser) -> None:
    """The ``--seed`` option."""
    parser.add_argument("--seed", type=non_negative_int, default=0, help="seed (default 0)")


def add_set(parser: argparse.ArgumentParser, help_text: str) -> None:
    """The repeatable ``--set KEY=JSON`` option (read with :func:`task_overrides`)."""
    parser.add_argument("--set", action="append", default=[], metavar="KEY=JSON", help=help_text)


def task_overrides(pairs: list[str], *, option: str = "--set") -> dict[str, object]:
    """``KEY=JSON`` pairs of ``option`` (``--set`` by default) as a dictionary."""
    overrides: dict[str, object] = {}
    for pair in pairs:
        key, sep, text = pair.partition("=")
        if not sep or not key:
            raise EnergyMarginError(f"{option} expects KEY=JSON, got {pair!r}")
        try:
            overrides[key] = json.loads(text)
        except json.JSONDecodeError:
            raise EnergyMarginError(f"{option} {key}: {text!r} is not valid JSON") from None
    return overrides


def scene_task_config(scene: str, overrides: dict[str, object]) -> tuple[str, dict[str, object]]:
    """The task name and configuration of ``--scene SCENE.toml``; ``--set`` sets its ``[design]`` parameters only."""
    if overrides:
        from energy_margin.tasks.scene_file import read_scene_file

        declared = [entry.name for entry in read_scene_file(scene).design]
        other = [key for key in overrides if key not in declared]
        if other:
            names = ", ".join(declared) if declared else "it declares none"
            raise EnergyMarginError(
                f"--set does not apply to --scene {scene} except for its [design] parameters ({names}): "
                f"{other[0]!r} is not one; edit the scene file instead"
            )
    return "scene", {"scene_file": os.path.abspath(scene), **overrides}


def print_json(value: Any) -> None:
    """Print ``value`` as one JSON object with sorted keys."""
    print(json.dumps(value, sort_keys=True))


class ProgressBar:
    """A tqdm bar on a terminal (or with ``ENERGY_MARGIN_PROGRESS=1``); silent otherwise."""

    def __init__(self, total: int, desc: str, unit: str = "traj") -> None:
        self._bar = None
        if sys.stderr.isatty() or os.environ.get("ENERGY_MARGIN_PROGRESS") == "1":
            from tqdm import tqdm

            self._bar = tqdm(total=total if isinstance(total, int) and total > 0 else 0, desc=desc, unit=unit)

    def update(self, count: int) -> None:
        """Advance by ``count``."""
        if self._bar is not None:
            self._bar.update(count)

    def close(self) -> None:
        """Close the bar."""
        if self._bar is not None:
            self._bar.close()


def say_notes(*notes: str | None) -> None:
    """Print each note (one line, a warning, not an error) on standard error; ``None`` is skipped."""
    for note in notes:
        if note:
            print(one_line(note), file=sys.stderr, flush=True)


def require_matplotlib() -> None:
    """Raise a one-line hint when the ``plot`` extra is missing."""
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise EnergyMarginError("the report needs matplotlib: pip install 'energy-margin[plot]'") from None


def one_line(message: str) -> str:
    """Collapse whitespace so an error is always reported on a single line."""
    return " ".join(message.split())


def add_overwrite(parser: argparse.ArgumentParser, what: str = "a run of other settings in --out") -> None:
    """``--overwrite``: the one rule of every run directory (energy_margin.runs): replace ``what``."""
    parser.add_argument("--overwrite", action="store_true", help=f"replace {what} (only the run's own files)")


class DeprecatedAlias(argparse.Action):
    """Store the value of an option whose old spelling still works for one release, with a warning.

    ``parser.add_argument("--object-bodies", "--objects", action=DeprecatedAlias, old="--objects")``:
    the first option string is the name; the old one says so on standard error when used.
    :func:`add_old_spelling` adds an old spelling as its own option, hidden from the help.
    """

    def __init__(
        self, option_strings: list[str], dest: str, *, old: str, new: str | None = None, **kwargs: Any
    ) -> None:
        super().__init__(option_strings, dest, **kwargs)
        self.old = old
        self.new = new if new is not None else option_strings[0]

    def __call__(
        self,
        parser: argparse.ArgumentParser,
        namespace: argparse.Namespace,
        values: Any,
        option_string: str | None = None,
    ) -> None:
        """Store ``values``; say on standard error when the old spelling gave them."""
        if option_string == self.old:
            print(f"{parser.prog}: {self.old} is now {self.new}; the old name goes in 0.3", file=sys.stderr)
        setattr(namespace, self.dest, values)


def add_old_spelling(
    parser: argparse.ArgumentParser | argparse._ArgumentGroup, old: str, action: argparse.Action
) -> None:
    """Accept ``old`` for one release as the option of ``action``, hidden from the help, with a warning.

    ``add_old_spelling(parser, "--iterations", parser.add_argument("--expansions", ...))``: the old
    option takes the same values into the same ``dest``; errors and help name the new one.
    """
    typed: dict[str, Any] = {"type": action.type} if action.type is not None else {}
    parser.add_argument(
        old,
        dest=action.dest,
        nargs=action.nargs,
        **typed,
        action=DeprecatedAlias,
        old=old,
        new=action.option_strings[0],
        default=action.default,
        help=argparse.SUPPRESS,
    )
