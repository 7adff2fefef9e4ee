"""The default success continuation: continued where the trees of a pilot reach no success, else the tree's own.

The tiny scene's pusher carries the boxes into the goal only after about 1.1 s, beyond the reach of
small trees (every pilot frame scores success 0: the rule continues); the tiny pushing dataset's
trees reach its success region on some first-half frames (the rule leaves the tree's own score).
"""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import pytest

from energy_margin.analysis import continuation_rule
from energy_margin.analysis.config import AnalyzerConfig
from energy_margin.analysis.continuation_rule import AUTO_SAMPLES, ContinuationChoice, choose, pilot_frames
from energy_margin.analysis.run import analyze, resolved_continuation
from energy_margin.cli import main
from energy_margin.data.generate import generate_dataset
from energy_margin.data.scores_file import load_scores
from tiny_scene import write_tiny_scene

SMALL = {"expansions": 10}


@pytest.fixture
def far_goal(tmp_path: Path) -> Path:
    """A dataset of the tiny scene, whose goal lies beyond the trees of its early frames."""
    scene = write_tiny_scene(tmp_path / "scene")
    return generate_dataset(
        "scene", n_objects=2, n_trajectories=2, n_frames=4, seed=0, out=tmp_path / "far",
        task_config={"scene_file": str(scene)},
    ).path  # type: ignore[return-value]  # fmt: skip


def _recorded(path: Path) -> dict:  # type: ignore[type-arg]
    return json.loads((path / "analysis.json").read_text())


def _scores(path: Path) -> list[tuple[float, float]]:
    scores = load_scores(path)
    return list(zip(scores["capture_score"].tolist(), scores["success_score"].tolist(), strict=True))


def test_the_pilot_is_the_first_half_of_the_first_roll_outs() -> None:
    assert pilot_frames(SimpleNamespace(n_trajectories=2, n_frames=3)) == [0, 1, 3, 4]  # type: ignore[arg-type]
    many = pilot_frames(SimpleNamespace(n_trajectories=9, n_frames=10))  # type: ignore[arg-type]
    assert len(many) == continuation_rule.PILOT_TRAJECTORIES * 5
    assert many[:6] == [0, 1, 2, 3, 4, 10] and max(many) == 44


def test_the_rule_continues_at_the_share_of_unreached_frames() -> None:
    def rows(zeros: int, total: int = 10) -> list[dict[str, float]]:
        return [{"success_score": 0.0 if i < zeros else 0.01} for i in range(total)]

    chosen = choose(rows(9))
    assert isinstance(chosen, ContinuationChoice)
    assert (chosen.continuation, chosen.unreached_share, chosen.pilot_frames) == (AUTO_SAMPLES, 0.9, 10)
    assert choose(rows(8)).continuation == 0
    assert choose([]).continuation == 0


def test_analyze_continues_where_the_pilot_reaches_no_success(far_goal: Path, tmp_path: Path) -> None:
    import shutil

    explicit = tmp_path / "explicit"
    shutil.copytree(far_goal, explicit)
    analyze(far_goal, AnalyzerConfig(**SMALL), seed=1, progress=False)
    recorded = _recorded(far_goal)
    # The settings say "the rule" (the same inputs decide the same), the decision sits beside them.
    assert recorded["analyzer"]["continuation"] is None
    assert resolved_continuation(recorded) == AUTO_SAMPLES
    assert recorded["continuation_choice"] == {
        "continuation": AUTO_SAMPLES, "unreached_share": 1.0, "pilot_frames": 4, "threshold": 0.9,
    }  # fmt: skip
    # The scores are those of the continuation asked for by name, to the bit.
    analyze(explicit, AnalyzerConfig(**SMALL, continuation=AUTO_SAMPLES), seed=1, progress=False)
    assert _scores(far_goal) == _scores(explicit)
    assert any(success > 0 for _, success in _scores(far_goal))
    assert resolved_continuation(_recorded(explicit)) == AUTO_SAMPLES and "continuation_choice" not in _recorded(
        explicit
    )


def test_a_resumed_run_keeps_the_recorded_decision_without_a_pilot(far_goal: Path, count_frames: list[int]) -> None:
    analyze(far_goal, AnalyzerConfig(**SMALL), seed=1, progress=False)
    finished = _scores(far_goal)
    (far_goal / "scores.csv").unlink()  # interrupted before scores.csv: the journal holds every row
    count_frames.clear()
    analyze(far_goal, AnalyzerConfig(**SMALL), seed=1, progress=False)
    assert count_frames == [] and _scores(far_goal) == finished
    # A finished run again: found, not refused, nothing grown.
    analyze(far_goal, AnalyzerConfig(**SMALL), seed=1, progress=False)
    assert count_frames == []


