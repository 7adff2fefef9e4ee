"""Closed-loop episodes: a policy drives the task's robot on a disturbed plant; results as a dataset.

An episode samples the task's randomised start, draws the plant's disturbance (friction, pushes,
observation noise; :mod:`energy_margin.control.disturbances`) and runs the task's duration with
one of the policies: ``scripted`` (the task's own script, as ``generate`` runs it) or MPPI with
the ``task``, ``heuristic``, ``margin`` or ``learned`` cost. It records ``frames`` evenly spaced
frames with their capture and success labels, so the episodes of a run form a dataset that
``analyze``, ``evaluate`` and the report read. Each episode is saved as it ends and a rerun
resumes; episode i's generators come from ``SeedSequence(seed).spawn(episodes)[i]``, so the
results do not depend on the number of workers. An episode's settings and draws are in
:mod:`energy_margin.control.episode_draws`, its scores and a run's summary in
:mod:`energy_margin.control.episode_scores`.
"""

from __future__ import annotations

import json
import signal
from collections.abc import Callable, Iterator
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin._version import __version__
from energy_margin.analysis.executors import pool_results
from energy_margin.compat import save_npz
from energy_margin.control.commands import CommandSpace, RobotInputs, command_space, controllable_tasks
from energy_margin.control.costs import CostContext, CostWeights, MarginPredictor, get_cost
from energy_margin.control.disturbances import Disturbance, Push, get_disturbance, push_wrenches
from energy_margin.control.episode_dataset import write_episodes_dataset
from energy_margin.control.episode_draws import (
    EPISODE_STREAMS,
    ControlSettings,
    draw_episode,
    episode_seeds,
    observed_frame,
)
from energy_margin.control.episode_scores import ControlResult, _frame_scores, summarize
from energy_margin.control.mppi import Controller, ControllerConfig
from energy_margin.data.dataset import FRAMES_FILE, METADATA_FILE, Dataset, load_dataset
from energy_margin.data.generate import trajectory_record
from energy_margin.errors import EnergyMarginError, InvalidParameterError, check_int, check_seed
from energy_margin.runs import Progress, RunSpec, progress_bar, run_directory
from energy_margin.runs.files import atomic_path
from energy_margin.sim import Simulator
from energy_margin.sim.base import ModelCommand
from energy_margin.tasks import ScriptedMotion, Task, Trajectory, command_robot, get_task
from energy_margin.world.state import FrameState

__all__ = [
    "CONTROL_FILE",
    "CONTROL_RUN",
    "EPISODES_DIR",
    "EPISODE_STREAMS",
    "POLICIES",
    "ControlResult",
    "ControlSettings",
    "apply_inputs",
    "draw_episode",
    "episode_seeds",
    "observed_frame",
    "run_control",
    "run_episode",
    "summarize",
]

#: The policies ``energy-margin control --policy`` offers.
POLICIES = ("scripted", "task", "heuristic", "margin", "learned")
#: The run's settings and, once finished, its summary.
CONTROL_FILE = "control.json"
EPISODES_DIR = "episodes"


def apply_inputs(plant: Simulator, inputs: RobotInputs, offset: int) -> None:
    """Set the robot inputs of step ``offset`` of the first sequence of ``inputs`` on ``plant``."""
    plant.set_robot_force(inputs.forces[0, offset])
    if inputs.targets is not None:
        plant.set_robot_targets(inputs.targets[0, offset])
    if inputs.ctrl is not None:
        ModelCommand(ctrl=inputs.ctrl[0, offset]).apply_to(plant, purpose="a controller's actuator controls")


