"""robomimic / robosuite demonstration files (HDF5) turned into a dataset (``record --format robomimic``).

The layout: a group ``data`` with one subgroup per demonstration, ``data/demo_0``, ``data/demo_1``,
... (taken in the order of the integer after ``demo_``). Each holds the dataset ``states`` (N, D),
the flattened MuJoCo state of every step (robosuite's ``MjSimState.flatten()``: time, qpos, qvel,
so D = 1 + nq + nv; D = nq + nv without the time is read too, the time of row i then being
i * dt), optionally ``actions`` (N, A), and the attribute ``model_file``, the MuJoCo model's XML.
``data`` may carry ``total`` and ``env_args`` (JSON; ``env_kwargs.control_freq`` gives dt = 1 /
control_freq for states without the time).

Each demonstration's model is rebuilt from its XML with ``mujoco.MjSpec``. The asset files a
robosuite XML names by the absolute paths of the machine that recorded it are looked for again:
a path that does not exist is re-rooted under the ``assets`` folder given (the part after
``models/assets/``, else the file's name) or under the installed robosuite's ``models/assets``
folder (found without importing robosuite). Every demonstration must compile to the same model.

The objects and the capture and success sets come from a scene file (its ``objects``,
``perturbation``, ``bounds``, ``capture`` and ``success`` tables; its model is not loaded) or from
body patterns and region tables given directly. The dataset directory gets a scene of its own,
``source/model.xml`` (the re-rooted XML) and ``source/scene.toml``, which its ``dataset.json``
names, so every later command rebuilds the task from the directory. The states carry no actuator
commands, so its motion declares ``robot = "recorded"`` (during analysis the robot follows each
demonstration's own recorded joint path from the frame on, kept in its drive parameters:
:mod:`~energy_margin.tasks.recorded_path`) or, with ``robot="coasting"`` or ``"still"``, that
(it keeps each frame's joint velocities, or is held where each frame has it).
Frames and labels are made as :func:`~energy_margin.data.record.record_dataset` makes them. Every
problem is one line naming the file and the demonstration; nothing is written then.

This module makes the frames and writes the dataset; :mod:`~energy_margin.data.robomimic_hdf5` reads
the file, :mod:`~energy_margin.data.robomimic_assets` rebuilds the models and
:mod:`~energy_margin.data.robomimic_scene` makes the scene.
"""

from __future__ import annotations

import shutil
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from energy_margin.data.dataset import Dataset
from energy_margin.data.dataset_files import check_target, write_directory
from energy_margin.data.generate import records_dataset
from energy_margin.data.record import DROPPED_KEY, check_rollout, rollout_records
from energy_margin.data.robomimic_assets import (
    _assets_folder,
    _build_models,
    _BuiltModel,
    compile_xml,
    reroot_assets,
)
from energy_margin.data.robomimic_hdf5 import (
    _file_sha256,
    _RawDemo,
    _read_file,
)
from energy_margin.data.robomimic_scene import (
    MODEL_FILE,
    ROBOT_CHOICES,
    ROBOT_DURING_ANALYSIS,
    SCENE_FILE,
    SOURCE_FOLDER,
    _scene_spec,
    _scene_text,
    _set_tables,
)
from energy_margin.errors import EnergyMarginError, check_choice, check_positive_float, check_positive_int
from energy_margin.runs.files import staging_directory
from energy_margin.runs.progress import Progress
from energy_margin.tasks import get_task
from energy_margin.tasks.scene_model import resolve_scene
from energy_margin.tasks.scene_task import SceneTask

__all__ = [
    "MODEL_FILE",
    "ROBOT_DURING_ANALYSIS",
    "SCENE_FILE",
    "SOURCE_FOLDER",
    "compile_xml",
    "record_robomimic",
    "reroot_assets",
]


