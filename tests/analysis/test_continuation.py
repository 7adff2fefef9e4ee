"""Success continuation: the scripted motion continued from a tree's likely states scores success.

The tiny scene's pusher carries the boxes into the goal only after about 1.1 s, beyond the reach
of a small tree grown from the first frame: the tree's own success score is 0, the continuation's
is not, and a horizon too short to reach the goal brings it back to 0.
"""

from __future__ import annotations

import csv
import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from energy_margin.analysis.continuation import continued_success
from energy_margin.analysis.frame import AnalyzerConfig, analyze_frame
from energy_margin.analysis.run import analyze
from energy_margin.cli import main
from energy_margin.errors import InvalidParameterError
from energy_margin.sim.base import BatchedRollout
from energy_margin.tasks import get_task
from tiny_scene import write_tiny_scene

SMALL = {"expansions": 30}


@pytest.fixture(scope="module")
def scene_task(tmp_path_factory: pytest.TempPathFactory):  # type: ignore[no-untyped-def]
    path = write_tiny_scene(tmp_path_factory.mktemp("continuation") / "scene")
    task = get_task("scene", {"scene_file": str(path)})
    return task, task.sample_trajectory(np.random.default_rng(1), 2)


def _frame(scene_task, config: AnalyzerConfig, seed: int = 3):  # type: ignore[no-untyped-def]
    task, trajectory = scene_task
    return analyze_frame(
        task, trajectory.initial, friction=trajectory.friction, drive=trajectory.drive, seed=seed, config=config
    )


def test_a_goal_beyond_the_trees_reach_scores_only_with_continuation(scene_task) -> None:  # type: ignore[no-untyped-def]
    task, _ = scene_task
    plain, field = _frame(scene_task, AnalyzerConfig(**SMALL))
    # The tree stays well short of the motion's end, and none of its states is successful.
    assert field.times.max() < 0.8 < task.config.duration
    assert plain.success_score == 0.0
    continued, continued_field = _frame(scene_task, AnalyzerConfig(**SMALL, continuation=8))
    assert continued.success_score > 0.5
    # The continuation draws from its own generator: the tree and its capture score are unchanged.
    assert continued.capture_score == plain.capture_score
    np.testing.assert_array_equal(continued_field.costs, field.costs)
    # Continued only 0.3 s past each node, no box reaches the goal.
    short, _ = _frame(scene_task, AnalyzerConfig(**SMALL, continuation=8, continuation_horizon=0.3))
    assert short.success_score == 0.0


def test_the_same_seed_gives_the_same_score_and_a_tree_grown_in_rounds_scores_too(scene_task) -> None:  # type: ignore[no-untyped-def]
    config = AnalyzerConfig(**SMALL, continuation=4)
    first, _ = _frame(scene_task, config, seed=5)
    again, _ = _frame(scene_task, config, seed=5)
    assert (first.success_score, first.capture_score) == (again.success_score, again.capture_score)
    batched, field = _frame(scene_task, AnalyzerConfig(**SMALL, continuation=4, batch=4), seed=5)
    assert field.states is not None and batched.success_score > 0.5


class _OneAtATime:
    """The simulator without its batched roll-outs (the path of a simulator that offers none)."""

    def __init__(self, simulator: object) -> None:
        self._simulator = simulator

    def __getattr__(self, name: str) -> object:
        if name == "rollout_propagator":
            raise AttributeError(name)
        return getattr(self._simulator, name)


@pytest.mark.parametrize("horizon", [None, 0.3])
def test_one_at_a_time_and_batched_continuations_agree(scene_task, horizon: float | None) -> None:  # type: ignore[no-untyped-def]
    task, trajectory = scene_task
    simulator = task.make_simulator(2, trajectory.friction, trajectory.drive)
    _, field = analyze_frame(
        task,
        trajectory.initial,
        friction=trajectory.friction,
        drive=trajectory.drive,
        seed=3,
        config=AnalyzerConfig(**SMALL),
        simulator=simulator,
    )
    lam = task.config.likelihood_lambda
    kwargs = {"lam": lam, "samples": 6, "seed": 9, "horizon": horizon}
    single = _OneAtATime(simulator)
    assert not isinstance(single, BatchedRollout)
    one = continued_success(single, task, trajectory.initial, field, trajectory.drive, **kwargs)  # type: ignore[arg-type]
    batched = continued_success(simulator, task, trajectory.initial, field, trajectory.drive, **kwargs)
    assert one == batched
    assert one.success_score == (1.0 if horizon is None else 0.0)
    # To the end of the motion (from the earliest drawn node), or 0.3 s.
    full = round(task.config.duration / task.config.timestep)
    assert full - 0.8 / task.config.timestep < one.steps <= full if horizon is None else one.steps == 30


