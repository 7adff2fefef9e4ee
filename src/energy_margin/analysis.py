"""Score every frame of a dataset with energy margins (Algorithm 1) and write the scores table.

``analyze_frame`` scores one state; ``analyze`` scores a whole dataset directory with a local
process pool, a progress bar and an append-only journal, so an interrupted run resumes where it
stopped. Frame ``i`` (trajectory-major order) uses the seed
``SeedSequence(seed).spawn(n_frames_total)[i].generate_state(1, uint64)[0]``, so the scores do not
depend on the number of workers or on the order in which frames finish.
"""

from __future__ import annotations

import dataclasses
import json
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin import __version__
from energy_margin.dataset import SCORES_FILE, Dataset
from energy_margin.energy import COST_MODELS, make_cost_model
from energy_margin.errors import EnergyMarginError
from energy_margin.executors import make_executor
from energy_margin.io import atomic_write_text, read_json, write_json
from energy_margin.planning import CostField, TreeBudget, grow_tree
from energy_margin.planning.density import PROJECTIONS, make_features
from energy_margin.planning.methods import METHODS
from energy_margin.scores import region_score
from energy_margin.sim import ENGINES, Simulator, make_simulator
from energy_margin.state import FrameState
from energy_margin.tasks import Task, all_inside
from energy_margin.validation import require_valid

JOURNAL_FILE = "scores.journal.csv"
CONFIG_FILE = "analysis.json"
#: Columns of scores.csv written as integers.
INTEGER_COLUMNS = ("trajectory", "frame", "nodes", "iterations", "seed")
COLUMNS = (
    "trajectory",
    "frame",
    "capture_score",
    "success_score",
    "nodes",
    "iterations",
    "runtime_s",
    "physics_s",
    "seed",
)


