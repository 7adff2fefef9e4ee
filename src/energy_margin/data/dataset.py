"""The on-disk dataset: recorded frames, ground-truth labels and metadata (format version 1).

A dataset is a directory with two files:

``dataset.json``
    ``format`` ("energy-margin-dataset"), ``schema_version`` (1), ``task``, ``task_config`` (every
    resolved setting), ``engine``, ``model_sha256`` (the task's compiled MuJoCo model), ``seed``,
    ``n_trajectories`` (T), ``n_frames`` (K), ``n_objects`` (n), ``n_robot_dofs`` (r), ``n_drive``
    (P), ``package_version``, ``versions`` (the engine and the MuJoCo and numpy versions that
    wrote it, :func:`energy_margin.runs.versions.engine_versions`; absent in sets written before
    it was recorded, whose versions are unknown: :mod:`energy_margin.data.provenance`).
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

import functools
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.errors import EnergyMarginError, check_int
from energy_margin.runs.files import read_json
from energy_margin.runs.npz import READ_ERRORS
from energy_margin.tasks import Task, get_recorded_task
from energy_margin.world.state import FrameState

__all__ = [
    "FORMAT",
    "FRAMES_FILE",
    "METADATA_FILE",
    "SCHEMA_VERSION",
    "Dataset",
    "Problem",
    "array_problems",
    "expected_shapes",
    "frame_from_arrays",
    "load_dataset",
    "metadata_problems",
    "raise_first",
    "read_dataset",
    "validate",
]

FORMAT = "energy-margin-dataset"
SCHEMA_VERSION = 1
METADATA_FILE = "dataset.json"
FRAMES_FILE = "frames.npz"

_FLOAT_ARRAYS = ("object_pos", "object_quat", "object_vel", "robot_q", "robot_v", "frame_time", "friction", "drive")
_BOOL_ARRAYS = ("captured", "in_success")


def frame_from_arrays(arrays: dict[str, Any], *index: int) -> FrameState:
    """The frame state at ``index`` of arrays laid out as ``frames.npz`` (or one trajectory's record).

    Args:
        arrays: ``object_pos``, ``object_quat``, ``object_vel``, ``robot_q``, ``robot_v`` with leading
            axes (trajectory, frame) for a dataset or (frame,) for :func:`record_trajectory`'s record.
        index: the leading indices, e.g. ``(trajectory, frame)`` or ``(frame,)``.
    """
    return FrameState(
        object_pos=arrays["object_pos"][index],
        object_quat=arrays["object_quat"][index],
        object_vel=arrays["object_vel"][index],
        robot_q=arrays["robot_q"][index],
        robot_v=arrays["robot_v"][index],
    )


@dataclass(frozen=True)
class Dataset:
    """A loaded dataset (see the module docstring for every array's shape and unit)."""

    path: Path | None
    metadata: dict[str, Any]
    arrays: dict[str, np.ndarray]

    @functools.cached_property
    def task(self) -> Task:
        """The task, with the configuration the data were generated with (resolved once per dataset)."""
        return get_recorded_task(self.metadata["task"], self.metadata.get("task_config"))

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

    def identity(self) -> dict[str, Any]:
        """What a run's settings record of the dataset it read: task, generation seed and sizes."""
        return {
            "task": self.metadata["task"],
            "seed": self.metadata.get("seed"),
            "n_trajectories": self.n_trajectories,
            "n_frames": self.n_frames,
            "n_objects": self.n_objects,
        }

    def frame(self, trajectory: int, index: int) -> FrameState:
        """The recorded state of frame ``index`` of ``trajectory``."""
        return frame_from_arrays(self.arrays, trajectory, index)

    def capture_labels(self, window: int = 0) -> np.ndarray:
        """Capture label of every frame, shape (T, K), bool.

        A frame is captured when every object lies in the capture region at frames
        k .. k + ``window`` (k-hat), each tested against the region built from that frame.
        """
        check_int("window", window, minimum=0)
        captured = self.arrays["captured"]
        labels = captured.copy()
        for shift in range(1, window + 1):
            labels[:, :-shift] &= captured[:, shift:]
        return labels

    def success_labels(self) -> np.ndarray:
        """Success label of every trajectory (every object in the success region at the last frame), (T,)."""
        return self.arrays["in_success"][:, -1].copy()


@dataclass(frozen=True)
class Problem:
    """One problem found in a dataset or scores file.

    Attributes:
        file: the file, e.g. ``"frames.npz"``.
        field: the key, array or column, e.g. ``"object_pos"`` or ``"task_config.friction_range"``.
        row: where in it, e.g. ``"trajectory 1, frame 0"`` or ``"line 5"``; empty when global.
        message: what is wrong.
    """

    file: str
    field: str
    row: str
    message: str

    def __str__(self) -> str:
        where = f" [{self.row}]" if self.row else ""
        location = ": ".join(part for part in (self.file, f"{self.field}{where}".strip()) if part)
        text = f"{location}: {self.message}" if location else self.message
        # One problem, one line, whatever a hostile file puts in a key or value.
        return " ".join(text.split())


#: Largest accepted dataset dimensions: guards allocations against corrupt or hostile headers.
_LIMITS = {
    "n_trajectories": 1_000_000,
    "n_frames": 100_000,
    "n_objects": 10_000,
    "n_robot_dofs": 1_000,
    "n_drive": 100_000,
}
_MAX_MEMBER_BYTES = 1 << 31
_MAX_PER_FIELD = 5


def raise_first(path: Path | str | None, problems: list[Problem]) -> None:
    """Raise :class:`EnergyMarginError` with the first problem (and how many more there are)."""
    if not problems:
        return
    more = f" (and {len(problems) - 1} more; run `energy-margin check` to list them)" if len(problems) > 1 else ""
    prefix = f"dataset {path}: " if path is not None else ""
    raise EnergyMarginError(f"{prefix}{problems[0]}{more}")


def load_dataset(path: Path | str) -> Dataset:
    """Read and validate a dataset directory; every problem raises :class:`EnergyMarginError`."""
    dataset, problems = read_dataset(path)
    raise_first(path, problems)
    assert dataset is not None
    return dataset


def read_dataset(path: Path | str) -> tuple[Dataset | None, list[Problem]]:
    """Read a dataset directory and list every problem of its files (no exception for bad input).

    Returns:
        The dataset (``None`` when it cannot be read at all) and the problems found.
    """
    path = Path(path)
    if not path.is_dir():
        return None, [Problem("", "", "", "directory does not exist or is not a directory")]
    metadata_path = path / METADATA_FILE
    if not metadata_path.is_file():
        return None, [Problem(METADATA_FILE, "file", "", f"{METADATA_FILE} does not exist")]
    try:
        metadata = read_json(metadata_path, what=METADATA_FILE)
    except EnergyMarginError as error:
        return None, [Problem(METADATA_FILE, "file", "", f"is not valid JSON ({str(error).split('(', 1)[-1]}")]
    problems, task = _checked_metadata(metadata)
    if problems:
        return None, problems
    frames_path = path / FRAMES_FILE
    if not frames_path.is_file():
        return None, [Problem(FRAMES_FILE, "file", "", f"{FRAMES_FILE} is missing")]
    shapes = expected_shapes(metadata)
    arrays, problems = _read_frames(frames_path, shapes)
    if problems:
        return None, problems
    dataset = Dataset(path=path, metadata=metadata, arrays=arrays)
    # The task built to check the metadata is the dataset's (its cached ``task``): one lookup per load.
    vars(dataset)["task"] = task
    return dataset, array_problems(dataset)


def metadata_problems(metadata: Any) -> list[Problem]:
    """Problems of the parsed ``dataset.json``: format, version, sizes and task configuration."""
    return _checked_metadata(metadata)[0]


def _checked_metadata(metadata: Any) -> tuple[list[Problem], Task | None]:
    """The problems of the parsed ``dataset.json`` and the task it records (``None`` if it has none)."""
    if not isinstance(metadata, dict) or metadata.get("format") != FORMAT:
        return [Problem(METADATA_FILE, "format", "", "is not an energy-margin dataset")], None
    if metadata.get("schema_version") != SCHEMA_VERSION:
        return [Problem(METADATA_FILE, "schema_version", "", _unsupported_schema(metadata))], None
    problems = []
    task: Task | None = None
    for key in ("task", *_LIMITS):
        if key not in metadata:
            problems.append(Problem(METADATA_FILE, key, "", "is missing"))
    for key, limit in _LIMITS.items():
        value = metadata.get(key)
        minimum = 0 if key in ("n_robot_dofs", "n_drive") else 1
        if key in metadata and (isinstance(value, bool) or not isinstance(value, int) or not minimum <= value <= limit):
            problems.append(
                Problem(METADATA_FILE, key, "", f"must be an integer in [{minimum}, {limit}], got {value!r}")
            )
    if "task" in metadata:
        config = metadata.get("task_config")
        if config is not None and not isinstance(config, dict):
            problems.append(Problem(METADATA_FILE, "task_config", "", "must be an object"))
        else:
            try:
                task = get_recorded_task(str(metadata["task"]), config)
            except EnergyMarginError as error:
                problems.append(Problem(METADATA_FILE, "task_config", "", str(error)))
            else:
                if not any(problem.field in ("n_robot_dofs", "n_drive") for problem in problems):
                    problems.extend(_task_size_problems(task, metadata))
    return problems, task


def _unsupported_schema(metadata: dict[str, Any]) -> str:
    """Why a ``schema_version`` other than :data:`SCHEMA_VERSION` is refused, in words."""
    version = metadata.get("schema_version")
    reads = f"this version of energy-margin reads {SCHEMA_VERSION}"
    if isinstance(version, int) and not isinstance(version, bool) and version > SCHEMA_VERSION:
        writer = metadata.get("package_version")
        by = f"energy-margin {writer}" if isinstance(writer, str) else "a later energy-margin"
        return f"{version} is not supported ({reads}; {by} wrote it: upgrade energy-margin to read it)"
    return f"{version!r} is not supported ({reads})"


def _task_size_problems(task: Task, metadata: dict[str, Any]) -> list[Problem]:
    """The end-effector and drive sizes of the metadata must be the task's."""
    try:
        dofs = task.robot_dofs()
        drive = task.drive_size()
    except (ValueError, OverflowError, FloatingPointError, ZeroDivisionError) as error:
        return [Problem(METADATA_FILE, "task_config", "", f"cannot build the task's scene ({error})")]
    problems = []
    for key, expected in (("n_robot_dofs", dofs), ("n_drive", drive)):
        if metadata.get(key) != expected:
            problems.append(
                Problem(METADATA_FILE, key, "", f"is {metadata.get(key)!r} but task {task.name!r} has {expected}")
            )
    return problems


def expected_shapes(metadata: dict[str, Any]) -> dict[str, tuple[int, ...]]:
    """Shape of every array of ``frames.npz`` given validated metadata."""
    t, k, n = metadata["n_trajectories"], metadata["n_frames"], metadata["n_objects"]
    r, p = metadata["n_robot_dofs"], metadata["n_drive"]
    return {
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


def _read_frames(frames_path: Path, shapes: dict[str, tuple[int, ...]]) -> tuple[dict[str, np.ndarray], list[Problem]]:
    """Read the expected arrays of ``frames.npz``, checking every header before allocating."""
    arrays: dict[str, np.ndarray] = {}
    problems: list[Problem] = []
    try:
        archive = zipfile.ZipFile(frames_path)
    except (OSError, zipfile.BadZipFile, ValueError, NotImplementedError, EOFError) as error:
        return arrays, [Problem(FRAMES_FILE, "archive", "", f"is corrupt or not an .npz archive ({error})")]
    with archive:
        members: dict[str, zipfile.ZipInfo] = {}
        for info in archive.infolist():
            name = info.filename.removesuffix(".npy")
            if name in shapes:
                members[name] = info
        for name, shape in shapes.items():
            if name not in members:
                problems.append(Problem(FRAMES_FILE, name, "", "array is missing"))
                continue
            info = members[name]
            if info.file_size > _MAX_MEMBER_BYTES:
                problems.append(Problem(FRAMES_FILE, name, "", f"is too large ({info.file_size} bytes)"))
                continue
            try:
                with archive.open(info) as stream:
                    version = np.lib.format.read_magic(stream)
                    header = (
                        np.lib.format.read_array_header_1_0(stream)
                        if version == (1, 0)
                        else np.lib.format.read_array_header_2_0(stream)
                    )
                    declared_shape, _, dtype = header
                    header_length = stream.tell()
                    if dtype.hasobject:
                        problems.append(Problem(FRAMES_FILE, name, "", "holds Python objects, not numbers"))
                        continue
                    if tuple(declared_shape) != shape:
                        problems.append(
                            Problem(FRAMES_FILE, name, "", f"has shape {tuple(declared_shape)}, expected {shape}")
                        )
                        continue
                    # The data must actually be there before anything is allocated for it.
                    declared_bytes = int(np.prod(shape, dtype=np.float64)) * dtype.itemsize
                    if declared_bytes > info.file_size - header_length:
                        problems.append(
                            Problem(FRAMES_FILE, name, "", "is truncated (less data than its header declares)")
                        )
                        continue
                with archive.open(info) as stream:
                    value = np.lib.format.read_array(stream, allow_pickle=False)
            except READ_ERRORS as error:
                problems.append(Problem(FRAMES_FILE, name, "", f"is corrupt ({error})"))
                continue
            arrays[name] = value
    return arrays, problems


def _location(name: str, index: tuple[int, ...]) -> str:
    if name in ("friction", "drive"):
        labels: tuple[str, ...] = ("trajectory",)
    elif name in ("robot_q", "robot_v"):
        labels = ("trajectory", "frame", "joint")
    else:
        labels = ("trajectory", "frame", "object")
    return ", ".join(f"{label} {i}" for label, i in zip(labels, index, strict=False))


def array_problems(dataset: Dataset) -> list[Problem]:
    """Problems of the arrays of a dataset whose shapes match its metadata."""
    problems: list[Problem] = []
    arrays = dataset.arrays
    for name in expected_shapes(dataset.metadata):
        array = arrays[name]
        if name in _BOOL_ARRAYS:
            if array.dtype != np.bool_:
                problems.append(Problem(FRAMES_FILE, name, "", f"labels must be booleans (0/1), got {array.dtype}"))
            continue
        if not np.issubdtype(array.dtype, np.floating):
            problems.append(Problem(FRAMES_FILE, name, "", f"must hold floats, got {array.dtype}"))
            continue
        for index in np.argwhere(~np.isfinite(array))[:_MAX_PER_FIELD]:
            problems.append(
                Problem(FRAMES_FILE, name, _location(name, tuple(int(i) for i in index)), "NaN or infinite value")
            )
    # NaN compares false, so these checks add nothing spurious next to the NaN problems above.
    if np.issubdtype(arrays["friction"].dtype, np.floating):
        for index in np.argwhere(arrays["friction"] < 0)[:_MAX_PER_FIELD]:
            location = _location("friction", (int(index[0]),))
            problems.append(Problem(FRAMES_FILE, "friction", location, "negative coefficient"))
    if not np.issubdtype(arrays["object_quat"].dtype, np.floating):
        return problems
    norms = np.linalg.norm(arrays["object_quat"], axis=-1)
    for index in np.argwhere(np.abs(norms - 1.0) > 1e-3)[:_MAX_PER_FIELD]:
        location = _location("object_quat", tuple(int(i) for i in index))
        problems.append(Problem(FRAMES_FILE, "object_quat", location, "not a unit quaternion"))
    return problems


def validate(dataset: Dataset) -> None:
    """Check an in-memory dataset's metadata and arrays; raise :class:`EnergyMarginError`."""
    problems = metadata_problems(dataset.metadata)
    if not problems:
        shapes = expected_shapes(dataset.metadata)
        for name, shape in shapes.items():
            array = dataset.arrays.get(name)
            if not isinstance(array, np.ndarray):
                problems.append(Problem(FRAMES_FILE, name, "", "array is missing"))
            elif array.shape != shape:
                problems.append(Problem(FRAMES_FILE, name, "", f"has shape {array.shape}, expected {shape}"))
        if not problems:
            problems = array_problems(dataset)
    raise_first(dataset.path, problems)
