"""Reading a user's ``.npz`` archive (a roll-out, a control file, a saved model) without trusting it.

:func:`read_npz` reads every ``.npy`` member of the archive with ``allow_pickle=False`` and
checks each member's header before anything is allocated for it. Every way the file can be
unreadable (not a zip archive, truncated, corrupt compressed data, an encrypted or unknown
compression, a broken ``.npy`` header, Python objects, less data than the header declares) raises
:class:`NpzError` with a one-line reason, which the caller turns into an
:class:`~energy_margin.errors.EnergyMarginError` naming its file.
"""

from __future__ import annotations

import lzma
import math
import zipfile
import zlib
from pathlib import Path

import numpy as np

__all__ = [
    "READ_ERRORS",
    "NpzError",
    "read_npz",
]

#: Everything reading a damaged archive or ``.npy`` member raises.
READ_ERRORS = (
    OSError,
    ValueError,
    EOFError,
    zipfile.BadZipFile,
    zlib.error,
    lzma.LZMAError,
    RuntimeError,
    MemoryError,
    NotImplementedError,
    OverflowError,
    TypeError,
)


class NpzError(ValueError):
    """The archive cannot be read; the message is one line saying why."""


def _one_line(error: BaseException) -> str:
    return " ".join(str(error).split()) or type(error).__name__


def read_npz(path: Path | str) -> dict[str, np.ndarray]:
    """Every array of the ``.npz`` archive at ``path``, by name (members not named ``*.npy`` are skipped).

    Raises:
        NpzError: the file is not a readable ``.npz`` archive of numeric or string arrays.
    """
    try:
        archive = zipfile.ZipFile(path)
    except READ_ERRORS as error:
        raise NpzError(f"not an .npz archive ({_one_line(error)})") from None
    arrays: dict[str, np.ndarray] = {}
    with archive:
        for info in archive.infolist():
            if info.is_dir() or not info.filename.endswith(".npy"):
                continue
            name = info.filename.removesuffix(".npy")
            try:
                arrays[name] = _read_member(archive, info)
            except NpzError as error:
                raise NpzError(f"array {name!r} {error}") from None
            except READ_ERRORS as error:
                raise NpzError(f"array {name!r} is corrupt ({_one_line(error)})") from None
    return arrays


def _read_member(archive: zipfile.ZipFile, info: zipfile.ZipInfo) -> np.ndarray:
    """One ``.npy`` member, its header checked against the member's size first."""
    with archive.open(info) as stream:
        version = np.lib.format.read_magic(stream)
        if version == (1, 0):
            shape, _, dtype = np.lib.format.read_array_header_1_0(stream)
        else:
            shape, _, dtype = np.lib.format.read_array_header_2_0(stream)
        header_length = stream.tell()
    if dtype.hasobject:
        raise NpzError("holds Python objects, not numbers")
    if any(size < 0 for size in shape):
        raise NpzError(f"has a negative size in its shape {shape}")
    if math.prod(shape) * dtype.itemsize > info.file_size - header_length:
        raise NpzError(f"is truncated (its header declares shape {shape} of {dtype})")
    with archive.open(info) as stream:
        value: np.ndarray = np.lib.format.read_array(stream, allow_pickle=False)
    return value
