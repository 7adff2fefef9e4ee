"""The on-disk dataset: recorded frames, ground-truth labels and metadata (format version 1).

A dataset is a directory with two files:

``dataset.json``
    ``format`` ("energy-margin-dataset"), ``schema_version`` (1), ``task``, ``task_config`` (every
    resolved setting), ``engine``, ``seed``, ``n_trajectories`` (T), ``n_frames`` (K),
    ``n_objects`` (n), ``n_robot_dofs`` (r), ``n_drive`` (P), ``package_version``.
``frames.npz``
    ``object_pos`` (T, K, n, 3) m; ``object_quat`` (T, K, n, 4) (w, x, y, z); ``object_vel``
    (T, K, n, 6) m/s and rad/s, world frame; ``robot_q`` and ``robot_v`` (T, K, r);
    ``frame_time`` (T, K) s; ``friction`` (T,); ``drive`` (T, P); ``captured`` (T, K) bool, every
    object inside the capture region built from the same frame; ``in_success`` (T, K) bool, every
    object inside the success region.

Labels derive from the two boolean arrays: success of a trajectory is ``in_success`` at its last
frame; capture of frame k with window k-hat is ``captured`` at frames k .. k + k-hat (truncated at
the end of the trajectory).
"""

from __future__ import annotations

import json
import shutil
import tempfile
import zipfile
import zlib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin import __version__
from energy_margin.errors import EnergyMarginError
from energy_margin.io import read_json, write_json
from energy_margin.sim import ENGINES, make_simulator
from energy_margin.state import FrameState
from energy_margin.tasks import Task, command_robot, get_task

FORMAT = "energy-margin-dataset"
SCHEMA_VERSION = 1
METADATA_FILE = "dataset.json"
FRAMES_FILE = "frames.npz"

_FLOAT_ARRAYS = ("object_pos", "object_quat", "object_vel", "robot_q", "robot_v", "frame_time", "friction", "drive")
_BOOL_ARRAYS = ("captured", "in_success")


@dataclass(frozen=True)
class Dataset:
    """A loaded dataset (see the module docstring for every array's shape and unit)."""

    path: Path | None
    metadata: dict[str, Any]
    arrays: dict[str, np.ndarray]

    @property
    def task(self) -> Task:
        """The task, with the configuration the data were generated with."""
        return get_task(self.metadata["task"], self.metadata.get("task_config"))

    @property
    def n_trajectories(self) -> int:
        """T."""
        return int(self.metadata["n_trajectories"])

    @property
    def n_frames(self) -> int:
        """K."""
        return int(self.metadata["n_frames"])

    @property
    def n_objects(self) -> int:
        """N."""
        return int(self.metadata["n_objects"])

    def frame(self, trajectory: int, index: int) -> FrameState:
        """The recorded state of frame ``index`` of ``trajectory``."""
        a = self.arrays
        return FrameState(
            object_pos=a["object_pos"][trajectory, index],
            object_quat=a["object_quat"][trajectory, index],
            object_vel=a["object_vel"][trajectory, index],
            robot_q=a["robot_q"][trajectory, index],
            robot_v=a["robot_v"][trajectory, index],
        )

    def capture_labels(self, window: int = 0) -> np.ndarray:
        """Capture label of every frame, shape (T, K), bool.

        A frame is captured when every object lies in the capture region at frames
        k .. k + ``window`` (k-hat), each tested against the region built from that frame.
        """
        if window < 0:
            raise ValueError(f"window must be >= 0, got {window}")
        captured = self.arrays["captured"]
        labels = captured.copy()
        for shift in range(1, window + 1):
            labels[:, :-shift] &= captured[:, shift:]
        return labels

    def success_labels(self) -> np.ndarray:
        """Success label of every trajectory (every object in the success region at the last frame), (T,)."""
        return self.arrays["in_success"][:, -1].copy()


