"""Import the authors' published frames, labels and scores (their CSV layout) as a dataset.

A reference folder (e.g. ``energy_margin_workshop/planepush-10objects``) holds, per task
(``PlanePushMulti`` = pushing, ``GripperMulti`` = scooping):

* ``scripted_movement_viapoints_<Task>.csv``: ``num_traj, data_id`` then the frame state;
* ``scripted_movement_capture_labels_<Task>.csv``: ``num_traj, data_id, capture_exists_label,
  capture_all_label, lateral_friction_coef``;
* ``scripted_movement_success_labels_<Task>.csv``: ``num_traj, success_all_label, success_exists_label``;
* ``ao_est.csv`` in the folder or in a sub-folder (``original``/``original-data`` = true states,
  ``1``..``5`` = perturbed states): ``data_id, trial, plan_iters, plan_time, best_cost,
  capture_exists_score, capture_score, success_exists_score, success_score, runtime``.

The mapping to this project's dataset (documented in docs/results/reference.md):

* pushing, per object ``x, y, theta, vx, vy, omega`` -> centre ``(x, y, rest height)``, yaw
  ``theta``, velocity ``(vx, vy, 0, 0, 0, omega)``; pusher ``xg, yg, thetag, vxg, vyg, omegag`` ->
  ``robot_q = (x, y, 0, yaw)``, ``robot_v = (vx, vy, 0, omega)``. Lengths are metres already.
* scooping (their simulation is 10x larger): per object 12 columns whose header reads
  ``x, z, y`` but whose values are ``x, y, z`` (the third is the height: 0.35 = resting on the
  table top at 0.3), Euler angles (PyBullet: R = Rz Ry Rx), linear and angular velocity. Lengths
  and linear velocities are divided by 10 and the table top moved to this task's ``table_top``.
  Gripper ``j0..j3, zt`` and velocities -> ``robot_q = (base z, right finger, right tip, left
  finger, left tip)``: base z is this gripper's blade-on-table height plus the authors' lift above
  their own pressed-on-table height (``zt`` = 1.776, the lowest in their data), fingers at this
  gripper's closed travel plus their (always 0) prismatic travel, tip angles unchanged. The
  blades and finger plates are widened to ``SCOOP_BLADE_HALF_WIDTH`` (their blades carry boxes
  further off the centre line than this task's default blades reach). During analysis the
  gripper's servos replay its recorded motion (``recorded_waypoints`` = the frames), since their
  timing is not this task's script.
* labels: ``captured`` <- ``capture_all_label`` (their k-hat = 0 label of the frame);
  ``in_success`` at the last frame <- ``success_all_label`` (their trajectory label, "ever reached"),
  earlier frames <- their success test applied to the frame.
* friction: their per-body ``lateral_friction_coef`` mu_b; Bullet multiplies two bodies'
  coefficients, so the stored (effective) coefficient is mu_b^2 (0.4 -> 0.16 for pushing).
* their scores -> ``scores.csv`` (``nodes`` 301, ``expansions`` = ``plan_iters``, ``runtime_s`` =
  ``runtime``, ``physics_s`` 0.0 (not recorded), ``seed`` 0 (their runs were unseeded)).

This module finds the task and writes the dataset; :mod:`~energy_margin.data.reference_files` reads
the CSV files and :mod:`~energy_margin.data.reference_convert` holds the mapping of the columns.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from energy_margin._version import __version__
from energy_margin.data.dataset import FORMAT, SCHEMA_VERSION, Dataset, validate
from energy_margin.data.dataset_files import check_target as _check_target
from energy_margin.data.dataset_files import write_directory as _write_directory
from energy_margin.data.reference_convert import (
    _CONVERTERS,
    PUSH_FRAME_PERIOD,
    PUSH_SUCCESS_HALF_WIDTH,
    PUSH_WALL_Y,
    SCOOP_BLADE_HALF_WIDTH,
    SCOOP_CAPTURE_VZ,
    SCOOP_CAPTURE_Z,
    SCOOP_FIRST_FRAME,
    SCOOP_FRAME_PERIOD,
    SCOOP_PRESSED_ZT,
    SCOOP_SCALE,
    SCOOP_SUCCESS_Z,
    SCOOP_TABLE_TOP,
)
from energy_margin.data.reference_files import (
    AO_EST_COLUMNS,
    DEFAULT_SCORES,
    SCORES_NAME,
    ReferenceSet,
    _fail,
    _grid,
    _read_csv,
    _scores_path,
)
from energy_margin.data.scores_file import COLUMNS, CONFIG_FILE, SCORES_FILE, UNKNOWN_COUNT
from energy_margin.errors import EnergyMarginError, InvalidParameterError, check_choice
from energy_margin.runs.files import atomic_write_text, write_json
from energy_margin.runs.versions import VERSIONS_KEY, engine_versions
from energy_margin.tasks import ReferenceLayout, available_tasks, get_task, task_class

__all__ = [
    "AO_EST_COLUMNS",
    "DEFAULT_SCORES",
    "DRIVES",
    "PUSH_FRAME_PERIOD",
    "PUSH_SUCCESS_HALF_WIDTH",
    "PUSH_WALL_Y",
    "SCOOP_BLADE_HALF_WIDTH",
    "SCOOP_CAPTURE_VZ",
    "SCOOP_CAPTURE_Z",
    "SCOOP_FIRST_FRAME",
    "SCOOP_FRAME_PERIOD",
    "SCOOP_PRESSED_ZT",
    "SCOOP_SCALE",
    "SCOOP_SUCCESS_Z",
    "SCOOP_TABLE_TOP",
    "SCORES_NAME",
    "ReferenceSet",
    "detect_task",
    "import_reference",
    "read_reference",
    "reference_tasks",
]

#: How the end-effector is driven when imported frames are analysed.
DRIVES = ("nominal", "coast")


def reference_tasks() -> dict[str, str]:
    """Their task names (file suffixes) -> the registered task that declares that layout.

    A task that inherits its layout (a variant of a task) imports their files when asked for by
    name (``import_reference(..., task=NAME)``); the one that declares it is the default.
    """
    found: dict[str, str] = {}
    for name in available_tasks():
        layout = vars(task_class(name)).get("reference_layout")
        if isinstance(layout, ReferenceLayout) and layout.suffix in _CONVERTERS:
            found.setdefault(layout.suffix, name)
    return found


def _layout(task: str) -> ReferenceLayout:
    """The reference layout of the registered task ``task``."""
    layout = task_class(task).reference_layout
    if layout is None or layout.suffix not in _CONVERTERS:
        raise EnergyMarginError(f"task {task!r} has no import of the authors' files")
    return layout


def detect_task(folder: Path, task: str | None = None) -> tuple[str, str]:
    """(their suffix, this project's task) of a reference folder, from its file names.

    Args:
        folder: the reference folder.
        task: the task to import their files as (it must read their layout); ``None``: the task
            that declares the layout of the files found.

    """
    if not folder.is_dir():
        raise EnergyMarginError(f"{folder} does not exist or is not a directory")
    tasks = reference_tasks()
    suffixes = [_layout(task).suffix] if task is not None else list(tasks)
    found = [suffix for suffix in suffixes if (folder / f"scripted_movement_viapoints_{suffix}.csv").is_file()]
    if len(found) != 1:
        raise EnergyMarginError(
            f"{folder} is not a reference folder: expected one scripted_movement_viapoints_<Task>.csv "
            f"with Task in {', '.join(suffixes)}"
        )
    return found[0], task if task is not None else tasks[found[0]]


def read_reference(
    folder: Path | str, *, scores: str | None = None, with_scores: bool = True, task: str | None = None
) -> ReferenceSet:
    """Parse a reference folder as ``task`` (default: the task its files name).

    Every problem raises :class:`EnergyMarginError`.
    """
    folder = Path(folder)
    suffix, task = detect_task(folder, task)
    via_path = folder / f"scripted_movement_viapoints_{suffix}.csv"
    header, via = _read_csv(via_path)
    if header[:2] != ["num_traj", "data_id"]:
        raise _fail(via_path, "the first two columns must be num_traj, data_id")
    width = len(header) - 2
    layout = _layout(task)
    per_object, robot = layout.object_columns, layout.robot_columns
    if width <= robot or (width - robot) % per_object:
        raise _fail(via_path, f"{width} state columns do not fit n objects x {per_object} + {robot} robot columns")
    n_traj, n_frames = _grid(via_path, via, via[:, 0], via[:, 1])
    cap_path = folder / f"scripted_movement_capture_labels_{suffix}.csv"
    _, cap = _read_csv(
        cap_path, ("num_traj", "data_id", "capture_exists_label", "capture_all_label", "lateral_friction_coef")
    )
    if cap.shape[0] != via.shape[0] or not np.array_equal(cap[:, :2], via[:, :2]):
        raise _fail(cap_path, f"rows do not match {via_path.name} (num_traj, data_id)")
    suc_path = folder / f"scripted_movement_success_labels_{suffix}.csv"
    _, suc = _read_csv(suc_path, ("num_traj", "success_all_label", "success_exists_label"))
    if not np.array_equal(suc[:, 0], np.arange(n_traj)):
        raise _fail(suc_path, f"expected one row per trajectory 0..{n_traj - 1}")
    for path, column in ((cap_path, cap[:, 3]), (suc_path, suc[:, 1])):
        if not np.all(np.isin(column, (0.0, 1.0))):
            raise _fail(path, "labels must be 0 or 1")
    friction = cap[:, 4].reshape(n_traj, n_frames)
    if np.any(friction < 0) or np.any(friction != friction[:, :1]):
        raise _fail(cap_path, "lateral_friction_coef must be >= 0 and constant within a trajectory")
    score_rows = None
    score_path = _scores_path(folder, scores) if with_scores else None
    if score_path is not None:
        _, score_rows = _read_csv(score_path, AO_EST_COLUMNS)
        if score_rows.shape[0] != via.shape[0] or not np.array_equal(score_rows[:, 0], np.arange(via.shape[0])):
            raise _fail(score_path, f"expected one row per frame, data_id 0..{via.shape[0] - 1} in order")
        for name in ("capture_score", "success_score"):
            column = score_rows[:, AO_EST_COLUMNS.index(name)]
            if np.any((column < 0) | (column > 1 + 1e-9)):
                raise _fail(score_path, f"{name} outside [0, 1]")
    return ReferenceSet(
        task=task,
        suffix=suffix,
        states=via[:, 2:].reshape(n_traj, n_frames, width),
        capture_label=cap[:, 3].reshape(n_traj, n_frames).astype(bool),
        friction_per_body=friction[:, 0].copy(),
        success_label=suc[:, 1].astype(bool),
        scores=score_rows,
    )


def import_reference(
    folder: Path | str,
    out: Path | str,
    *,
    scores: str | None = None,
    with_scores: bool = True,
    overwrite: bool = False,
    drive: str = "nominal",
    task: str | None = None,
) -> Dataset:
    """Convert a reference folder into a dataset directory (plus ``scores.csv`` from their scores).

    Args:
        folder: a task folder such as ``energy_margin_workshop/planepush-10objects``.
        out: the dataset directory to create.
        scores: sub-folder of the ``ao_est.csv`` to import (``"."`` for the folder itself);
            default: ``original``, ``original-data`` or the folder itself, whichever exists.
        with_scores: import their scores as ``scores.csv`` (when a file is found).
        overwrite: replace an existing ``out``.
        drive: ``"nominal"``: this project's nominal drive for the trajectory's friction (the
            end-effector keeps following the manipulation during analysis); ``"coast"`` (pushing
            only): no drive force, the pusher coasts from its recorded velocity, as in the
            authors' planner. Scooping always replays the gripper's recorded motion
            (``imported_drive`` = ``"recorded"``).
        task: the task to import their files as (one that reads their layout, such as a variant
            of the task they name); ``None``: the task their file names map to.

    Returns:
        The written dataset.
    """
    folder, out = Path(folder), Path(out)
    check_choice("drive", drive, DRIVES)
    ref = read_reference(folder, scores=scores, with_scores=with_scores, task=task)
    layout = _layout(ref.task)
    if drive not in layout.drives:
        following = " (its end-effector replays its recorded motion)" if layout.replays_recorded else ""
        raise InvalidParameterError(
            "drive", f"{drive} does not apply to {ref.task}{following}; its drives: {', '.join(layout.drives)}"
        )
    n_objects = (ref.states.shape[-1] - layout.robot_columns) // layout.object_columns
    arrays, overrides = _CONVERTERS[layout.suffix](ref, n_objects)
    if drive == "coast":
        arrays["drive"] = np.zeros_like(arrays["drive"])
    arrays["in_success"][:, -1] = ref.success_label
    arrays["captured"] = ref.capture_label.copy()
    arrays["in_success"] = arrays["in_success"].astype(bool)
    imported = get_task(ref.task, overrides)
    n_traj, n_frames = ref.states.shape[:2]
    metadata = {
        "format": FORMAT,
        "schema_version": SCHEMA_VERSION,
        "task": ref.task,
        "task_config": imported.config.to_dict(),
        "engine": "pybullet",
        "seed": 0,
        "n_trajectories": n_traj,
        "n_frames": n_frames,
        "n_objects": n_objects,
        "n_robot_dofs": int(arrays["robot_q"].shape[-1]),
        "n_drive": int(arrays["drive"].shape[-1]),
        "package_version": __version__,
        # The software that imported the set (the frames are the authors' own).
        VERSIONS_KEY: engine_versions("pybullet"),
        "imported_from": str(folder),
        "imported_drive": "recorded" if layout.replays_recorded else drive,
    }
    arrays = {key: np.ascontiguousarray(value) for key, value in arrays.items()}
    dataset = Dataset(path=out, metadata=metadata, arrays=arrays)
    validate(dataset)
    _check_target(out, overwrite=overwrite)
    _write_directory(out, metadata, arrays, overwrite=overwrite)
    if ref.scores is not None:
        _write_scores(out, ref, n_frames)
    return Dataset(path=out, metadata=metadata, arrays=arrays)


def _write_scores(out: Path, ref: ReferenceSet, n_frames: int) -> None:
    assert ref.scores is not None
    index = {name: i for i, name in enumerate(AO_EST_COLUMNS)}
    lines = [",".join(COLUMNS)]
    for row_number, row in enumerate(ref.scores):
        trajectory, frame = divmod(row_number, n_frames)
        values = {
            "trajectory": trajectory,
            "frame": frame,
            "capture_score": min(1.0, float(row[index["capture_score"]])),
            "success_score": min(1.0, float(row[index["success_score"]])),
            "nodes": int(row[index["plan_iters"]]) + 1,
            "expansions": int(row[index["plan_iters"]]),
            "runtime_s": float(row[index["runtime"]]),
            "physics_s": 0.0,
            "seed": 0,
            "rejected": UNKNOWN_COUNT,
            "diverged": UNKNOWN_COUNT,
            "tree_capture_score": min(1.0, float(row[index["capture_score"]])),  # theirs is ungated
        }
        lines.append(",".join(repr(v) if isinstance(v, float) else str(v) for v in (values[c] for c in COLUMNS)))
    atomic_write_text(out / SCORES_FILE, "\n".join(lines) + "\n")
    # Marks the scores as not this analyzer's: `analyze` refuses to mix them without --overwrite.
    write_json(out / CONFIG_FILE, {"analyzer": "reference scores (ao_est.csv)", "source": str(ref.task)})
