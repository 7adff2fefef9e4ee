"""Recorded MuJoCo roll-outs of a scene file's model turned into a dataset (``energy-margin record``).

A roll-out is one ``.npz`` file with ``time`` (n,) s, ``qpos`` (n, nq) and ``qvel`` (n, nv) in
MuJoCo's own state layout for the scene's compiled model, and optionally ``ctrl`` (n, nu) (checked,
not used: the analysis follows the scene file's declared motion from each frame's time) and
``mocap_pos`` (n, nmocap, 3) / ``mocap_quat`` (n, nmocap, 4) (without them the mocap bodies take
the declared motion's pose at each time). An HDF5 file (``.h5``/``.hdf5``, or any file with
``file_format="hdf5"``; read with h5py) holds one group per roll-out with the same arrays, taken in
the order of the group names (robomimic files: :mod:`energy_margin.data.robomimic`). ``time`` is
the motion's clock: 0 is its start. K frames are taken at the rows nearest to K evenly spaced
times from the first row to the last; the labels come from the scene file's capture and success
sets. Every problem is one line naming the
file and the array.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence, Sized
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from energy_margin.data.dataset import Dataset
from energy_margin.data.dataset_files import check_target
from energy_margin.data.generate import trajectory_record, write_records
from energy_margin.data.physical import frame_violations
from energy_margin.errors import EnergyMarginError, check_choice, check_positive_int
from energy_margin.runs.npz import NpzError, read_npz
from energy_margin.runs.progress import Progress, progress_bar
from energy_margin.sim.base import CompiledModel, Simulator, require
from energy_margin.sim.mujoco_audit import PHYSICS_WARNINGS, WARNINGS_ARRAY
from energy_margin.tasks import get_task
from energy_margin.tasks.recorded_path import nearest_rows
from energy_margin.tasks.scene_task import SceneTask
from energy_margin.tasks.state_box import StateBox
from energy_margin.world.state import FrameState

__all__ = [
    "DROPPED_KEY",
    "FILE_FORMATS",
    "check_rollout",
    "read_rollout_file",
    "record_dataset",
    "rollout_records",
]

_HDF5_SUFFIXES = (".h5", ".hdf5")
#: Key of ``dataset.json`` listing the roll-outs left out for a physically impossible frame.
DROPPED_KEY = "dropped"


#: What h5py raises for a file, group or dataset it cannot read.
_HDF5_ERRORS = (OSError, RuntimeError, ValueError, KeyError, TypeError)


#: The roll-out file formats ``record`` reads by itself (``None``: by the file's suffix).
FILE_FORMATS = ("npz", "hdf5")


def _load_arrays(path: Path, file_format: str | None = None) -> list[tuple[str, dict[str, np.ndarray]]]:
    """The roll-outs in one file: ``(name, arrays)``; an ``.npz`` holds one, an HDF5 file one per group."""
    try:
        is_file = path.is_file()
    except OSError as error:
        raise EnergyMarginError(f"{path}: roll-out file cannot be read ({error.strerror})") from None
    if not is_file:
        problem = "is not a file" if path.exists() else "does not exist"
        raise EnergyMarginError(f"{path}: roll-out file {problem}")
    if file_format == "hdf5" or (file_format is None and path.suffix.lower() in _HDF5_SUFFIXES):
        return _load_hdf5(path)
    try:
        arrays = read_npz(path)
    except NpzError as error:
        raise EnergyMarginError(f"{path}: not a readable .npz roll-out ({error})") from None
    return [(str(path), arrays)]


def _load_hdf5(path: Path) -> list[tuple[str, dict[str, np.ndarray]]]:
    """One roll-out per group of the HDF5 file at ``path``, in the order of the group names."""
    try:
        import h5py
    except ImportError:
        raise EnergyMarginError(
            f"{path}: reading HDF5 roll-outs needs h5py: pip install 'energy-margin[hdf5]'"
        ) from None
    rollouts = []
    try:
        with h5py.File(path, "r") as handle:
            for group_name in sorted(handle):
                where = f"{path}:/{group_name}"
                try:
                    group = handle[group_name]
                except _HDF5_ERRORS as error:
                    raise EnergyMarginError(f"{where}: cannot be read ({_one_line(error)})") from None
                if not isinstance(group, h5py.Group):
                    raise EnergyMarginError(f"{where}: expected a group per roll-out, found a dataset")
                if group_name == "data" and any(str(key).startswith("demo_") for key in group):
                    raise EnergyMarginError(
                        f"{where}: holds demo_* groups, as a robomimic file does: pass `file_format=robomimic`"
                    )
                arrays = {}
                for key in sorted(group):
                    try:
                        item = group[key]
                        if not isinstance(item, h5py.Dataset):
                            continue
                        if item.shape is None:
                            raise EnergyMarginError(f"{where}: {key}: holds no data (an empty dataset)")
                        if item.dtype.kind not in "fiu":
                            raise EnergyMarginError(f"{where}: {key}: must hold numbers, got {item.dtype}")
                        arrays[key] = np.asarray(item[()])
                    except _HDF5_ERRORS as error:
                        raise EnergyMarginError(f"{where}: {key}: cannot be read ({_one_line(error)})") from None
                rollouts.append((where, arrays))
    except _HDF5_ERRORS as error:
        raise EnergyMarginError(f"{path}: not a readable HDF5 file ({_one_line(error)})") from None
    if not rollouts:
        raise EnergyMarginError(f"{path}: holds no roll-out group")
    return rollouts


def _one_line(error: BaseException) -> str:
    return " ".join(str(error).split()) or type(error).__name__


def read_rollout_file(
    path: Path | str, model: mujoco.MjModel, *, file_format: str | None = None
) -> list[tuple[str, dict[str, np.ndarray]]]:
    """The checked roll-outs of one file for the scene's compiled ``model``, as ``(name, arrays)``.

    An ``.npz`` file holds one roll-out (named by the file), an HDF5 file one per group (named
    ``FILE:/GROUP``); every array is returned as float.

    Args:
        path: the file.
        model: the compiled model that recorded it.
        file_format: ``"npz"`` or ``"hdf5"``; ``None`` decides by the suffix (``.h5``, ``.hdf5``: HDF5).

    Raises:
        EnergyMarginError: an unreadable file, a missing array, a width that does not fit
            ``model``, a NaN or a ``time`` that does not increase (one line naming file and array).
    """
    if file_format is not None:
        check_choice("file_format", file_format, FILE_FORMATS)
    return [(name, check_rollout(name, raw, model)) for name, raw in _load_arrays(Path(path), file_format)]


def check_rollout(path: str, arrays: dict[str, np.ndarray], model: mujoco.MjModel) -> dict[str, np.ndarray]:
    """The arrays of one roll-out (``path`` names it in errors), checked against ``model``'s sizes, as float.

    Raises:
        EnergyMarginError: a missing ``time``, ``qpos`` or ``qvel``, a width that does not fit
            ``model``, a NaN or a ``time`` that does not increase (one line naming ``path`` and the array).
    """
    for name in ("time", "qpos", "qvel"):
        if name not in arrays:
            raise EnergyMarginError(f"{path}: {name}: array is missing (a roll-out needs time, qpos and qvel)")
    for name, value in arrays.items():
        if value.dtype.kind not in "fiu":
            raise EnergyMarginError(f"{path}: {name}: must hold numbers, got {value.dtype}")
    time = arrays["time"].astype(float)
    if time.ndim != 1 or time.size < 1:
        raise EnergyMarginError(f"{path}: time: must be a non-empty 1-d array, got shape {time.shape}")
    n = time.size
    widths = {
        "qpos": (n, int(model.nq)),
        "qvel": (n, int(model.nv)),
        "ctrl": (n, int(model.nu)),
        "mocap_pos": (n, int(model.nmocap), 3),
        "mocap_quat": (n, int(model.nmocap), 4),
        WARNINGS_ARRAY: (n, len(PHYSICS_WARNINGS)),
    }
    for name, shape in widths.items():
        if name in arrays and arrays[name].shape != shape:
            raise EnergyMarginError(
                f"{path}: {name}: has shape {arrays[name].shape}, expected {shape} for the scene's model "
                f"(nq {model.nq}, nv {model.nv}, nu {model.nu}, nmocap {model.nmocap})"
            )
    for name, value in arrays.items():
        bad = np.argwhere(~np.isfinite(value.astype(float)))
        if bad.size:
            raise EnergyMarginError(f"{path}: {name}: NaN or infinite value at row {int(bad[0][0])}")
    steps = np.diff(time)
    if np.any(steps <= 0):
        row = int(np.flatnonzero(steps <= 0)[0]) + 1
        raise EnergyMarginError(f"{path}: time: is not increasing (row {row}: {time[row]} after {time[row - 1]})")
    return {name: value.astype(float) for name, value in arrays.items()}


def _warned(arrays: dict[str, np.ndarray]) -> str | None:
    """Where a recorded roll-out's MuJoCo warning counts first grew, in words (``None``: they never did)."""
    counts = arrays.get(WARNINGS_ARRAY)
    if counts is None:
        return None
    grown = np.argwhere(counts > counts[0])
    if not grown.size:
        return None
    row, column = (int(i) for i in grown[0])
    name = list(PHYSICS_WARNINGS)[column]
    return f"row {row}: MuJoCo warned {name} during the roll-out ({PHYSICS_WARNINGS[name]})"


