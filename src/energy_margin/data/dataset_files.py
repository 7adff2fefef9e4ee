"""Writing dataset directories: the target's check, the atomic write and a working copy.

A dataset is written whole or not at all (:func:`write_directory` stages it in a sibling and
renames it); :func:`check_target` refuses to replace a non-empty directory unless asked;
:func:`copy_dataset` copies a dataset's two files into a working directory.
"""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.compat import save_npz
from energy_margin.data.dataset import FRAMES_FILE, METADATA_FILE
from energy_margin.errors import EnergyMarginError
from energy_margin.runs.files import staging_directory, write_json

__all__ = ["check_target", "copy_dataset", "write_directory"]


def copy_dataset(directory: Path, work: Path) -> None:
    """Copy the dataset files of ``directory`` into the working directory ``work`` (kept if there)."""
    work.mkdir(parents=True, exist_ok=True)
    for name in (METADATA_FILE, FRAMES_FILE):
        target = work / name
        if not target.exists():
            shutil.copyfile(directory / name, target)


def check_target(out: Path, *, overwrite: bool) -> None:
    """Refuse to replace a non-empty ``out`` unless ``overwrite``."""
    if overwrite or not out.exists():
        return
    if out.is_file() or any(out.iterdir()):
        raise EnergyMarginError(f"{out} already exists; pass `overwrite=True` to replace it")


def write_directory(
    out: Path,
    metadata: dict[str, Any],
    arrays: dict[str, np.ndarray],
    *,
    overwrite: bool,
    staging: Path | None = None,
) -> None:
    """Write a dataset directory atomically: staged in a sibling, then renamed onto ``out``.

    ``staging`` is a sibling of ``out`` from ``staging_directory`` that already holds other files
    of the dataset (they move with it); ``None`` makes a fresh one. It is removed on an error.
    """
    out.parent.mkdir(parents=True, exist_ok=True)
    staging = staging if staging is not None else staging_directory(out.parent, out.name)
    try:
        save_npz(staging / FRAMES_FILE, arrays, compressed=True)
        write_json(staging / METADATA_FILE, metadata)
        check_target(out, overwrite=overwrite)
        if out.is_dir():
            shutil.rmtree(out)
        elif out.exists():
            out.unlink()
        staging.rename(out)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
