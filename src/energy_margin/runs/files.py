"""Small file helpers: atomic writes, folders made with the user's umask, JSON with clear errors."""

from __future__ import annotations

import json
import os
import re
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from energy_margin.errors import EnergyMarginError

__all__ = [
    "atomic_path",
    "atomic_write_text",
    "current_umask",
    "directory_mode",
    "file_mode",
    "leftovers",
    "read_json",
    "remove_leftovers",
    "staging_directory",
    "write_json",
]


def current_umask() -> int:
    """The process's file-mode creation mask."""
    # /proc reads it without changing it (safe with threads); elsewhere set it and put it back.
    try:
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def file_mode() -> int:
    """Mode of a new regular file under the current umask (0o644 under the usual 022)."""
    return 0o666 & ~current_umask()


def directory_mode() -> int:
    """Mode of a new directory under the current umask (0o755 under the usual 022)."""
    return 0o777 & ~current_umask()


def staging_directory(parent: Path, name: str) -> Path:
    """A new, empty hidden directory in ``parent`` to build ``name`` in, with the umask's mode.

    ``tempfile.mkdtemp`` makes it 0o700 whatever the umask; the result is renamed onto the
    final path, so it gets the mode a plain ``mkdir`` would have given.
    """
    staging = Path(tempfile.mkdtemp(dir=parent, prefix=f".{name}."))
    staging.chmod(directory_mode())
    return staging


def atomic_write_text(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` so a reader sees either the old file or the whole new one.

    The file gets the mode a plain ``open(path, "w")`` would give it under the current umask.
    """
    path = Path(path)
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        # mkstemp creates 0o600 whatever the umask: a shared results folder could not read it.
        os.fchmod(handle, file_mode())
        with os.fdopen(handle, "w", encoding="utf-8") as stream:
            stream.write(text)
            stream.flush()
            os.fsync(stream.fileno())
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


@contextmanager
def atomic_path(path: Path) -> Iterator[Path]:
    """A temporary sibling of ``path`` to write a file into; renamed onto ``path`` when the block ends.

    When the block raises, the temporary file is removed and ``path`` is left as it was. The file
    gets the mode a plain ``open(path, "w")`` would give it under the current umask.
    """
    path = Path(path)
    handle, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=path.suffix)
    os.close(handle)
    temporary = Path(name)
    try:
        yield temporary
        os.chmod(temporary, file_mode())
        os.replace(temporary, path)
    except BaseException:
        temporary.unlink(missing_ok=True)
        raise


def leftovers(directory: Path, name: str | None = None) -> list[Path]:
    """What writers killed mid-way left in ``directory``: temporary files and staging folders.

    Those of :func:`atomic_write_text`, :func:`atomic_path` and :func:`staging_directory` for
    ``directory / name`` (``.NAME.XXXXXXXX.tmp``, ``.NAME.XXXXXXXX.SUFFIX``, ``.NAME.XXXXXXXX``,
    tempfile's eight random characters); of any name when ``name`` is ``None``.
    """
    if name is None:
        pattern = re.compile(r"\..+\.[a-z0-9_]{8}(?:\.[A-Za-z0-9]+)?")
    else:
        suffix = re.escape(Path(name).suffix)
        pattern = re.compile(rf"\.{re.escape(name)}\.[a-z0-9_]{{8}}(?:\.tmp|{suffix})?")
    try:
        entries = list(Path(directory).iterdir())
    except (FileNotFoundError, NotADirectoryError):
        return []
    return sorted(entry for entry in entries if pattern.fullmatch(entry.name))


def remove_leftovers(paths: list[Path]) -> None:
    """Remove temporary files and staging folders found by :func:`leftovers`."""
    for path in paths:
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path, ignore_errors=True)
        else:
            path.unlink(missing_ok=True)


def write_json(path: Path, value: Any) -> None:
    """Atomically write ``value`` as indented JSON."""
    atomic_write_text(path, json.dumps(value, indent=2, sort_keys=True) + "\n")


def read_json(path: Path, *, what: str) -> Any:
    """Read a JSON file, raising :class:`EnergyMarginError` naming ``what`` on any problem."""
    path = Path(path)
    if not path.is_file():
        raise EnergyMarginError(f"{what}: {path} does not exist")
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError, RecursionError) as error:
        raise EnergyMarginError(f"{what}: {path} is not valid JSON ({error})") from None