def run_episode(
    task: Task,
    settings: ControlSettings,
    seed: np.random.SeedSequence,
    *,
    model: MarginPredictor | None = None,
) -> dict[str, Any]:
    """One episode: its trajectory record (:func:`~energy_margin.data.generate.trajectory_record`) and ``info``.

    ``info`` holds whether it succeeded, its decisions and their compute time (s), the plant's
    friction, its pushes and, with ``score_expansions``, the frames' capture and success scores.
    """
    seeds = episode_seeds(seed)
    disturbance = Disturbance(**settings.disturbance)
    trajectory, friction, pushes = draw_episode(task, settings.n_objects, disturbance, seeds)
    plant = task.make_simulator(settings.n_objects, friction, trajectory.drive, "mujoco")
    plant.reset(trajectory.initial)
    space = command_space(task, settings.n_objects)
    held = space.initial_targets(trajectory)
    if held is not None:
        plant.set_robot_targets(held)
    controller = None
    if settings.policy != "scripted":
        controller = _controller(task, settings, space, trajectory, seeds, model)
    frames, times, executed = _closed_loop(
        task, settings, plant, space, trajectory, pushes, disturbance, controller, held, seeds
    )
    drive = space.recorded_drive(trajectory, np.array(executed).reshape(-1, space.dimension))
    record = trajectory_record(task, frames, times, friction, drive)
    info = _episode_info(record, controller, trajectory, friction, pushes)
    if settings.score_expansions > 0:
        capture, success = _frame_scores(task, frames, times, friction, drive, settings, seeds["score"])
        info["capture_scores"] = capture
        info["success_scores"] = success
    return {"record": record, "info": info}


def _controller(
    task: Task,
    settings: ControlSettings,
    space: CommandSpace,
    trajectory: Trajectory,
    seeds: dict[str, np.random.SeedSequence],
    model: MarginPredictor | None,
) -> Controller:
    """The episode's MPPI controller with the policy's cost (every policy but ``scripted``)."""
    config = ControllerConfig(**settings.controller)
    context = CostContext(
        task,
        length_scale=space.length_scale,
        weights=CostWeights(**settings.weights),
        friction=trajectory.friction,
        drive=trajectory.drive,
        analysis_drive=lambda force: space.analysis_drive(trajectory, force),
        margin_expansions=config.margin_expansions,
        margin_samples=config.margin_samples,
        seed_sequence=seeds["cost"],
        model=model,
    )
    return Controller(
        task,
        space,
        trajectory,
        get_cost(settings.policy),
        context,
        config,
        np.random.default_rng(seeds["sample"]),
    )


def _closed_loop(
    task: ScriptedMotion,
    settings: ControlSettings,
    plant: Simulator,
    space: CommandSpace,
    trajectory: Trajectory,
    pushes: list[Push],
    disturbance: Disturbance,
    controller: Controller | None,
    held: np.ndarray | None,
    seeds: dict[str, np.random.SeedSequence],
) -> tuple[list[FrameState], list[float], list[np.ndarray]]:
    """Step the plant through the task's duration under pushes and the policy's commands.

    Returns:
        The recorded frames, their times (s) and the controller's executed commands, each of
        shape (space.dimension,) (none for ``scripted``).

    """
    observe_rng, script_rng = np.random.default_rng(seeds["observe"]), np.random.default_rng(seeds["script"])
    dt = plant.timestep
    record_steps = set(task.frame_steps(settings.n_frames).tolist())
    frames: list[FrameState] = []
    times: list[float] = []
    executed: list[np.ndarray] = []
    period_steps = controller.period_steps if controller is not None else 1
    inputs = None
    for step in range(task.n_steps + 1):
        now = step * dt
        if step in record_steps:
            frames.append(plant.frame_state())
            times.append(now)
        if step == task.n_steps:
            break
        plant.set_object_wrenches(push_wrenches(pushes, now, settings.n_objects))
        if controller is None:
            command_robot(task, plant, trajectory.drive, now, script_rng)
        else:
            offset = step % period_steps
            if offset == 0:
                command = controller.decide(observed_frame(plant.frame_state(), disturbance, observe_rng), now, held)
                executed.append(command)
                inputs = space.inputs(command[None, None], held=held, start_time=now, dt=dt, period_steps=period_steps)
                held = None if inputs.held is None else inputs.held[0]
            assert inputs is not None
            apply_inputs(plant, inputs, offset)
        plant.step(1)
    return frames, times, executed


def _episode_info(
    record: dict[str, np.ndarray],
    controller: Controller | None,
    trajectory: Trajectory,
    friction: float,
    pushes: list[Push],
) -> dict[str, Any]:
    """Whether the episode succeeded, its decisions and their compute time (s), its plant."""
    return {
        "success": bool(record["in_success"][-1]),
        "captured_fraction": float(np.mean(record["captured"])),
        "decisions": 0 if controller is None else controller.decisions,
        "decision_seconds": 0.0 if controller is None else controller.seconds,
        "analyses": 0 if controller is None else controller.context.analyses,
        "nominal_friction": float(trajectory.friction),
        "plant_friction": float(friction),
        "pushes": len(pushes),
    }


