"""Generation: scripted roll-outs of a task recorded as a dataset, with their labels."""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin._version import __version__
from energy_margin.data.dataset import (
    FORMAT,
    METADATA_FILE,
    SCHEMA_VERSION,
    Dataset,
    load_dataset,
    validate,
)
from energy_margin.data.dataset_files import check_target, write_directory
from energy_margin.data.physical import LIKELY_FIX, DrawTally, RolloutWatch, count_reasons
from energy_margin.data.validation import deep_overlaps, describe_overlap, overlap_limits
from energy_margin.errors import EnergyMarginError, check_positive_int, check_seed
from energy_margin.runs.progress import Progress, progress_bar
from energy_margin.runs.versions import VERSIONS_KEY, engine_versions
from energy_margin.sim import Simulator, get_engine, recording_engines
from energy_margin.tasks import Task, Trajectory, command_robot, resolve_task
from energy_margin.tasks.protocols import TaskRegions
from energy_margin.world.state import FrameState

__all__ = [
    "MAX_DRAWS",
    "REDRAWN_KEY",
    "DeepOverlapError",
    "RefusedDrawError",
    "UnphysicalError",
    "check_engine",
    "draw_trajectory",
    "generate_dataset",
    "record_trajectory",
    "records_dataset",
    "redrawn_draw",
    "replay_trajectory",
    "roll_out",
    "trajectory_record",
    "trajectory_rng",
    "write_records",
]


def _check_inputs(n_objects: int, n_trajectories: int, n_frames: int, seed: int) -> None:
    check_positive_int("n_objects", n_objects)
    check_positive_int("n_trajectories", n_trajectories)
    check_positive_int("n_frames", n_frames)
    check_seed(seed)


def check_engine(task: Task, engine: str, *, records: bool = False) -> None:
    """Raise one line when ``engine`` cannot simulate ``task`` (``records``: record its roll-outs)."""
    if task.engines is not None and engine not in task.engines:
        able = [name for name in task.engines if not records or get_engine(name).records]
        raise EnergyMarginError(f"{task.label} runs on {', '.join(able)} only, not `engine={engine}`")


#: Draws of one trajectory before generation gives up. A draw whose frames the dataset check would
#: refuse is replaced by the next: in crowds (20 pushing cylinders driven into each other and the
#: walls) MuJoCo's soft contacts let a pile sink up to 30 mm into itself, deeper than the limit
#: with which ``analyze`` refuses a dataset (data/validation.py), in about one trajectory in 15; and
#: a roll-out that blew up, left the bounds or gained energy from nothing is drawn again (data/physical.py).
MAX_DRAWS = 8
#: Key of ``dataset.json`` that lists the redrawn trajectories: ``{"index": {"draw": d, "reasons":
#: [why draw 0 failed, ..., why draw d - 1 failed]}}`` (datasets of earlier versions: ``{"index": d}``).
REDRAWN_KEY = "redrawn"


class RefusedDrawError(ValueError):
    """A drawn trajectory the dataset would refuse: it is drawn again."""


class DeepOverlapError(RefusedDrawError):
    """A recorded frame whose objects overlap deeper than the dataset check allows."""


class UnphysicalError(RefusedDrawError):
    """A roll-out that blew up, left the bounds, moved too fast or gained energy from nothing."""


def trajectory_rng(seed: int, n_trajectories: int, index: int, draw: int = 0) -> np.random.Generator:
    """The random generator of trajectory ``index`` of a dataset generated with ``seed``.

    ``numpy.random.SeedSequence(seed).spawn(n_trajectories)[index]``: it draws the trajectory's
    start, friction and drive, then every step's scripted variation. A redrawn trajectory's
    draw ``d`` >= 1 uses that sequence's ``spawn(d)[d - 1]``.
    """
    sequence = np.random.SeedSequence(seed).spawn(n_trajectories)[index]
    if draw:
        sequence = sequence.spawn(draw)[draw - 1]
    return np.random.default_rng(sequence)