@pytest.mark.parametrize(
    ("settings", "name"),
    [
        ({"continuation": -1}, "continuation"),
        ({"continuation": 1.5}, "continuation"),
        ({"continuation_horizon": 0.0}, "continuation_horizon"),
        ({"continuation_horizon": -1.0}, "continuation_horizon"),
        ({"continuation": 2, "engine": "pybullet"}, "continuation"),
    ],
)
def test_bad_continuation_settings_are_parameter_errors(settings: dict[str, object], name: str) -> None:
    with pytest.raises(InvalidParameterError, match=name):
        AnalyzerConfig(**settings)  # type: ignore[arg-type]


def test_bad_continuation_arguments_are_parameter_errors(scene_task) -> None:  # type: ignore[no-untyped-def]
    task, trajectory = scene_task
    simulator = task.make_simulator(2, trajectory.friction, trajectory.drive)
    _, field = _frame(scene_task, AnalyzerConfig(expansions=5))
    args = (simulator, task, trajectory.initial, field, trajectory.drive)
    with pytest.raises(InvalidParameterError, match="samples"):
        continued_success(*args, lam=1.0, samples=0, seed=0)
    with pytest.raises(InvalidParameterError, match="horizon"):
        continued_success(*args, lam=1.0, samples=2, seed=0, horizon=0.0)
    without = type(field)(**{**field.__dict__, "states": None})
    with pytest.raises(InvalidParameterError, match="node states"):
        continued_success(simulator, task, trajectory.initial, without, trajectory.drive, lam=1.0, samples=2, seed=0)


def _rows(path: Path) -> tuple[list[str], list[dict[str, str]]]:
    with (path / "scores.csv").open() as handle:
        reader = csv.DictReader(handle)
        return list(reader.fieldnames or []), list(reader)