def record_robomimic(
    path: Path | str,
    *,
    n_frames: int,
    out: Path | str,
    scene_file: Path | str | None = None,
    objects: str | Sequence[str] | None = None,
    capture: Mapping[str, Any] | str | None = None,
    success: Mapping[str, Any] | str | None = None,
    assets: Path | str | None = None,
    dt: float | None = None,
    robot: str = ROBOT_DURING_ANALYSIS,
    overwrite: bool = False,
    progress: Progress = None,
    drop_unphysical: bool = False,
) -> Dataset:
    """Turn the demonstrations of a robomimic / robosuite HDF5 file into a dataset directory.

    Args:
        path: the HDF5 file (``data/demo_*`` with ``states`` and the attribute ``model_file``).
        n_frames: frames K per demonstration, >= 1 (at most the rows of the shortest one).
        out: the dataset directory to create.
        scene_file: a scene file whose ``objects``, ``perturbation``, ``bounds``, ``capture`` and
            ``success`` tables apply (its ``mjcf`` is not loaded: the demonstrations' model is the
            model); instead of ``objects``, ``capture`` and ``success``.
        objects: object body names or glob patterns, a list or one comma-separated string.
        capture: the capture set: a region table (``{"type": "box", ...}``) or a scene file's
            ``[capture]`` table (``{"region": {...}, "at_least": 2}``), as a mapping or JSON text.
        success: the success set, likewise.
        assets: a folder to look for asset files (meshes, textures) the XML names by paths that do
            not exist here: the part of such a path after ``models/assets/``, else its file name.
        dt: seconds between rows for states without the time column (default: 1 /
            ``env_kwargs.control_freq`` of the file's ``env_args``).
        robot: what the robot does during analysis (the scene's ``motion.robot``):
            ``"recorded"`` (it follows the demonstration's recorded joint path), ``"coasting"`` (it
            keeps each frame's joint velocities) or ``"still"``.
        overwrite: replace an existing ``out``.
        drop_unphysical: leave out the demonstrations with a physically impossible frame (listed
            under ``dropped`` in ``dataset.json``) instead of refusing them.
        progress: after each demonstration: ``True`` a bar on standard error, a callable is
            called with 1 (:data:`~energy_margin.runs.progress.Progress`).

    Returns:
        The dataset written to ``out``, whose ``source/scene.toml`` and ``source/model.xml`` rebuild its task.

    Raises:
        EnergyMarginError: a file that is not in this layout, a demonstration whose states do not
            fit its model, hold a NaN or are too short, a model that does not compile or compiles
            to another model than the first demonstration's, an asset file that cannot be found,
            or a bad scene file or region table; one line each, and nothing is written.
    """
    check_positive_int("n_frames", n_frames)
    check_choice("robot", robot, ROBOT_CHOICES)
    if dt is not None:
        check_positive_float("dt", dt)
    path = Path(path)
    out = Path(out)
    tables = _set_tables(scene_file, objects, capture, success)
    assets_folder = _assets_folder(assets)
    check_target(out, overwrite=overwrite)
    raw_demos, env_dt = _read_file(path)
    built = _build_models(path, raw_demos, assets_folder)
    model = built[0].model
    rollouts = [_rollout(path, demo, model, dt if dt is not None else env_dt, n_frames) for demo in raw_demos]
    duration = _duration(rollouts, model)
    spec = _scene_spec(tables, scene_file, path, duration, robot)
    loaded = resolve_scene(spec, model)
    scene_text = _scene_text(spec, loaded, duration)
    sources = [
        {"file": path.name, "sha256": _file_sha256(path), "format": "robomimic", "demos": [d.key for d in raw_demos]}
    ]
    return _write(out, built[0], scene_text, rollouts, n_frames, sources, overwrite=overwrite, progress=progress,
                  drop_unphysical=drop_unphysical)  # fmt: skip


def _duration(rollouts: list[tuple[str, dict[str, np.ndarray]]], model: mujoco.MjModel) -> float:
    """The longest demonstration's duration, s (one time step when every one lasts no time)."""
    duration = max(float(arrays["time"][-1]) for _, arrays in rollouts)
    if duration <= 0:
        duration = float(model.opt.timestep)
    return duration


# -- the states --------------------------------------------------------------------------------