def roll_out(
    task: Task,
    trajectory: Trajectory,
    simulator: Simulator,
    rng: np.random.Generator,
    steps: np.ndarray,
    *,
    after_step: Callable[[], None] | None = None,
) -> Iterator[int]:
    """Run a scripted roll-out from ``trajectory.initial``, stopping at each of ``steps`` (sorted, >= 0).

    Yields each step number once the simulator has reached it (the simulator then holds that
    state). The command of every step is drawn from ``rng``, as during generation;
    ``after_step`` is called after every physics step.
    """
    simulator.reset(trajectory.initial)
    dt = simulator.timestep
    step = 0
    for target in steps:
        while step < target:
            command_robot(task, simulator, trajectory.drive, step * dt, rng)
            simulator.step(1)
            if after_step is not None:
                after_step()
            step += 1
        yield step


def record_trajectory(
    task: Task,
    n_objects: int,
    n_frames: int,
    rng: np.random.Generator,
    *,
    engine: str = "mujoco",
    check_overlaps: bool = False,
) -> dict[str, Any]:
    """Run one scripted roll-out and record ``n_frames`` evenly spaced frames with their labels.

    Raises:
        UnphysicalError: ``check_overlaps`` and the roll-out went wrong (data/physical.py): MuJoCo
            warned (a blow-up, which it restarts by itself), a frame has an object outside the
            task's state box or too fast, or the energy grew without work.
        DeepOverlapError: ``check_overlaps`` and a frame the dataset check would refuse (checked after
            the roll-out, each frame reset as ``analyze`` resets it, so the roll-out is unchanged).
    """
    trajectory = task.sample_trajectory(rng, n_objects)
    simulator = task.make_simulator(n_objects, trajectory.friction, trajectory.drive, engine)
    dt = simulator.timestep
    frames: list[FrameState] = []
    times: list[float] = []
    watch = None
    if check_overlaps:
        simulator.reset(trajectory.initial)
        watch = RolloutWatch(simulator, task.frame_box)
    steps = task.frame_steps(n_frames)
    for step in roll_out(
        task, trajectory, simulator, rng, steps, after_step=None if watch is None else watch.after_step
    ):
        frame = simulator.frame_state()
        frames.append(frame)
        times.append(step * dt)
        if watch is not None:
            watch.frame(frame)
    if watch is not None:
        found = watch.problems()
        if found:
            raise UnphysicalError(found[0])
        limits = overlap_limits(simulator.scene)
        for index, frame in enumerate(frames):
            simulator.reset(frame)
            overlapping = deep_overlaps(simulator, limits)
            if overlapping:
                raise DeepOverlapError(f"frame {index}: {describe_overlap(*overlapping[0])}")
    return trajectory_record(task, frames, times, trajectory.friction, trajectory.drive)


def draw_trajectory(
    task: Task,
    n_objects: int,
    n_frames: int,
    seed: int,
    n_trajectories: int,
    index: int,
    *,
    engine: str,
    tally: DrawTally | None = None,
) -> tuple[dict[str, Any], list[str]]:
    """Trajectory ``index``'s record from the first of :data:`MAX_DRAWS` draws the dataset check accepts.

    Returns:
        The record and why each earlier draw was refused (empty: the first draw was accepted).

    Raises:
        EnergyMarginError: every draw was refused, or most draws of the generation so far
            (``tally``), naming the cause and the likely fix.
    """
    tally = tally if tally is not None else DrawTally()
    reasons: list[str] = []
    for draw in range(MAX_DRAWS):
        rng = trajectory_rng(seed, n_trajectories, index, draw)
        try:
            record = record_trajectory(task, n_objects, n_frames, rng, engine=engine, check_overlaps=True)
        except RefusedDrawError as error:
            reasons.append(str(error))
            tally.add(str(error))
            stop = tally.stop_reason(task)
            if stop is not None:
                raise EnergyMarginError(stop) from None
            continue
        tally.add(None)
        return record, reasons
    kind = count_reasons(reasons)
    raise EnergyMarginError(
        f"cannot generate {task.name} trajectory {index}: each of {MAX_DRAWS} draws failed (the last: "
        f"{reasons[-1]}); {LIKELY_FIX[kind]}"
    )


