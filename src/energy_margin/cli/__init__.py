"""The command line: one module per command, registered in :mod:`energy_margin.cli.app`."""

from energy_margin.cli.app import build_parser, main

__all__ = ["build_parser", "main"]