def test_analysis_json_records_it_scores_csv_keeps_its_columns_and_workers_agree(copy_dataset, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    config = AnalyzerConfig(expansions=10, continuation=3, continuation_horizon=0.5)
    one, two, plain = copy_dataset("one"), copy_dataset("two"), copy_dataset("plain")
    analyze(one, config, seed=2, workers=1, progress=False)
    analyze(two, config, seed=2, workers=2, progress=False)
    analyze(plain, AnalyzerConfig(expansions=10), seed=2, progress=False)
    recorded = json.loads((one / "analysis.json").read_text())["analyzer"]
    assert (recorded["continuation"], recorded["continuation_horizon"]) == (3, 0.5)
    columns, rows = _rows(one)
    plain_columns, plain_rows = _rows(plain)
    assert columns == plain_columns
    assert [row["success_score"] for row in rows] == [row["success_score"] for row in _rows(two)[1]]
    assert [row["capture_score"] for row in rows] == [row["capture_score"] for row in plain_rows]
    # A fraction of three draws.
    assert {round(float(row["success_score"]) * 3, 9) % 1 for row in rows} == {0.0}


def test_the_command_line_takes_the_continuation(tiny_dataset: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["analyze", str(tiny_dataset), "--expansions", "5", "--continuation", "2", "--no-progress"]) == 0
    assert json.loads((tiny_dataset / "analysis.json").read_text())["analyzer"]["continuation"] == 2
    capsys.readouterr()
    with pytest.raises(SystemExit):
        main(["analyze", str(tiny_dataset), "--expansions", "5", "--continuation-horizon", "0", "--no-progress"])
    assert "continuation-horizon" in capsys.readouterr().err


@pytest.mark.parametrize("batched", [True, False])
def test_a_continuation_from_a_recorded_frame_replays_the_recorded_motion(tmp_path: Path, batched: bool) -> None:
    # The command of every step, as the generator's: held for a period, the roll-out would differ.
    from energy_margin.analysis import continuation
    from energy_margin.data.generate import generate_dataset

    scene = write_tiny_scene(tmp_path / "scene")
    dataset = generate_dataset(
        get_task("scene", {"scene_file": str(scene)}), n_objects=None, n_trajectories=1, n_frames=4, seed=0,
        out=tmp_path / "data",
    )  # fmt: skip
    task = dataset.task
    friction, drive = float(dataset.arrays["friction"][0]), dataset.arrays["drive"][0]
    simulator = task.make_simulator(dataset.n_objects, friction, drive)
    _, field = analyze_frame(task, dataset.frame(0, 1), friction=friction, drive=drive, seed=0,
                             config=AnalyzerConfig(expansions=3), start_time=float(dataset.arrays["frame_time"][0, 1]),
                             simulator=simulator)  # fmt: skip
    nodes, start = np.array([0]), float(dataset.arrays["frame_time"][0, 1])
    steps = continuation._steps(task.config.duration, simulator.timestep, field, nodes, start, None)
    run = continuation._continue_batched if batched else continuation._continue_one_by_one
    args = (simulator if batched else _OneAtATime(simulator), task, field, nodes, np.array([start]), steps, drive)
    pos = run(*args, *((False, 1) if batched else ()))[0]  # type: ignore[operator]
    assert float(dataset.arrays["frame_time"][0, -1]) == pytest.approx(task.config.duration)
    np.testing.assert_allclose(pos[0], dataset.frame(0, 3).object_pos, atol=1e-6)


@pytest.mark.parametrize("batch", [1, 4])
def test_a_lambda_re_scoring_continues_at_every_lambda_as_analyze_would(tmp_path: Path, batch: int) -> None:
    """The continuation's draws depend on lambda: re-scored, each lambda's row is analyze's at that lambda."""
    from energy_margin.analysis.frame import FrameAnalyzer
    from energy_margin.data.generate import generate_dataset
    from energy_margin.evaluation.lambda_rescoring import LambdaRescorer

    scene = write_tiny_scene(tmp_path / "scene")
    dataset = generate_dataset("scene", n_objects=2, n_trajectories=2, n_frames=2, seed=0, out=tmp_path / "d",
                               task_config={"scene_file": str(scene)})  # fmt: skip
    # Continued 1.1 s, about half of the first frame's continuations reach the goal: which nodes are
    # drawn (by lambda) decides the score.
    config = AnalyzerConfig(expansions=10, batch=batch, continuation=16, continuation_horizon=1.1)
    lambdas = [0.0, 1e5]
    rescorer = LambdaRescorer(dataset, config, 3, lambdas=lambdas)
    scores = []
    for index in range(4):
        rows = rescorer(index)["rows"]
        for lam, row in zip(lambdas, rows, strict=True):
            direct = FrameAnalyzer(dataset, dataclasses.replace(config, likelihood_lambda=lam), 3)(index)
            assert (row["capture_score"], row["success_score"]) == (direct["capture_score"], direct["success_score"])
        scores.append([row["success_score"] for row in rows])
    assert any(low != high for low, high in scores)  # lambda moved a continued score
    assert rescorer.config.continuation == 0  # the tree is grown once, without a continuation


def test_analyze_says_when_the_trees_reach_no_success_early(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The tiny scene's goal lies beyond the trees of its early frames: a note names the continuation."""
    scene = write_tiny_scene(tmp_path / "scene")
    data = tmp_path / "data"
    assert main(["generate", "--scene", str(scene), "--trajectories", "2", "--frames", "4", "--seed", "0",
                 "--out", str(data)]) == 0  # fmt: skip
    capsys.readouterr()
    # The tree's own score, asked for by name (by default analyze continues:
    # tests/analysis/test_continuation_rule.py).
    assert main(["analyze", str(data), "--expansions", "10", "--continuation", "0", "--no-progress"]) == 0
    notes = [line for line in capsys.readouterr().err.splitlines() if "score success 0" in line]
    assert len(notes) == 1 and "100% of the first-half frames" in notes[0] and "--continuation 16" in notes[0]
    again = ["analyze", str(data), "--expansions", "10", "--continuation", "4", "--no-progress", "--overwrite"]
    assert main(again) == 0
    assert "score success 0" not in capsys.readouterr().err


def test_the_share_of_unreached_success_counts_the_first_half_only() -> None:
    from energy_margin.data.scores_file import unreached_success_share

    frames = np.array([0, 1, 2, 3, 4, 0, 1, 2, 3, 4])
    success = np.array([0.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.001, 0.0, 0.0, 0.0])
    assert unreached_success_share({"frame": frames, "success_score": success}) == 5 / 6
    assert unreached_success_share({"frame": frames[:0], "success_score": success[:0]}) is None