def test_where_the_trees_reach_success_the_pilot_rows_are_the_runs_own(copy_dataset, count_frames: list[int]) -> None:  # type: ignore[no-untyped-def]
    auto, plain = copy_dataset("auto"), copy_dataset("plain")
    analyze(auto, AnalyzerConfig(**SMALL), seed=1, progress=False)
    # Every frame grown once: the pilot's four, then the other two.
    assert sorted(count_frames) == list(range(6))
    recorded = _recorded(auto)
    assert resolved_continuation(recorded) == 0
    assert recorded["continuation_choice"]["unreached_share"] < 0.9
    analyze(plain, AnalyzerConfig(**SMALL, continuation=0), seed=1, progress=False)
    assert _scores(auto) == _scores(plain)
    assert "continuation_choice" not in _recorded(plain)


def test_an_engine_that_cannot_continue_runs_no_pilot(tiny_dataset: Path) -> None:
    from energy_margin.analysis.executors import make_executor
    from energy_margin.analysis.run import _resolve_continuation
    from energy_margin.data.dataset import load_dataset

    pytest.importorskip("pybullet")
    config = AnalyzerConfig(**SMALL, engine="pybullet")
    record = tiny_dataset / "analysis.json"  # not read: the engine decides
    resolved, pilot = _resolve_continuation(load_dataset(tiny_dataset), config, 0, make_executor(), record)
    assert (resolved.continuation, pilot) == (0, {})


def test_the_command_line_says_when_the_rule_continues(far_goal: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["analyze", str(far_goal), "--expansions", "10", "--no-progress"]) == 0
    err = capsys.readouterr().err
    notes = [line for line in err.splitlines() if "continuing the motion" in line]
    assert len(notes) == 1 and "100% of the pilot's 4 first-half frames" in notes[0] and "--continuation 0" in notes[0]
    assert "score success 0: their trees end" not in err
    again = ["analyze", str(far_goal), "--expansions", "10", "--continuation", "auto", "--no-progress"]
    assert main(again) == 0
    assert resolved_continuation(_recorded(far_goal)) == AUTO_SAMPLES
    # The tree's own score asked for by name is another analysis: refused without --overwrite.
    assert main(["analyze", str(far_goal), "--expansions", "10", "--continuation", "0", "--no-progress"]) == 2
    assert "continuation" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["analyze", str(far_goal), "--continuation", "some", "--no-progress"])
    assert "expected an integer" in capsys.readouterr().err


def test_protocols_that_compare_analyses_score_success_one_way() -> None:
    from energy_margin.design.scorers import TreeScorer

    assert AnalyzerConfig().continuation is None
    assert AnalyzerConfig().fixed_continuation().continuation == 0
    assert AnalyzerConfig(continuation=8).fixed_continuation().continuation == 8
    # A design search records (and analyses with) the tree's own success score unless told otherwise.
    assert TreeScorer().settings()["analyzer"]["continuation"] == 0


@pytest.mark.parametrize("recorded", [0, "absent"], ids=["given", "earlier-release"])
def test_the_rule_defers_to_an_analysis_whose_continuation_was_given(
    far_goal: Path, count_frames: list[int], recorded: object
) -> None:
    # The tree's own score by name (or by a release before the rule, whose analysis.json has no
    # continuation): analyze at the default finds that analysis finished, it neither refuses nor regrows.
    analyze(far_goal, AnalyzerConfig(**SMALL, continuation=0), seed=1, progress=False)
    if recorded == "absent":
        description = _recorded(far_goal)
        del description["analyzer"]["continuation"]
        (far_goal / "analysis.json").write_text(json.dumps(description))
    finished = _scores(far_goal)
    count_frames.clear()
    analyze(far_goal, AnalyzerConfig(**SMALL), seed=1, progress=False)
    assert count_frames == [] and _scores(far_goal) == finished
    assert resolved_continuation(_recorded(far_goal)) == 0
    # Other settings: another analysis, which the rule decides for (here: it continues).
    analyze(far_goal, AnalyzerConfig(expansions=12), seed=1, progress=False, overwrite=True)
    assert resolved_continuation(_recorded(far_goal)) == AUTO_SAMPLES
