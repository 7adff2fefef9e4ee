"""The installed distribution's version: ``pyproject.toml`` is its single source."""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version

__all__: list[str] = []

try:
    __version__ = version("energy-margin")
except PackageNotFoundError:  # a source tree on sys.path that was never installed
    __version__ = "0+unknown"