def _check_inputs(n_objects: int, n_trajectories: int, n_frames: int, seed: int) -> None:
    for name, value, minimum in (
        ("objects", n_objects, 1),
        ("trajectories", n_trajectories, 1),
        ("frames", n_frames, 1),
        ("seed", seed, 0),
    ):
        if isinstance(value, bool) or not isinstance(value, int | np.integer):
            raise EnergyMarginError(f"{name} must be an integer, got {value!r}")
        if value < minimum:
            raise EnergyMarginError(f"{name} must be >= {minimum}, got {value}")


def record_trajectory(
    task: Task, n_objects: int, n_frames: int, rng: np.random.Generator, *, engine: str = "mujoco"
) -> dict[str, Any]:
    """Run one scripted roll-out and record ``n_frames`` evenly spaced frames with their labels."""
    trajectory = task.sample_trajectory(rng, n_objects)
    simulator = make_simulator(task.build_scene(n_objects, trajectory.friction, trajectory.drive), engine)
    simulator.reset(trajectory.initial)
    record_at = task.frame_steps(n_frames)
    dt = simulator.timestep
    frames: list[FrameState] = []
    times: list[float] = []
    step = 0
    for target in record_at:
        while step < target:
            command_robot(task, simulator, trajectory.drive, step * dt, rng)
            simulator.step(1)
            step += 1
        frames.append(simulator.frame_state())
        times.append(step * dt)
    return {
        "object_pos": np.stack([f.object_pos for f in frames]),
        "object_quat": np.stack([f.object_quat for f in frames]),
        "object_vel": np.stack([f.object_vel for f in frames]),
        "robot_q": np.stack([f.robot_q for f in frames]),
        "robot_v": np.stack([f.robot_v for f in frames]),
        "frame_time": np.array(times),
        "friction": np.float64(trajectory.friction),
        "drive": np.asarray(trajectory.drive, dtype=float),
        "captured": np.array([task.is_captured(f) for f in frames]),
        "in_success": np.array([task.is_successful(f) for f in frames]),
    }


def generate_dataset(
    task_name: str,
    *,
    n_objects: int,
    n_trajectories: int,
    n_frames: int,
    seed: int,
    out: Path | str,
    engine: str = "mujoco",
    task_config: dict[str, Any] | None = None,
    overwrite: bool = False,
    progress: Callable[[int], None] | None = None,
) -> Dataset:
    """Generate scripted roll-outs and write them as a dataset directory.

    Trajectory ``i`` uses ``numpy.random.SeedSequence(seed).spawn(n_trajectories)[i]``. The
    directory is written to a temporary sibling and renamed, so an error leaves nothing behind.

    Args:
        task_name: a registered task.
        n_objects: objects per scene, >= 1.
        n_trajectories: roll-outs T, >= 1.
        n_frames: frames K per roll-out, >= 1.
        seed: non-negative integer seed.
        out: the dataset directory to create.
        engine: physics engine.
        task_config: overrides of the task's configuration.
        overwrite: replace an existing ``out``.
        progress: called with 1 after each trajectory.

    """
    _check_inputs(n_objects, n_trajectories, n_frames, seed)
    if engine not in ENGINES:
        raise EnergyMarginError(f"unknown engine {engine!r}; choose one of {', '.join(ENGINES)}")
    task = get_task(task_name, task_config)
    out = Path(out)
    if not overwrite:
        existing = _same_dataset(out, task, engine, seed, n_objects, n_trajectories, n_frames)
        if existing is not None:
            return existing
    _check_target(out, overwrite=overwrite)
    seeds = np.random.SeedSequence(seed).spawn(n_trajectories)
    records = []
    for child in seeds:
        try:
            records.append(record_trajectory(task, n_objects, n_frames, np.random.default_rng(child), engine=engine))
        except ValueError as error:
            raise EnergyMarginError(f"cannot generate {task_name} trajectories: {error}") from None
        if progress is not None:
            progress(1)
    arrays = {key: np.stack([r[key] for r in records]) for key in records[0]}
    metadata = {
        "format": FORMAT,
        "schema_version": SCHEMA_VERSION,
        "task": task.name,
        "task_config": task.config.to_dict(),
        "engine": engine,
        "seed": int(seed),
        "n_trajectories": n_trajectories,
        "n_frames": n_frames,
        "n_objects": n_objects,
        "n_robot_dofs": int(arrays["robot_q"].shape[-1]),
        "n_drive": int(arrays["drive"].shape[-1]),
        "package_version": __version__,
    }
    dataset = Dataset(path=out, metadata=metadata, arrays=arrays)
    validate(dataset)
    _write_directory(out, metadata, arrays, overwrite=overwrite)
    return dataset