def _episode_path(out: Path, index: int) -> Path:
    return out / EPISODES_DIR / f"{index:05d}.npz"


def _save_episode(path: Path, result: dict[str, Any]) -> None:
    with atomic_path(path) as temporary, open(temporary, "wb") as stream:
        save_npz(stream, {"info": np.array(json.dumps(result["info"])), **result["record"]})


def _load_episode(path: Path) -> dict[str, Any] | None:
    """A saved episode, or ``None`` when the file is missing or unreadable (it is then rerun)."""
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as stored:
            info = json.loads(str(stored["info"]))
            record = {key: stored[key] for key in stored.files if key != "info"}
    except (OSError, ValueError, KeyError, json.JSONDecodeError):
        return None
    return {"record": record, "info": info}


_WORKER: dict[str, Any] = {}


def _init_worker(task: Task, settings: ControlSettings, model: MarginPredictor | None) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _WORKER.update(task=task, settings=settings, model=model)


def _run_in_worker(job: tuple[int, np.random.SeedSequence]) -> tuple[int, dict[str, Any]]:
    index, seed = job
    return index, run_episode(_WORKER["task"], _WORKER["settings"], seed, model=_WORKER["model"])


def _run_jobs(
    task: Task,
    settings: ControlSettings,
    model: MarginPredictor | None,
    jobs: list[tuple[int, np.random.SeedSequence]],
    workers: int,
) -> Iterator[tuple[int, dict[str, Any]]]:
    if workers == 1 or len(jobs) <= 1:
        for index, seed in jobs:
            yield index, run_episode(task, settings, seed, model=model)
        return
    yield from pool_results(
        _run_in_worker, jobs, workers=workers, initializer=_init_worker, initargs=(task, settings, model)
    )


#: A control run: ``control.json`` (the settings, then the summary), one file per episode in
#: ``episodes/``, and the episodes as a dataset. The number of episodes may change: episode i's
#: seed does not depend on it, so a run grows (or is summarised over its first E episodes)
#: without recomputing any.
CONTROL_RUN = RunSpec(
    contents="episodes",
    settings_file=CONTROL_FILE,
    outputs=(EPISODES_DIR, METADATA_FILE, FRAMES_FILE),
    may_differ=("episodes",),
    settings_key="settings",
)


def _episodes(
    task: Task,
    settings: ControlSettings,
    model: MarginPredictor | None,
    out: Path,
    *,
    workers: int,
    progress: Progress,
    on_episode: Callable[[int], None] | None,
) -> list[dict[str, Any]]:
    """Every episode of the run in order: the saved ones read back, the others run and saved as they finish."""
    seeds = np.random.SeedSequence(settings.seed).spawn(settings.episodes)
    results: dict[int, dict[str, Any]] = {}
    for index in range(settings.episodes):
        saved = _load_episode(_episode_path(out, index))
        if saved is not None:
            results[index] = saved
    jobs = [(index, seeds[index]) for index in range(settings.episodes) if index not in results]
    bar = progress_bar(
        settings.episodes, desc=f"control {settings.policy}", initial=len(results), enabled=progress, unit="episode"
    )
    try:
        for index, result in _run_jobs(task, settings, model, jobs, workers):
            _save_episode(_episode_path(out, index), result)
            results[index] = result
            bar.update(1)
            if on_episode is not None:
                on_episode(index)
    finally:
        bar.close()
    return [results[index] for index in range(settings.episodes)]