def record_dataset(
    scene_file: Path | str,
    rollouts: Sequence[Path | str],
    *,
    n_frames: int,
    out: Path | str,
    overwrite: bool = False,
    progress: Progress = None,
    file_format: str | None = None,
    drop_unphysical: bool = False,
) -> Dataset:
    """Turn recorded roll-outs of a scene file's model into a dataset directory.

    Args:
        scene_file: the scene file whose model recorded the roll-outs.
        rollouts: one ``.npz`` per roll-out, or HDF5 files (``.h5``, ``.hdf5``) with one group per
            roll-out holding the same arrays (needs h5py); see the module docstring.
        n_frames: frames K per roll-out, >= 1 (at most the rows of the shortest roll-out).
        out: the dataset directory to create.
        overwrite: replace an existing ``out``.
        progress: after each roll-out: ``True`` a bar on standard error, a callable is called
            with 1 (:data:`~energy_margin.runs.progress.Progress`).
        file_format: ``"npz"`` or ``"hdf5"`` for every file; ``None`` decides by each file's suffix.
        drop_unphysical: leave out the roll-outs with a physically impossible frame (listed under
            ``dropped`` in ``dataset.json``) instead of refusing them.

    """
    check_positive_int("n_frames", n_frames)
    if file_format is not None:
        check_choice("file_format", file_format, FILE_FORMATS)
    if not rollouts:
        raise EnergyMarginError("record needs at least one roll-out file")
    task = get_task("scene", {"scene_file": str(Path(scene_file).resolve())})
    assert isinstance(task, SceneTask)
    out = Path(out)
    check_target(out, overwrite=overwrite)
    model = task.loaded.model
    loaded_rollouts: list[tuple[str, dict[str, np.ndarray]]] = []
    sources: list[dict[str, Any]] = []
    for item in rollouts:
        path = Path(item)
        loaded_rollouts.extend(read_rollout_file(path, model, file_format=file_format))
        sources.append({"file": path.name, "sha256": hashlib.sha256(path.read_bytes()).hexdigest()})
    dropped: list[dict[str, str]] | None = [] if drop_unphysical else None
    records = rollout_records(task, loaded_rollouts, n_frames=n_frames, progress=progress, dropped=dropped)
    extra: dict[str, Any] = {"recorded_from": sources, **({DROPPED_KEY: dropped} if dropped else {})}
    return write_records(task, records, out, engine="mujoco", extra=extra, overwrite=overwrite)


