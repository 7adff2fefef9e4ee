"""The default success continuation: 16 draws per frame where the engine continues, else the tree's own.

The tiny scene's pusher carries the boxes into the goal only after about 1.1 s, beyond the reach of
small trees: the tree's own success score is 0 on every early frame, the continued one is not.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from energy_margin.analysis.config import AnalyzerConfig
from energy_margin.analysis.continuation_rule import AUTO_SAMPLES, default_continuation, recorded_choice
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


def test_the_default_continues_on_an_engine_that_can() -> None:
    assert default_continuation("mujoco") == AUTO_SAMPLES
    pytest.importorskip("pybullet")
    assert default_continuation("pybullet") == 0


def test_a_recorded_decision_is_read_from_either_release() -> None:
    assert recorded_choice({"continuation_choice": {"continuation": 16}}) == 16
    # An earlier release's pilot rule recorded its share and threshold beside the decision.
    earlier = {"continuation": 0, "unreached_share": 0.4, "pilot_frames": 25, "threshold": 0.9}
    assert recorded_choice({"continuation_choice": earlier}) == 0
    assert recorded_choice({}) is None and recorded_choice({"continuation_choice": None}) is None


def test_analyze_continues_by_default(far_goal: Path, tmp_path: Path, count_frames: list[int]) -> None:
    import shutil

    explicit = tmp_path / "explicit"
    shutil.copytree(far_goal, explicit)
    analyze(far_goal, AnalyzerConfig(**SMALL), seed=1, progress=False)
    # Every frame grown once, in order: nothing before the run decides.
    assert count_frames == list(range(8))
    recorded = _recorded(far_goal)
    # The settings say "the default", the decision sits beside them.
    assert recorded["analyzer"]["continuation"] is None
    assert resolved_continuation(recorded) == AUTO_SAMPLES
    assert recorded["continuation_choice"] == {"continuation": AUTO_SAMPLES}
    # The scores are those of the continuation asked for by name, to the bit.
    analyze(explicit, AnalyzerConfig(**SMALL, continuation=AUTO_SAMPLES), seed=1, progress=False)
    assert _scores(far_goal) == _scores(explicit)
    assert any(success > 0 for _, success in _scores(far_goal))
    assert resolved_continuation(_recorded(explicit)) == AUTO_SAMPLES and "continuation_choice" not in _recorded(
        explicit
    )


def test_a_resumed_run_keeps_the_recorded_decision(far_goal: Path, count_frames: list[int]) -> None:
    analyze(far_goal, AnalyzerConfig(**SMALL), seed=1, progress=False)
    finished = _scores(far_goal)
    (far_goal / "scores.csv").unlink()  # interrupted before scores.csv: the journal holds every row
    count_frames.clear()
    analyze(far_goal, AnalyzerConfig(**SMALL), seed=1, progress=False)
    assert count_frames == [] and _scores(far_goal) == finished
    # A finished run again: found, not refused, nothing grown.
    analyze(far_goal, AnalyzerConfig(**SMALL), seed=1, progress=False)
    assert count_frames == []


def test_a_run_an_earlier_release_decided_keeps_its_decision(copy_dataset, count_frames: list[int]) -> None:  # type: ignore[no-untyped-def]
    # Begun by the earlier pilot rule, which left the tree's own score, and interrupted: resumed as it was.
    earlier, plain = copy_dataset("earlier"), copy_dataset("plain")
    analyze(earlier, AnalyzerConfig(**SMALL), seed=1, progress=False)
    description = _recorded(earlier)
    description["continuation_choice"] = {
        "continuation": 0,
        "unreached_share": 0.5,
        "pilot_frames": 4,
        "threshold": 0.9,
    }
    (earlier / "analysis.json").write_text(json.dumps(description))
    (earlier / "scores.csv").unlink()
    (earlier / "scores.journal.csv").unlink()
    count_frames.clear()
    analyze(earlier, AnalyzerConfig(**SMALL), seed=1, progress=False)
    assert sorted(count_frames) == list(range(6)) and resolved_continuation(_recorded(earlier)) == 0
    analyze(plain, AnalyzerConfig(**SMALL, continuation=0), seed=1, progress=False)
    assert _scores(earlier) == _scores(plain)
    assert "continuation_choice" not in _recorded(plain)


def test_an_engine_that_cannot_continue_keeps_the_trees_own_score(tiny_dataset: Path) -> None:
    from energy_margin.analysis.run import _resolve_continuation

    pytest.importorskip("pybullet")
    record = tiny_dataset / "analysis.json"
    record.write_text(json.dumps({"analyzer": {"continuation": None}}))
    resolved = _resolve_continuation(AnalyzerConfig(**SMALL, engine="pybullet"), record)
    assert resolved.continuation == 0 and _recorded(tiny_dataset)["continuation_choice"] == {"continuation": 0}


def test_the_command_line_continues_by_default_and_quietly(far_goal: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["analyze", str(far_goal), "--expansions", "10", "--no-progress"]) == 0
    err = capsys.readouterr().err
    # The default is no news: no note on it (the one on unranked early success is for the tree's own score;
    # the scene's unset lambda has its own).
    notes = [line for line in err.splitlines() if line.startswith("note:")]
    assert len(notes) == 1 and "lambda is unset" in notes[0]
    assert resolved_continuation(_recorded(far_goal)) == AUTO_SAMPLES
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
    # Other settings: another analysis, which the default decides for (it continues).
    analyze(far_goal, AnalyzerConfig(expansions=12), seed=1, progress=False, overwrite=True)
    assert resolved_continuation(_recorded(far_goal)) == AUTO_SAMPLES