def run_control(
    task_name: str,
    *,
    n_objects: int,
    episodes: int,
    policy: str,
    disturbance: str,
    seed: int,
    out: Path | str,
    task_overrides: dict[str, Any] | None = None,
    controller: ControllerConfig | None = None,
    weights: CostWeights | None = None,
    n_frames: int = 10,
    score_expansions: int = 30,
    model: MarginPredictor | None = None,
    model_info: dict[str, Any] | None = None,
    workers: int = 1,
    overwrite: bool = False,
    progress: Progress = False,
    on_episode: Callable[[int], None] | None = None,
) -> tuple[ControlResult, Dataset]:
    """Run (or resume) ``episodes`` episodes of ``policy`` and write them as a dataset at ``out``.

    Args:
        task_name: a registered task with a command space.
        n_objects: objects per episode, >= 1.
        episodes: number of episodes, >= 1.
        policy: one of :data:`POLICIES`.
        disturbance: a level of :data:`~energy_margin.control.disturbances.DISTURBANCES`.
        seed: non-negative integer seed.
        out: the run's directory (the dataset, ``control.json`` and ``episodes/``).
        task_overrides: task settings to override.
        controller: MPPI settings (defaults when ``None``).
        weights: cost weights (defaults when ``None``).
        n_frames: frames recorded per episode, >= 2.
        score_expansions: expansions per recorded frame of the scoring analysis, >= 0.
        model: the learned margin, for ``policy="learned"``.
        model_info: what identifies the model (saved with the settings).
        workers: processes running episodes, >= 1.
        overwrite: replace a run of other settings in ``out``.
        progress: show a progress bar on standard error.
        on_episode: called with each episode's index as it is saved (tests use it to interrupt).

    Returns:
        The summary (:class:`~energy_margin.control.episode_scores.ControlResult`) and the dataset.

    """
    _check_arguments(n_objects, episodes, seed, n_frames, score_expansions, workers, policy, model)
    task = _control_task(task_name, task_overrides, n_objects, model)
    settings = ControlSettings(
        task=task.name,
        task_config=task.config.to_dict(),
        n_objects=int(n_objects),
        episodes=int(episodes),
        policy=policy,
        disturbance=get_disturbance(disturbance).to_dict(),
        seed=int(seed),
        n_frames=int(n_frames),
        score_expansions=int(score_expansions),
        controller=(controller or ControllerConfig()).to_dict(),
        weights=asdict(weights or CostWeights()),
        model=model_info,
    )
    out = Path(out)
    with run_directory(out, CONTROL_RUN, settings.to_dict(), overwrite=overwrite) as run:
        run.write_settings({"package_version": __version__})
        (out / EPISODES_DIR).mkdir(exist_ok=True)
        ordered = _episodes(task, settings, model, out, workers=workers, progress=progress, on_episode=on_episode)
        summary = summarize(settings, [result["info"] for result in ordered])
        extra = {"control": {"settings": settings.to_dict(), "summary": summary.to_dict()}}
        write_episodes_dataset(task, [result["record"] for result in ordered], out, extra=extra)
        run.write_settings({"summary": summary.to_dict(), "package_version": __version__})
    return summary, load_dataset(out)


def _check_arguments(
    n_objects: int,
    episodes: int,
    seed: int,
    n_frames: int,
    score_expansions: int,
    workers: int,
    policy: str,
    model: MarginPredictor | None,
) -> None:
    """Refuse counts out of range, an unknown policy, and a model without ``learned`` (or the reverse)."""
    check_int("n_objects", n_objects, minimum=1)
    check_int("episodes", episodes, minimum=1)
    check_seed(seed)
    check_int("n_frames", n_frames, minimum=2)
    check_int("score_expansions", score_expansions, minimum=0)
    check_int("workers", workers, minimum=1)
    if policy not in POLICIES:
        raise EnergyMarginError(f"unknown policy {policy!r}; choose one of {', '.join(POLICIES)}")
    if policy == "learned" and model is None:
        raise InvalidParameterError("policy", "learned needs `model`, a model made by energy-margin learn")
    if policy != "learned" and model is not None:
        raise InvalidParameterError("model", "is only for `policy=learned`")


def _control_task(
    task_name: str, task_overrides: dict[str, Any] | None, n_objects: int, model: MarginPredictor | None
) -> Task:
    """The controllable task, checked against the number of objects and the model's task."""
    if task_name not in controllable_tasks():
        raise EnergyMarginError(
            f"task {task_name!r} cannot be controlled; controllable tasks: {', '.join(controllable_tasks())}"
        )
    task = get_task(task_name, task_overrides or None)
    if task.fixed_objects is not None and n_objects != task.fixed_objects:
        raise EnergyMarginError(f"{task.label} has {task.fixed_objects} objects, not {n_objects}")
    if model is not None and model.task_name != task.name:
        raise EnergyMarginError(f"the model was learned on task {model.task_name!r}, not {task.name!r}")
    return task