def trajectory_record(
    task: TaskRegions, frames: list[FrameState], times: list[float], friction: float, drive: np.ndarray
) -> dict[str, Any]:
    """One trajectory's arrays as ``frames.npz`` lays them out (without the trajectory axis), with labels.

    Args:
        task: the task whose capture and success sets label the frames.
        frames: the recorded frame states, K of them.
        times: time of each frame within the roll-out, s.
        friction: the trajectory's Coulomb coefficient.
        drive: the trajectory's drive parameters, shape (n_drive,).

    """
    return {
        "object_pos": np.stack([f.object_pos for f in frames]),
        "object_quat": np.stack([f.object_quat for f in frames]),
        "object_vel": np.stack([f.object_vel for f in frames]),
        "robot_q": np.stack([f.robot_q for f in frames]),
        "robot_v": np.stack([f.robot_v for f in frames]),
        "frame_time": np.array(times, dtype=float),
        "friction": np.float64(friction),
        "drive": np.asarray(drive, dtype=float),
        "captured": np.array([task.is_captured(f) for f in frames]),
        "in_success": np.array([task.is_successful(f) for f in frames]),
    }


def write_records(
    task: Task,
    records: list[dict[str, Any]],
    out: Path,
    *,
    engine: str,
    extra: dict[str, Any],
    overwrite: bool,
) -> Dataset:
    """Stack trajectory records into a dataset, validate it and write it atomically to ``out``.

    Args:
        task: the task of every record.
        records: one :func:`trajectory_record` per trajectory, all with the same K.
        out: the dataset directory.
        engine: the engine that produced the frames.
        extra: further metadata (e.g. ``seed``, or the recordings a dataset was made from).
        overwrite: replace an existing ``out``.

    """
    dataset = records_dataset(task, records, out, engine=engine, extra=extra)
    write_directory(out, dataset.metadata, dataset.arrays, overwrite=overwrite)
    return dataset


def records_dataset(
    task: Task, records: list[dict[str, Any]], out: Path, *, engine: str, extra: dict[str, Any]
) -> Dataset:
    """Stack trajectory records into a validated dataset at ``out`` (not written).

    Args:
        task: the task of every record.
        records: one :func:`trajectory_record` per trajectory, all with the same K.
        out: the dataset directory.
        engine: the engine that produced the frames.
        extra: further metadata.

    """
    arrays = {key: np.stack([r[key] for r in records]) for key in records[0]}
    metadata = {
        "format": FORMAT,
        "schema_version": SCHEMA_VERSION,
        "task": task.name,
        "task_config": task.config.to_dict(),
        "engine": engine,
        # The compiled MuJoCo model of the design: the same configuration, the same hash.
        "model_sha256": task.model_sha256(int(arrays["object_pos"].shape[2])),
        **extra,
        "n_trajectories": len(records),
        "n_frames": int(arrays["frame_time"].shape[1]),
        "n_objects": int(arrays["object_pos"].shape[2]),
        "n_robot_dofs": int(arrays["robot_q"].shape[-1]),
        "n_drive": int(arrays["drive"].shape[-1]),
        "package_version": __version__,
        # Frames depend on the engine's version: the same seed moves centimetres between releases.
        VERSIONS_KEY: engine_versions(engine),
    }
    dataset = Dataset(path=out, metadata=metadata, arrays=arrays)
    validate(dataset)
    return dataset


def redrawn_draw(metadata: dict[str, Any], index: int) -> int:
    """The draw that trajectory ``index`` of a generated dataset comes from (0 unless it was redrawn)."""
    redrawn = metadata.get(REDRAWN_KEY) or {}
    entry = redrawn.get(str(index), 0) if isinstance(redrawn, dict) else 0
    draw = entry.get("draw", 0) if isinstance(entry, dict) else entry
    return draw if isinstance(draw, int) and not isinstance(draw, bool) and draw >= 0 else 0


