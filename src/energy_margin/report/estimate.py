"""How long ``reproduce`` will take on this machine: a short calibration and the work left to do.

The calibration records one roll-out of each task, grows the trees of its middle and last frames
with the run's expansions (at most 300), perturbs its three frames once and draws one picture; the estimate multiplies
those wall times by the frames not yet in a ``scores.csv`` or journal (pushing scaled by the number
of objects, which the runtime grows with linearly), the roll-outs not yet generated, the frames of
the valid-protocol perturbed copies not yet written (the paper protocol's draw checks nothing and
costs next to nothing) and the pictures of the report.
"""

from __future__ import annotations

import contextlib
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.report.config import TABLE_ONE_PROTOCOLS, ReproduceConfig

__all__ = [
    "CALIBRATION_EXPANSIONS",
    "PlannedAnalysis",
    "StepTimes",
    "calibration_objects",
    "estimate_seconds",
    "frames_left",
    "measure_step_times",
    "planned_analyses",
    "work_left",
]

#: Most expansions a calibration tree grows (its time is scaled to the run's expansions). A tree's
#: later expansions cost more than its first (more nodes, more contacts), so the calibration grows
#: the run's own number up to this.
CALIBRATION_EXPANSIONS = 300
#: Pictures the report draws per task besides its video (rendered frames, perturbed examples).
_REPORT_STILLS = 11
#: Pictures per second of the report's videos.
_REPORT_FPS = 30.0
#: Matplotlib figures, views and encoding of the report, s (measured: docs/howto/report.md).
_REPORT_OVERHEAD_S = 25.0


def calibration_objects(task_name: str) -> int:
    """Objects of a task's calibration scene: its :attr:`~energy_margin.tasks.base.Task.default_objects`."""
    from energy_margin.tasks import get_task

    return get_task(task_name).default_objects


def _report_pictures(task_name: str) -> int:
    """Pictures the report draws of a task: the stills and one video of a roll-out at ``_REPORT_FPS``."""
    from energy_margin.report.video import video_steps
    from energy_margin.tasks import get_task

    config = get_task(task_name).config
    return _REPORT_STILLS + len(video_steps(config.duration, config.timestep, _REPORT_FPS))


@dataclass(frozen=True)
class PlannedAnalysis:
    """One dataset ``reproduce`` generates and analyses.

    Attributes:
        path: the dataset directory relative to the output directory.
        task: task name.
        n_objects: objects per scene.
        n_trajectories: roll-outs.
        n_frames: frames per roll-out.
        generated: whether ``reproduce`` generates it (perturbed copies are not rolled out).
        protocol: the perturbation protocol of a perturbed copy (``None`` for a generated set).

    """

    path: str
    task: str
    n_objects: int
    n_trajectories: int
    n_frames: int
    generated: bool
    protocol: str | None = None


def planned_analyses(config: ReproduceConfig, table_objects: dict[str, int]) -> list[PlannedAnalysis]:
    """Every dataset of a run: Table I datasets and their perturbed copies (both protocols), then the ablation."""
    plan = []
    for task, n_objects in table_objects.items():
        name = f"{task}-{n_objects}"
        plan.append(PlannedAnalysis(f"data/{name}", task, n_objects, config.n_trajectories, config.n_frames, True))
        plan.extend(
            PlannedAnalysis(
                f"data/{name}-{suffix}/{r}", task, n_objects, config.n_trajectories, config.n_frames, False, protocol
            )
            for protocol, suffix in TABLE_ONE_PROTOCOLS.items()
            for r in range(1, config.repeats + 1)
        )
    plan.extend(
        PlannedAnalysis(
            f"data/ablation-pushing-{n}", "pushing", n, config.ablation_n_trajectories, config.ablation_n_frames, True
        )
        for n in config.ablation_objects
    )
    return plan


def frames_left(directory: Path, total: int) -> int:
    """Frames of a dataset directory not yet scored (``scores.csv`` or its journal)."""
    from energy_margin.data.scores_file import JOURNAL_FILE, SCORES_FILE, read_journal

    if (directory / SCORES_FILE).is_file():
        return 0
    return max(0, total - len(read_journal(directory / JOURNAL_FILE)))


@dataclass(frozen=True)
class StepTimes:
    """Wall times measured on this machine.

    Attributes:
        frame_s: seconds per analysed frame of each task at the calibration size, at the run's
            expansions.
        rollout_s: seconds per generated roll-out of each task at the calibration size.
        perturb_s: seconds per perturbed frame of each task at the calibration size.
        picture_s: seconds per drawn picture of the report.
        measured_s: wall time of the calibration itself.

    """

    frame_s: dict[str, float]
    rollout_s: dict[str, float]
    perturb_s: dict[str, float]
    picture_s: float
    measured_s: float