def _rollout(
    path: Path, demo: _RawDemo, model: mujoco.MjModel, dt: float | None, n_frames: int
) -> tuple[str, dict[str, np.ndarray]]:
    """The demonstration as a checked roll-out ``(name, {time, qpos, qvel})``."""
    where = f"{path}:/data/{demo.key}"
    states = demo.states
    rows, width = states.shape
    nq, nv = int(model.nq), int(model.nv)
    timed = width == 1 + nq + nv
    if timed:
        time, qpos, qvel = states[:, 0], states[:, 1 : 1 + nq], states[:, 1 + nq :]
    elif width == nq + nv:
        if dt is None:
            raise EnergyMarginError(
                f"{where}: states: has {width} columns, nq + nv ({nq} + {nv}) without the time, and the file's "
                "env_args gives no env_kwargs.control_freq: pass `dt`, the seconds between rows"
            )
        time, qpos, qvel = np.arange(rows) * dt, states[:, :nq], states[:, nq:]
    else:
        raise EnergyMarginError(
            f"{where}: states: has {width} columns, expected 1 + nq + nv = {1 + nq + nv} (time, qpos, qvel) "
            f"or nq + nv = {nq + nv} for its model (nq {nq}, nv {nv})"
        )
    bad = np.argwhere(~np.isfinite(states))
    if bad.size:
        raise EnergyMarginError(f"{where}: states: NaN or infinite value at row {int(bad[0][0])}")
    late = np.flatnonzero(np.diff(time) <= 0)
    if timed and late.size:
        row = int(late[0]) + 1
        raise EnergyMarginError(
            f"{where}: states: the time (column 0) does not increase at row {row} ({time[row]} after {time[row - 1]})"
        )
    if demo.action_rows is not None and demo.action_rows != rows:
        raise EnergyMarginError(f"{where}: actions: has {demo.action_rows} rows, states {rows}")
    if rows < n_frames:
        raise EnergyMarginError(f"{where}: states: has {rows} rows, fewer than `n_frames={n_frames}`")
    arrays = check_rollout(where, {"time": time, "qpos": qpos, "qvel": qvel}, model)
    return where, arrays


def _write(
    out: Path,
    built: _BuiltModel,
    scene_text: str,
    rollouts: list[tuple[str, dict[str, np.ndarray]]],
    n_frames: int,
    sources: list[dict[str, Any]],
    *,
    overwrite: bool,
    progress: Progress,
    drop_unphysical: bool = False,
) -> Dataset:
    """Build the dataset in a sibling of ``out`` with its ``source`` scene, then rename it onto ``out``."""
    out.parent.mkdir(parents=True, exist_ok=True)
    staging = staging_directory(out.parent, out.name)
    try:
        source = staging / SOURCE_FOLDER
        source.mkdir()
        (source / MODEL_FILE).write_text(built.xml, encoding="utf-8")
        (source / SCENE_FILE).write_text(scene_text, encoding="utf-8")
        task = get_task("scene", {"scene_file": str(source / SCENE_FILE)})
        assert isinstance(task, SceneTask)
        if task.loaded.model_sha256 != built.sha256:
            raise EnergyMarginError(
                f"{out}: the model written to {SOURCE_FOLDER}/{MODEL_FILE} does not compile to the recorded model "
                f"(sha256 {task.loaded.model_sha256[:12]}…, recorded {built.sha256[:12]}…)"
            )
        dropped: list[dict[str, str]] | None = [] if drop_unphysical else None
        records = rollout_records(task, rollouts, n_frames=n_frames, progress=progress, dropped=dropped)
        extra: dict[str, Any] = {"recorded_from": sources, **({DROPPED_KEY: dropped} if dropped else {})}
        dataset = records_dataset(task, records, out, engine="mujoco", extra=extra)
        metadata = dict(dataset.metadata)
        metadata["task_config"] = {
            **metadata["task_config"],
            "scene_file": str(out.resolve() / SOURCE_FOLDER / SCENE_FILE),
        }
        write_directory(out, metadata, dataset.arrays, overwrite=overwrite, staging=staging)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    return Dataset(path=out, metadata=metadata, arrays=dataset.arrays)