@dataclass(frozen=True)
class AnalyzerConfig:
    """Settings of an energy-margin analysis.

    Attributes:
        iterations: EST expansions per frame (accepted or rejected); ``None`` for a node budget only.
        nodes: accepted tree nodes (children of the root) per frame; ``None`` for no node budget.
        cost: incremental cost model, ``"wrench"`` (perturbation work) or ``"energy"`` (|dE - W_fri|).
        likelihood_lambda: softmax inverse temperature lambda, 1/J; ``None`` uses the task's value.
        n_projections: random projections of the EST density estimate.
        cell_size: density grid cell width, m.
        engine: physics engine.
        method: tree method, ``"est"`` (the paper), ``"montecarlo"`` (independent roll-outs) or
            ``"rrt"`` (nearest node to a random target, one random control); see
            :mod:`energy_margin.planning.methods`.
        batch: iterations propagated together per round through ``mujoco.rollout`` (1: one at a
            time, the reference behaviour; > 1 needs the ``"wrench"`` cost).
        threads: ``mujoco.rollout`` threads when ``batch`` > 1.
        rollout_length: propagations per Monte Carlo roll-out.
        rrt_extent: half width of the RRT target box, m.
        projection: EST density features, ``"objects"`` (every object's centre relative to the
            root) or ``"ellipsoid"`` (centre and shape matrix of the ellipsoid of the centres).

    """

    iterations: int | None = 300
    nodes: int | None = None
    cost: str = "wrench"
    likelihood_lambda: float | None = None
    n_projections: int = 8
    cell_size: float = 0.01
    engine: str = "mujoco"
    method: str = "est"
    batch: int = 1
    threads: int = 1
    rollout_length: int = 10
    rrt_extent: float = 0.1
    projection: str = "objects"

    def __post_init__(self) -> None:
        for name in ("iterations", "nodes"):
            value = getattr(self, name)
            if value is not None and (isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 0):
                raise ValueError(f"{name} must be a non-negative integer, got {value!r}")
        if self.iterations is None and self.nodes is None:
            raise ValueError("iterations and nodes cannot both be None")
        if self.cost not in COST_MODELS:
            raise ValueError(f"cost must be one of {', '.join(COST_MODELS)}, got {self.cost!r}")
        if self.likelihood_lambda is not None and not (
            np.isfinite(self.likelihood_lambda) and self.likelihood_lambda >= 0
        ):
            raise ValueError(f"likelihood_lambda must be finite and >= 0, got {self.likelihood_lambda!r}")
        if isinstance(self.n_projections, bool) or not isinstance(self.n_projections, int) or self.n_projections < 1:
            raise ValueError(f"n_projections must be an integer >= 1, got {self.n_projections!r}")
        if not (np.isfinite(self.cell_size) and self.cell_size > 0):
            raise ValueError(f"cell_size must be > 0, got {self.cell_size!r}")
        if self.engine not in ENGINES:
            raise ValueError(f"engine must be one of {', '.join(ENGINES)}, got {self.engine!r}")
        if self.method not in METHODS:
            raise ValueError(f"method must be one of {', '.join(METHODS)}, got {self.method!r}")
        for name in ("batch", "threads", "rollout_length"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
                raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
        if self.batch > 1 and make_cost_model(self.cost).needs_friction_work:
            raise ValueError(f"batch > 1 does not integrate friction work: use cost 'wrench', not {self.cost!r}")
        if not (np.isfinite(self.rrt_extent) and self.rrt_extent > 0):
            raise ValueError(f"rrt_extent must be > 0, got {self.rrt_extent!r}")
        if self.projection not in PROJECTIONS:
            raise ValueError(f"projection must be one of {', '.join(PROJECTIONS)}, got {self.projection!r}")

    @property
    def budget(self) -> TreeBudget:
        """The tree budget."""
        return TreeBudget(iterations=self.iterations, nodes=self.nodes)

    def to_dict(self) -> dict[str, Any]:
        """JSON-compatible dictionary of every field."""
        return dataclasses.asdict(self)


@dataclass(frozen=True)
class FrameScores:
    """Scores of one frame.

    Attributes:
        capture_score: likelihood mass of captured states, in [0, 1].
        success_score: likelihood mass of successful states, in [0, 1].
        nodes: tree nodes including the root.
        iterations: expansions performed.
        runtime_s: wall time of tree growth and scoring, s.
        physics_s: part of it spent in the simulator, s.

    """

    capture_score: float
    success_score: float
    nodes: int
    iterations: int
    runtime_s: float
    physics_s: float


def frame_seeds(seed: int, count: int) -> list[int]:
    """Per-frame seeds spawned from ``seed``: one 64-bit integer per frame."""
    children = np.random.SeedSequence(seed).spawn(count)
    return [int(child.generate_state(1, np.uint64)[0]) for child in children]


def score_field(task: Task, root: FrameState, field: CostField, lam: float) -> tuple[float, float]:
    """Capture and success scores of a cost field (Algorithm 1, lines 4-11)."""
    captured = all_inside(task.capture_region(root), field.object_pos, field.object_vel)
    successful = all_inside(task.success_region(), field.object_pos, field.object_vel)
    return region_score(field.costs, captured, lam), region_score(field.costs, successful, lam)


def analyze_frame(
    task: Task,
    frame: FrameState,
    *,
    friction: float,
    drive: np.ndarray,
    seed: int,
    config: AnalyzerConfig | None = None,
    start_time: float = 0.0,
    simulator: Simulator | None = None,
) -> tuple[FrameScores, CostField]:
    """Grow a tree (``config.method``, EST by default) from ``frame`` and score it.

    Args:
        task: the task.
        frame: the state z_init.
        friction: Coulomb coefficient of the frame's trajectory.
        drive: drive parameters of the trajectory, shape (n_drive,).
        seed: the frame's seed.
        config: analysis settings (defaults when ``None``).
        start_time: time of the frame within its roll-out, s.
        simulator: a simulator of the frame's scene, to reuse one across frames.

    Returns:
        The scores and the energy-cost field.

    """
    config = config if config is not None else AnalyzerConfig()
    if simulator is None:
        simulator = make_simulator(task.build_scene(frame.n_objects, friction, drive), config.engine)
    lam = config.likelihood_lambda if config.likelihood_lambda is not None else task.config.likelihood_lambda
    started = time.perf_counter()
    field = grow_tree(
        simulator,
        task,
        frame,
        np.asarray(drive, dtype=float),
        np.random.default_rng(seed),
        budget=config.budget,
        cost_model=make_cost_model(config.cost),
        features=make_features(config.projection, simulator.scene),
        n_projections=config.n_projections,
        cell_size=config.cell_size,
        start_time=start_time,
        method=config.method,
        batch=config.batch,
        threads=config.threads,
        rollout_length=config.rollout_length,
        rrt_extent=config.rrt_extent,
    )
    capture, success = score_field(task, frame, field, lam)
    runtime = time.perf_counter() - started
    scores = FrameScores(capture, success, field.nodes, field.iterations, runtime, field.physics_s)
    return scores, field


_SIMULATOR_CACHE = 4


class FrameAnalyzer:
    """Scores frames of one dataset, reusing one simulator per distinct (friction, drive) pair."""

    def __init__(self, dataset: Dataset, config: AnalyzerConfig, seed: int) -> None:
        self.dataset = dataset
        self.task = dataset.task
        self.config = config
        total = dataset.n_trajectories * dataset.n_frames
        self.seeds = frame_seeds(seed, total)
        self._simulators: dict[tuple[float, bytes], Simulator] = {}

    def _simulator(self, friction: float, drive: np.ndarray) -> Simulator:
        # The drive may change the model (e.g. a servo stiffness), so it is part of the key.
        key = (friction, np.asarray(drive, dtype=float).tobytes())
        simulator = self._simulators.pop(key, None)
        if simulator is None:
            # Frames arrive trajectory by trajectory: a few recent simulators suffice, and keeping
            # more would let memory grow with the number of distinct trajectories.
            while len(self._simulators) >= _SIMULATOR_CACHE:
                self._simulators.pop(next(iter(self._simulators)))
            scene = self.task.build_scene(self.dataset.n_objects, friction, drive)
            simulator = make_simulator(scene, self.config.engine)
        self._simulators[key] = simulator
        return simulator

    def __call__(self, index: int) -> dict[str, Any]:
        """The scores row of frame ``index`` (trajectory-major)."""
        dataset = self.dataset
        trajectory, frame_index = divmod(index, dataset.n_frames)
        friction = float(dataset.arrays["friction"][trajectory])
        drive = dataset.arrays["drive"][trajectory]
        scores, _ = analyze_frame(
            self.task,
            dataset.frame(trajectory, frame_index),
            friction=friction,
            drive=drive,
            seed=self.seeds[index],
            config=self.config,
            start_time=float(dataset.arrays["frame_time"][trajectory, frame_index]),
            simulator=self._simulator(friction, drive),
        )
        return {
            "trajectory": trajectory,
            "frame": frame_index,
            "capture_score": scores.capture_score,
            "success_score": scores.success_score,
            "nodes": scores.nodes,
            "iterations": scores.iterations,
            "runtime_s": scores.runtime_s,
            "physics_s": scores.physics_s,
            "seed": self.seeds[index],
        }


def _format_row(row: dict[str, Any]) -> str:
    return ",".join(repr(float(row[c])) if isinstance(row[c], float) else str(row[c]) for c in COLUMNS)


def _parse_row(line: str) -> dict[str, Any] | None:
    """A journal line as a row, or ``None`` for a torn or foreign line."""
    fields = line.rstrip("\n").split(",")
    if len(fields) != len(COLUMNS) or not line.endswith("\n"):
        return None
    try:
        row: dict[str, Any] = {}
        for name, text in zip(COLUMNS, fields, strict=True):
            row[name] = int(text) if name in INTEGER_COLUMNS else float(text)
    except ValueError:
        return None
    return row


def read_journal(path: Path) -> dict[tuple[int, int], dict[str, Any]]:
    """Completed rows of a journal, keyed by (trajectory, frame); torn or duplicate lines are dropped."""
    rows: dict[tuple[int, int], dict[str, Any]] = {}
    if not path.is_file():
        return rows
    with path.open(encoding="utf-8", errors="replace") as stream:
        for line in stream:
            row = _parse_row(line)
            if row is not None:
                rows.setdefault((row["trajectory"], row["frame"]), row)
    return rows


def _header() -> str:
    return ",".join(COLUMNS) + "\n"


def _run_description(dataset: Dataset, config: AnalyzerConfig, seed: int) -> dict[str, Any]:
    import mujoco

    description: dict[str, Any] = {
        "analyzer": config.to_dict(),
        "seed": int(seed),
        "dataset": {
            "task": dataset.metadata["task"],
            "seed": dataset.metadata.get("seed"),
            "n_trajectories": dataset.n_trajectories,
            "n_frames": dataset.n_frames,
            "n_objects": dataset.n_objects,
        },
        "task_config": dataset.task.config.to_dict(),
        "likelihood_lambda": config.likelihood_lambda
        if config.likelihood_lambda is not None
        else dataset.task.config.likelihood_lambda,
        "versions": {"energy_margin": __version__, "mujoco": mujoco.__version__, "numpy": np.__version__},
    }
    if config.engine == "pybullet":
        from importlib.metadata import version

        description["versions"]["pybullet"] = version("pybullet")
    return description


# Analyzer settings added after the first release: an analysis.json without them used their defaults.
_LATER_FIELDS = ("method", "batch", "threads", "rollout_length", "rrt_extent")


def _same_run(previous: dict[str, Any], current: dict[str, Any]) -> bool:
    if isinstance(previous.get("analyzer"), dict):
        defaults = AnalyzerConfig().to_dict()
        previous = {**previous, "analyzer": {**{k: defaults[k] for k in _LATER_FIELDS}, **previous["analyzer"]}}
    keys = ("analyzer", "seed", "dataset", "task_config")
    previous = dict(previous)
    if isinstance(previous.get("analyzer"), dict):
        # Settings added later (e.g. ``projection``) take their defaults in older files.
        previous["analyzer"] = {**AnalyzerConfig().to_dict(), **previous["analyzer"]}
    return all(json.dumps(previous.get(k), sort_keys=True) == json.dumps(current.get(k), sort_keys=True) for k in keys)


def analyze(
    path: Path | str,
    config: AnalyzerConfig | None = None,
    *,
    seed: int = 0,
    workers: int = 1,
    executor: str = "local",
    address: str | None = None,
    overwrite: bool = False,
    progress: bool = True,
) -> Path:
    """Score every frame of the dataset at ``path`` and write ``scores.csv`` beside it.

    The resolved configuration goes to ``analysis.json``. Rows are appended to
    ``scores.journal.csv`` as frames finish; ``scores.csv`` (sorted by trajectory and frame) is
    written atomically at the end. Running again after an interruption skips finished frames.

    Args:
        path: dataset directory.
        config: analysis settings.
        seed: non-negative integer seed of the analysis.
        workers: parallel workers, >= 1 (local processes or Ray actors).
        executor: ``"local"`` (default) or ``"ray"``.
        address: Ray cluster address for ``executor="ray"``; ``None`` starts a local instance.
        overwrite: discard scores of a different configuration instead of refusing.
        progress: show a progress bar on standard error.

    Returns:
        The path of ``scores.csv``.

    """
    config = config if config is not None else AnalyzerConfig()
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise EnergyMarginError(f"seed must be a non-negative integer, got {seed!r}")
    runner = make_executor(executor, workers=workers, address=address)
    dataset = require_valid(path, overlaps=True, scores=False)
    directory = Path(path)
    description = _run_description(dataset, config, seed)
    config_path, journal_path, scores_path = (directory / name for name in (CONFIG_FILE, JOURNAL_FILE, SCORES_FILE))

    if config_path.exists():
        try:
            previous = read_json(config_path, what="analysis configuration")
        except EnergyMarginError:
            previous = None
        if not isinstance(previous, dict) or not _same_run(previous, description):
            if not overwrite:
                raise EnergyMarginError(
                    f"{directory} holds scores of a different analysis ({config_path.name}); "
                    "pass --overwrite to replace them"
                )
            for stale in (journal_path, scores_path):
                stale.unlink(missing_ok=True)
        elif scores_path.exists():
            return scores_path
    total = dataset.n_trajectories * dataset.n_frames
    done = {key: row for key, row in read_journal(journal_path).items() if _valid_key(key, dataset)}
    write_json(config_path, description)
    # Rewrite the journal without torn or duplicate lines before appending to it.
    atomic_write_text(journal_path, _header() + "".join(_format_row(done[k]) + "\n" for k in sorted(done)))
    pending = [i for i in range(total) if divmod(i, dataset.n_frames) not in done]

    bar = _progress_bar(total, len(done), enabled=progress)
    try:
        with journal_path.open("a", encoding="utf-8") as journal:
            for row in runner.run(dataset, config, seed, pending):
                journal.write(_format_row(row) + "\n")
                journal.flush()
                os.fsync(journal.fileno())
                done[(row["trajectory"], row["frame"])] = row
                bar.update(1)
    finally:
        bar.close()
    lines = [_format_row(done[key]) + "\n" for key in sorted(done)]
    atomic_write_text(scores_path, _header() + "".join(lines))
    return scores_path


def _valid_key(key: tuple[int, int], dataset: Dataset) -> bool:
    return 0 <= key[0] < dataset.n_trajectories and 0 <= key[1] < dataset.n_frames


class _NoBar:
    def update(self, count: int) -> None:
        del count

    def close(self) -> None:
        pass


def _progress_bar(total: int, initial: int, *, enabled: bool) -> Any:
    if not enabled:
        return _NoBar()
    from tqdm import tqdm

    return tqdm(total=total, initial=initial, unit="frame", desc="analyze", dynamic_ncols=True)


def load_scores(path: Path | str) -> dict[str, np.ndarray]:
    """Read ``scores.csv`` of a dataset directory into columns; raise :class:`EnergyMarginError`."""
    directory = Path(path)
    scores_path = directory / SCORES_FILE
    if not scores_path.is_file():
        hint = (
            " (an analysis was interrupted: run analyze again to resume)" if (directory / JOURNAL_FILE).exists() else ""
        )
        raise EnergyMarginError(f"{directory} has no {SCORES_FILE}; run `energy-margin analyze` first{hint}")
    lines = scores_path.read_text(encoding="utf-8", errors="replace").splitlines(keepends=True)
    if not lines or lines[0] != _header():
        raise EnergyMarginError(f"{scores_path}: unexpected header (expected {','.join(COLUMNS)})")
    rows = []
    for number, line in enumerate(lines[1:], start=2):
        row = _parse_row(line if line.endswith("\n") else line + "\n")
        if row is None:
            raise EnergyMarginError(f"{scores_path}: line {number} is malformed")
        rows.append(row)
    dtypes = {"seed": np.uint64, "trajectory": np.int64, "frame": np.int64, "nodes": np.int64, "iterations": np.int64}
    try:
        return {name: np.array([row[name] for row in rows], dtype=dtypes.get(name, np.float64)) for name in COLUMNS}
    except OverflowError:
        raise EnergyMarginError(f"{scores_path}: a count or seed is out of range") from None