def rollout_records(
    task: SceneTask,
    rollouts: Sequence[tuple[str, dict[str, np.ndarray]]],
    *,
    n_frames: int,
    progress: Progress = None,
    dropped: list[dict[str, str]] | None = None,
) -> list[dict[str, Any]]:
    """The frames and labels of checked roll-outs, one :func:`trajectory_record` each.

    A roll-out with a frame outside the task's frame box (an object outside the scene's bounds or
    faster than its speed bound: data/physical.py) is refused; with ``dropped`` it is left out and
    ``{"rollout": name, "reason": ...}`` appended to ``dropped`` instead.

    Args:
        task: the scene task whose model recorded the roll-outs.
        rollouts: ``(name, arrays)`` as :func:`check_rollout` returns them; ``name`` names the
            roll-out in errors.
        n_frames: frames K per roll-out, taken at the rows nearest to K evenly spaced times.
        progress: after each roll-out (:data:`~energy_margin.runs.progress.Progress`).
        dropped: receives the roll-outs left out (``None``: refuse them).

    Raises:
        EnergyMarginError: a roll-out with fewer rows than ``n_frames``, an object quaternion
            that is not a unit quaternion, or a physically impossible frame (without ``dropped``),
            or every roll-out dropped.
    """
    loaded = task.loaded
    friction = task.default_friction()
    drive = np.ones(task.drive_size())
    simulator = task.make_simulator(loaded.n_objects, friction, drive)
    compiled = require(simulator, CompiledModel, purpose="record")
    box = task.frame_box
    records = []
    total = len(rollouts) if isinstance(rollouts, Sized) else 0
    bar = progress_bar(total, desc="record", unit="roll-out", enabled=progress)
    for name, arrays in rollouts:
        time = arrays["time"]
        if time.size < n_frames:
            raise EnergyMarginError(f"{name}: time: has {time.size} rows, fewer than `n_frames={n_frames}`")
        kept = _rollout_frames(task, simulator, compiled, box, drive, name, arrays, n_frames, dropped)
        if kept is not None:
            path = task.recorded_drive(time, arrays["qpos"], arrays["qvel"])
            records.append(trajectory_record(task, kept[0], kept[1], friction, path))
        bar.update(1)
    bar.close()
    if not records:
        raise EnergyMarginError(
            f"every roll-out has a physically impossible frame (the first: {dropped[0]['rollout'] if dropped else ''}: "
            f"{dropped[0]['reason'] if dropped else ''})"
        )
    return records