def replay_trajectory(
    dataset: Dataset, index: int, steps: np.ndarray, *, simulator: Simulator | None = None
) -> Iterator[tuple[int, FrameState]]:
    """The states of trajectory ``index`` of a generated dataset at ``steps`` (sorted), by running it again.

    Generation is deterministic, so the roll-out is the recorded one: at the recorded frames'
    steps the states are the dataset's. ``simulator`` (of the trajectory's scene and the
    dataset's engine) is built when ``None``.

    Raises:
        EnergyMarginError: the dataset was not generated by ``generate`` (no seed) or its
            trajectory does not start as this version draws it (another seed or version).

    """
    meta = dataset.metadata
    seed = meta.get("seed")
    if isinstance(seed, bool) or not isinstance(seed, int):
        raise EnergyMarginError(f"{dataset.path}: no generation seed in dataset.json; cannot run the roll-out again")
    task = dataset.task
    rng = trajectory_rng(seed, dataset.n_trajectories, index, redrawn_draw(meta, index))
    trajectory = task.sample_trajectory(rng, dataset.n_objects)
    stored_drive = dataset.arrays["drive"][index]
    if trajectory.friction != float(dataset.arrays["friction"][index]) or not np.array_equal(
        trajectory.drive, stored_drive
    ):
        raise EnergyMarginError(
            f"{dataset.path}: trajectory {index} does not start as seed {seed} draws it "
            "(generated by another version or imported); cannot run the roll-out again"
        )
    if simulator is None:
        simulator = task.make_simulator(
            dataset.n_objects, trajectory.friction, trajectory.drive, str(meta.get("engine", "mujoco"))
        )
    for step in roll_out(task, trajectory, simulator, rng, np.asarray(steps, dtype=int)):
        yield step, simulator.frame_state()


def generate_dataset(
    task_name: str | Task,
    *,
    n_objects: int | None,
    n_trajectories: int,
    n_frames: int,
    seed: int,
    out: Path | str,
    engine: str = "mujoco",
    task_config: dict[str, Any] | None = None,
    overwrite: bool = False,
    progress: Progress = None,
) -> Dataset:
    """Generate scripted roll-outs and write them as a dataset directory.

    Trajectory ``i`` uses ``numpy.random.SeedSequence(seed).spawn(n_trajectories)[i]`` (a redrawn
    one that sequence's children, :func:`draw_trajectory`). The
    directory is written to a temporary sibling and renamed, so an error leaves nothing behind.

    Args:
        task_name: a registered task's name, or a resolved task (its configuration is kept,
            ``task_config`` applied over it).
        n_objects: objects per scene, >= 1 (``None`` for a task that fixes them, e.g. a scene file).
        n_trajectories: roll-outs T, >= 1.
        n_frames: frames K per roll-out, >= 1.
        seed: non-negative integer seed.
        out: the dataset directory to create.
        engine: physics engine.
        task_config: overrides of the task's configuration.
        overwrite: replace an existing ``out``.
        progress: after each trajectory: ``True`` a bar on standard error, a callable is called
            with 1 (:data:`~energy_margin.runs.progress.Progress`).

    """
    if not get_engine(engine).records:  # (an unknown engine: get_engine's one line)
        raise EnergyMarginError(f"engine {engine!r} records no roll-outs: use {' or '.join(recording_engines())}")
    task = resolve_task(task_name, task_config)
    check_engine(task, engine, records=True)
    if task.fixed_objects is not None:
        if n_objects is not None and n_objects != task.fixed_objects:
            raise EnergyMarginError(
                f"task {task.name!r} has {task.fixed_objects} objects; `n_objects={n_objects}` differs"
            )
        n_objects = task.fixed_objects
    if n_objects is None:
        raise EnergyMarginError(f"task {task.name!r} needs the number of objects (`n_objects`)")
    _check_inputs(n_objects, n_trajectories, n_frames, seed)
    out = Path(out)
    if not overwrite:
        existing = _same_dataset(out, task, engine, seed, n_objects, n_trajectories, n_frames)
        if existing is not None:
            return existing
    check_target(out, overwrite=overwrite)
    records = []
    redrawn: dict[str, dict[str, Any]] = {}
    tally = DrawTally()
    bar = progress_bar(n_trajectories, desc="generate", unit="traj", enabled=progress)
    for index in range(n_trajectories):
        try:
            record, reasons = draw_trajectory(
                task, n_objects, n_frames, seed, n_trajectories, index, engine=engine, tally=tally
            )
        except ValueError as error:
            raise EnergyMarginError(f"cannot generate {task.name} trajectories: {error}") from None
        records.append(record)
        if reasons:
            redrawn[str(index)] = {"draw": len(reasons), "reasons": reasons}
        bar.update(1)
    bar.close()
    extra: dict[str, Any] = {"seed": int(seed)}
    if redrawn:
        extra[REDRAWN_KEY] = redrawn
    return write_records(task, records, out, engine=engine, extra=extra, overwrite=overwrite)


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