def _same_dataset(
    out: Path, task: Task, engine: str, seed: int, n_objects: int, n_trajectories: int, n_frames: int
) -> Dataset | None:
    """The dataset already at ``out`` if it was generated with exactly these settings."""
    if not (out / METADATA_FILE).is_file():
        return None
    try:
        existing = load_dataset(out)
    except EnergyMarginError:
        return None
    meta = existing.metadata
    wanted = {
        "task": task.name,
        "task_config": json.loads(json.dumps(task.config.to_dict())),
        "engine": engine,
        "seed": int(seed),
        "n_objects": n_objects,
        "n_trajectories": n_trajectories,
        "n_frames": n_frames,
    }
    return existing if all(meta.get(key) == value for key, value in wanted.items()) else None


def _check_target(out: Path, *, overwrite: bool) -> None:
    """Refuse to replace a non-empty ``out`` unless ``overwrite``."""
    if overwrite or not out.exists():
        return
    if out.is_file() or any(out.iterdir()):
        raise EnergyMarginError(f"{out} already exists; pass --overwrite to replace it")


def _write_directory(out: Path, metadata: dict[str, Any], arrays: dict[str, np.ndarray], *, overwrite: bool) -> None:
    out.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(dir=out.parent, prefix=f".{out.name}."))
    try:
        np.savez_compressed(staging / FRAMES_FILE, allow_pickle=False, **arrays)
        write_json(staging / METADATA_FILE, metadata)
        _check_target(out, overwrite=overwrite)
        if out.is_dir():
            shutil.rmtree(out)
        elif out.exists():
            out.unlink()
        staging.rename(out)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise


def load_dataset(path: Path | str) -> Dataset:
    """Read and validate a dataset directory; every problem raises :class:`EnergyMarginError`."""
    path = Path(path)
    if not path.is_dir():
        raise EnergyMarginError(f"dataset {path} does not exist or is not a directory")
    metadata = read_json(path / METADATA_FILE, what=f"dataset {path}")
    if not isinstance(metadata, dict) or metadata.get("format") != FORMAT:
        raise EnergyMarginError(f"dataset {path}: {METADATA_FILE} is not an energy-margin dataset")
    if metadata.get("schema_version") != SCHEMA_VERSION:
        raise EnergyMarginError(
            f"dataset {path}: schema_version {metadata.get('schema_version')!r} is not supported "
            f"(this version reads {SCHEMA_VERSION})"
        )
    frames_path = path / FRAMES_FILE
    if not frames_path.is_file():
        raise EnergyMarginError(f"dataset {path}: {FRAMES_FILE} is missing")
    arrays = _read_frames(path, frames_path)
    dataset = Dataset(path=path, metadata=metadata, arrays=arrays)
    validate(dataset)
    return dataset


