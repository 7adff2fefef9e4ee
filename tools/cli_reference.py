"""The command-line reference page, generated from the ``energy-margin`` argument parsers.

``python tools/cli_reference.py`` prints the page's Markdown; the docs site's hook
(``tools/mkdocs_hooks.py``) puts it in ``docs/reference/cli.md`` at every build, so the page
always lists the options the installed parsers accept.
"""

from __future__ import annotations

import argparse
import os

from energy_margin.cli import build_parser
from energy_margin.cli.common import HelpFormatter

#: Where the generated text goes in a page.
MARKER = "<!-- cli-reference -->"


def _cell(text: str) -> str:
    return " ".join(text.split()).replace("|", "\\|")


def _flags(action: argparse.Action) -> str:
    if action.option_strings:
        names = ", ".join(f"`{name}`" for name in action.option_strings)
        if action.nargs != 0:
            metavar = action.metavar or (action.dest.upper() if not action.choices else None)
            if metavar is None:
                metavar = "{" + ",".join(str(choice) for choice in action.choices or ()) + "}"
            names += f" `{metavar}`"
        return names
    return f"`{action.metavar or action.dest}`"


def _help(parser: argparse.ArgumentParser, action: argparse.Action) -> str:
    if not action.help or action.help == argparse.SUPPRESS:
        return ""
    formatter = HelpFormatter(parser.prog)
    return _cell(formatter._expand_help(action))


def _subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def command_markdown(name: str, parser: argparse.ArgumentParser) -> str:
    """One command's section: usage, description, options, examples."""
    lines = [f"## {name}", "", parser.description or "", ""]
    lines += ["```text", parser.format_usage().strip(), "```", ""]
    rows = [action for action in parser._actions if not isinstance(action, argparse._HelpAction)]
    if rows:
        lines += ["| argument | meaning |", "|---|---|"]
        lines += [f"| {_flags(action)} | {_help(parser, action)} |" for action in rows]
        lines.append("")
    if parser.epilog:
        lines += ["```bash", *(line.strip() for line in parser.epilog.splitlines()[1:] if line.strip()), "```", ""]
    return "\n".join(lines)


def markdown() -> str:
    """The reference of every command, in the order ``energy-margin --help`` lists them."""
    os.environ["COLUMNS"] = "100"  # usage lines wrap the same on every machine
    parser = build_parser()
    commands = _subcommands(parser)
    lines = ["| command | what it does |", "|---|---|"]
    for name, sub in commands.items():
        lines.append(f"| [`{name}`](#{name.replace('_', '-')}) | {_cell(sub.description or '')} |")
    sections = [command_markdown(name, sub) for name, sub in commands.items()]
    return "\n".join(lines) + "\n\n" + "\n".join(sections)


if __name__ == "__main__":
    print(markdown())