def _rollout_frames(
    task: SceneTask,
    simulator: Simulator,
    compiled: CompiledModel,
    box: StateBox,
    drive: np.ndarray,
    name: str,
    arrays: dict[str, np.ndarray],
    n_frames: int,
    dropped: list[dict[str, str]] | None,
) -> tuple[list[FrameState], list[float]] | None:
    """The roll-out's K frames and their times (s), or ``None`` when it is dropped (then listed in ``dropped``).

    Raises:
        EnergyMarginError: a warned or physically impossible roll-out without ``dropped``, or an
            object quaternion that is not a unit quaternion.
    """
    time = arrays["time"]
    frames: list[FrameState] = []
    times: list[float] = []
    warned = _warned(arrays)
    if warned is not None:
        if dropped is None:
            raise EnergyMarginError(
                f"{name}: {WARNINGS_ARRAY}: {warned}; a physically impossible frame never becomes data "
                "(`drop_unphysical=True` leaves such roll-outs out)"
            )
        dropped.append({"rollout": name, "reason": warned})
        return None
    for row in nearest_rows(time, n_frames):
        frame = _frame_at(task, simulator, compiled, drive, name, arrays, row)
        frames.append(frame)
        times.append(float(time[row]))
        violations = frame_violations(box, frame)
        if violations:
            reason = f"row {row} (frame {len(frames) - 1}): {violations[0].message}"
            if dropped is None:
                raise EnergyMarginError(
                    f"{name}: qpos: {reason}; a physically impossible frame never becomes data "
                    "(`drop_unphysical=True` leaves such roll-outs out)"
                )
            dropped.append({"rollout": name, "reason": reason})
            return None
    return frames, times


def _frame_at(
    task: SceneTask,
    simulator: Simulator,
    compiled: CompiledModel,
    drive: np.ndarray,
    name: str,
    arrays: dict[str, np.ndarray],
    row: int,
) -> FrameState:
    """The frame of row ``row``: its coordinates, velocities and mocap poses set, then forward.

    Raises:
        EnergyMarginError: an object quaternion that is not a unit quaternion.
    """
    model, data = compiled.model, compiled.data
    time = arrays["time"]
    mujoco.mj_resetData(model, data)
    data.qpos[:] = arrays["qpos"][row]
    data.qvel[:] = arrays["qvel"][row]
    command = task.model_command(drive, float(time[row]))
    if command is not None and command.mocap_pos is not None:
        data.mocap_pos[:] = command.mocap_pos
        data.mocap_quat[:] = command.mocap_quat
    if "mocap_pos" in arrays:
        data.mocap_pos[:] = arrays["mocap_pos"][row]
    if "mocap_quat" in arrays:
        data.mocap_quat[:] = arrays["mocap_quat"][row]
    mujoco.mj_forward(model, data)
    frame = simulator.frame_state()
    if np.any(np.abs(np.linalg.norm(frame.object_quat, axis=1) - 1.0) > 1e-3):
        raise EnergyMarginError(f"{name}: qpos: row {row} holds an object quaternion that is not a unit quaternion")
    return frame