def _read_frames(path: Path, frames_path: Path) -> dict[str, np.ndarray]:
    """The arrays of ``frames.npz``; anything but a readable archive of arrays is an error."""
    try:
        loaded = np.load(frames_path, allow_pickle=False)
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, zlib.error) as error:
        raise EnergyMarginError(f"dataset {path}: {FRAMES_FILE} is corrupt ({error})") from None
    if not isinstance(loaded, np.lib.npyio.NpzFile):
        raise EnergyMarginError(f"dataset {path}: {FRAMES_FILE} is not an .npz archive")
    arrays: dict[str, np.ndarray] = {}
    with loaded as archive:
        for name in archive.files:
            try:
                value = archive[name]
            except (OSError, ValueError, EOFError, zipfile.BadZipFile, zlib.error, KeyError) as error:
                raise EnergyMarginError(f"dataset {path}: {FRAMES_FILE} member {name!r} is corrupt ({error})") from None
            if not isinstance(value, np.ndarray):
                raise EnergyMarginError(f"dataset {path}: {FRAMES_FILE} member {name!r} is not an array")
            arrays[name] = value
    return arrays


def validate(dataset: Dataset) -> None:
    """Check metadata, array shapes, finiteness and labels; raise :class:`EnergyMarginError`."""
    where = f"dataset {dataset.path}" if dataset.path is not None else "dataset"
    meta = dataset.metadata
    for key in ("task", "n_trajectories", "n_frames", "n_objects", "n_robot_dofs", "n_drive"):
        if key not in meta:
            raise EnergyMarginError(f"{where}: {METADATA_FILE} lacks {key!r}")
    for key in ("n_trajectories", "n_frames", "n_objects", "n_robot_dofs", "n_drive"):
        value = meta[key]
        if (
            isinstance(value, bool)
            or not isinstance(value, int)
            or value < (0 if key in ("n_robot_dofs", "n_drive") else 1)
        ):
            raise EnergyMarginError(f"{where}: {METADATA_FILE} field {key!r} is invalid ({value!r})")
    try:
        task = dataset.task
    except EnergyMarginError as error:
        raise EnergyMarginError(f"{where}: {error}") from None
    del task
    t, k, n = meta["n_trajectories"], meta["n_frames"], meta["n_objects"]
    r, p = meta["n_robot_dofs"], meta["n_drive"]
    shapes = {
        "object_pos": (t, k, n, 3),
        "object_quat": (t, k, n, 4),
        "object_vel": (t, k, n, 6),
        "robot_q": (t, k, r),
        "robot_v": (t, k, r),
        "frame_time": (t, k),
        "friction": (t,),
        "drive": (t, p),
        "captured": (t, k),
        "in_success": (t, k),
    }
    arrays = dataset.arrays
    for name, shape in shapes.items():
        if name not in arrays:
            raise EnergyMarginError(f"{where}: {FRAMES_FILE} lacks array {name!r}")
        array = arrays[name]
        if not isinstance(array, np.ndarray):
            raise EnergyMarginError(f"{where}: {name!r} is not an array")
        if array.shape != shape:
            raise EnergyMarginError(f"{where}: array {name!r} has shape {array.shape}, expected {shape}")
        if name in _BOOL_ARRAYS:
            if array.dtype != np.bool_:
                raise EnergyMarginError(f"{where}: labels {name!r} must be booleans (0/1), got {array.dtype}")
            continue
        if not np.issubdtype(array.dtype, np.floating):
            raise EnergyMarginError(f"{where}: array {name!r} must hold floats, got {array.dtype}")
        bad = ~np.isfinite(array)
        if np.any(bad):
            index = tuple(int(i) for i in np.argwhere(bad)[0])
            location = f"trajectory {index[0]}" + (
                f", frame {index[1]}" if len(index) > 1 and name not in ("drive",) else ""
            )
            raise EnergyMarginError(f"{where}: array {name!r} has a NaN or infinite value at {location}")
    if np.any(arrays["friction"] < 0):
        raise EnergyMarginError(f"{where}: array 'friction' has a negative coefficient")
    norms = np.linalg.norm(arrays["object_quat"], axis=-1)
    if np.any(np.abs(norms - 1.0) > 1e-3):
        index = tuple(int(i) for i in np.argwhere(np.abs(norms - 1.0) > 1e-3)[0])
        raise EnergyMarginError(
            f"{where}: array 'object_quat' is not a unit quaternion at trajectory {index[0]}, frame {index[1]}"
        )
