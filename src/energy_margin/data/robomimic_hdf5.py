"""Reading a robomimic / robosuite HDF5 file: its demonstrations' states, model XML and time step.

The layout is described in :mod:`energy_margin.data.robomimic`; every problem is one line naming
the file and the demonstration.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.errors import EnergyMarginError

__all__: list[str] = []


_DEMO = re.compile(r"demo_(\d+)")
#: What h5py raises for a file, group, dataset or attribute it cannot read.
_HDF5_ERRORS = (OSError, RuntimeError, ValueError, KeyError, TypeError)


@dataclass(frozen=True)
class _RawDemo:
    """One demonstration as stored: its key, ``states`` (N, D), ``model_file`` text, ``actions`` rows."""

    key: str
    states: np.ndarray
    model_file: str
    action_rows: int | None


def _one_line(error: BaseException) -> str:
    return " ".join(str(error).split()) or type(error).__name__


def _text(value: Any) -> str | None:
    """An HDF5 string attribute as text (h5py gives ``str``, ``bytes`` or a NumPy scalar)."""
    if isinstance(value, np.ndarray) and value.shape == ():
        value = value[()]
    if isinstance(value, bytes | np.bytes_):
        try:
            return bytes(value).decode("utf-8")
        except UnicodeDecodeError:
            return None
    if isinstance(value, str):
        return value
    return None


def _read_file(path: Path) -> tuple[list[_RawDemo], float | None]:
    """The demonstrations of the file at ``path`` in the order of their numbers, and ``env_args``' dt."""
    try:
        import h5py
    except ImportError:
        raise EnergyMarginError(
            f"{path}: reading robomimic files needs h5py: pip install 'energy-margin[demos]'"
        ) from None
    try:
        is_file = path.is_file()
    except OSError as error:
        raise EnergyMarginError(f"{path}: cannot be read ({error.strerror})") from None
    if not is_file:
        raise EnergyMarginError(f"{path}: {'is not a file' if path.exists() else 'does not exist'}")
    demos: list[_RawDemo] = []
    try:
        with h5py.File(path, "r") as handle:
            data = handle.get("data")
            if not isinstance(data, h5py.Group):
                raise EnergyMarginError(
                    f"{path}: has no group 'data' (a robomimic file holds data/demo_0, data/demo_1, ...)"
                )
            numbered = sorted((int(match.group(1)), name) for name in data if (match := _DEMO.fullmatch(name)))
            if not numbered:
                raise EnergyMarginError(f"{path}:/data: holds no demonstration (groups demo_0, demo_1, ...)")
            env_dt = _env_dt(data.attrs.get("env_args"))
            for _, key in numbered:
                demos.append(_read_demo(h5py, path, key, data[key]))
    except EnergyMarginError:
        raise
    except _HDF5_ERRORS as error:
        raise EnergyMarginError(f"{path}: not a readable HDF5 file ({_one_line(error)})") from None
    return demos, env_dt


def _read_demo(h5py: Any, path: Path, key: str, group: Any) -> _RawDemo:
    where = f"{path}:/data/{key}"
    if not isinstance(group, h5py.Group):
        raise EnergyMarginError(f"{where}: is a dataset, expected a group with states and model_file")
    states_item = group.get("states")
    if not isinstance(states_item, h5py.Dataset):
        raise EnergyMarginError(f"{where}: has no dataset 'states' (N, 1 + nq + nv), the flattened MuJoCo state")
    if states_item.shape is None or states_item.dtype.kind not in "fiu":
        raise EnergyMarginError(f"{where}: states: must hold numbers, got {states_item.dtype}")
    states = np.asarray(states_item[()], dtype=float)
    if states.ndim != 2 or states.shape[0] < 1:
        raise EnergyMarginError(f"{where}: states: must be a non-empty (N, D) array, got shape {states.shape}")
    if "model_file" not in group.attrs:
        raise EnergyMarginError(f"{where}: has no attribute 'model_file' (the MuJoCo model's XML)")
    model_file = _text(group.attrs["model_file"])
    if not model_file:
        raise EnergyMarginError(f"{where}: model_file: must be the MuJoCo model's XML as text")
    actions = group.get("actions")
    action_rows = None
    if isinstance(actions, h5py.Dataset) and actions.shape:
        action_rows = int(actions.shape[0])
    return _RawDemo(key, states, model_file, action_rows)


def _env_dt(env_args: Any) -> float | None:
    """1 / ``env_kwargs.control_freq`` of the ``env_args`` JSON attribute, or ``None``."""
    text = _text(env_args)
    if text is None:
        return None
    try:
        parsed = json.loads(text)
    except (ValueError, RecursionError):
        return None
    kwargs = parsed.get("env_kwargs") if isinstance(parsed, dict) else None
    frequency = kwargs.get("control_freq") if isinstance(kwargs, dict) else None
    if isinstance(frequency, bool) or not isinstance(frequency, int | float):
        return None
    if not math.isfinite(frequency) or frequency <= 0:
        return None
    return 1.0 / float(frequency)


def _file_sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as stream:
        for block in iter(lambda: stream.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()