def measure_step_times(config: ReproduceConfig, tasks: list[str]) -> StepTimes:
    """Measure a roll-out, two trees, a perturbation and a picture of each task on this machine (seconds)."""
    from energy_margin.analysis.frame import AnalyzerConfig, analyze_frame
    from energy_margin.data.dataset import frame_from_arrays
    from energy_margin.data.generate import record_trajectory
    from energy_margin.report.render import FrameRenderer
    from energy_margin.robustness.perturb import perturb_frame
    from energy_margin.sim import make_simulator
    from energy_margin.tasks import get_task

    started = time.perf_counter()
    frame_s, rollout_s, perturb_s = {}, {}, {}
    picture_s = 0.05
    expansions = max(1, min(config.expansions, CALIBRATION_EXPANSIONS))
    for name in tasks:
        task = get_task(name)
        n_objects = calibration_objects(name)
        rng = np.random.default_rng(config.seed)
        tick = time.perf_counter()
        record = record_trajectory(task, n_objects, 3, rng, engine=config.engine)
        rollout_s[name] = time.perf_counter() - tick
        friction, drive = float(record["friction"]), record["drive"]
        simulator = make_simulator(task.build_scene(n_objects, friction, drive), config.engine)
        # The middle and the last frame: contacts (pusher, wall, blades) make them the costly ones.
        tick = time.perf_counter()
        for index in (1, 2):
            analyze_frame(
                task,
                frame_from_arrays(record, index),
                friction=friction,
                drive=drive,
                seed=config.seed,
                config=AnalyzerConfig(expansions=expansions, engine=config.engine),
                start_time=float(record["frame_time"][index]),
                simulator=simulator,
            )
        frame_s[name] = (time.perf_counter() - tick) / 2.0 * config.expansions / expansions
        scene = simulator.scene
        tick = time.perf_counter()
        # Perturbing costs little for a spread pile and much for a packed one: all three frames.
        for index in (0, 1, 2):
            # A frame that cannot be perturbed still took its time.
            with contextlib.suppress(Exception):
                perturb_frame(
                    frame_from_arrays(record, index),
                    simulator,
                    np.random.default_rng(config.seed),
                    planar=scene.object_motion == "upright",
                    min_thickness=min(min(obj.geom.size) for obj in scene.objects),
                )
        perturb_s[name] = (time.perf_counter() - tick) / 3.0
    try:
        from energy_margin.sim.mujoco_backend import MujocoSimulator

        task = get_task(tasks[0])
        record = record_trajectory(task, 2, 1, np.random.default_rng(0))
        with FrameRenderer(MujocoSimulator(task.build_scene(2, float(record["friction"]))), task) as renderer:
            frame = frame_from_arrays(record, 0)
            renderer.render(frame)
            tick = time.perf_counter()
            renderer.render(frame)
            picture_s = time.perf_counter() - tick
    except Exception:  # the report falls back to matplotlib; its cost is in the overhead
        pass
    return StepTimes(frame_s, rollout_s, perturb_s, picture_s, time.perf_counter() - started)


def work_left(out: Path, plan: list[PlannedAnalysis]) -> tuple[dict[PlannedAnalysis, int], list[PlannedAnalysis]]:
    """Frames left to analyse per planned dataset, and the datasets still to write (generate or perturb)."""
    from energy_margin.data.dataset import METADATA_FILE

    frames = {entry: frames_left(out / entry.path, entry.n_trajectories * entry.n_frames) for entry in plan}
    to_write = [entry for entry in plan if not (out / entry.path / METADATA_FILE).is_file()]
    return frames, to_write


def estimate_seconds(
    calibration: StepTimes,
    frames: dict[PlannedAnalysis, int],
    to_write: list[PlannedAnalysis],
    *,
    workers: int,
    report: bool,
) -> float:
    """Expected wall time of the work left, s (frames shared by ``workers`` on this machine's cores)."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    parallel = max(1, min(workers, cores))

    def per_object(table: dict[str, float], entry: PlannedAnalysis) -> float:
        reference = calibration_objects(entry.task)
        return table[entry.task] * entry.n_objects / reference

    analysis = sum(count * per_object(calibration.frame_s, entry) for entry, count in frames.items())
    generation = sum(
        entry.n_trajectories * per_object(calibration.rollout_s, entry)
        if entry.generated
        else entry.n_trajectories * entry.n_frames * per_object(calibration.perturb_s, entry)
        for entry in to_write
        if entry.generated or entry.protocol != "paper"
    )
    pictures = sum(_report_pictures(task) for task in {entry.task for entry in frames})
    report_s = pictures * calibration.picture_s + _REPORT_OVERHEAD_S if report else 0.0
    return analysis / parallel + generation + report_s


#: Names of 0.1 that clashed with :func:`energy_margin.evaluation.calibration.calibrate` (λ).
_RENAMED = {"calibrate": "measure_step_times", "Calibration": "StepTimes"}


def __getattr__(name: str) -> Any:
    if name in _RENAMED:
        import warnings

        warnings.warn(
            f"energy_margin.report.estimate.{name} is now {_RENAMED[name]}; the old name goes in 0.3",
            DeprecationWarning,
            stacklevel=2,
        )
        return globals()[_RENAMED[name]]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
