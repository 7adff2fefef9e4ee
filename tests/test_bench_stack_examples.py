"""benchmarks/stack_examples.py: a stack's row from its example's results, and its interpreters."""

from __future__ import annotations

import pytest

from bench_modules import load_benchmark


@pytest.fixture(scope="module")
def bench():
    return load_benchmark("stack_examples")


def _evaluation(margin: float, best: float, word: str) -> dict:
    keys = ("capture_ap", "capture_ap_window2", "success_ap", "success_ap_first_half")
    verdict = {
        "baseline": "current_state",
        "difference": margin - best,
        "low": margin - best - 0.01,
        "high": margin - best + 0.01,
        "word": word,
    }
    return {
        **dict.fromkeys(keys, margin),
        "baselines": {"current_state": dict.fromkeys(keys, best), "chance": dict.fromkeys(keys, 0.5)},
        "verdict": dict.fromkeys(keys, verdict),
    }


def test_a_row_says_the_runs_and_each_questions_verdict_against_its_baseline(bench) -> None:
    results = {
        "mujoco": "3.3.0",
        "episodes": 30,
        "success_rate": 17 / 30,
        "timing": {"mean_ms": 49.0, "mean_expansions": 54.0},
        "evaluate": _evaluation(0.944, 0.917, "ahead"),
    }
    row = bench.row("metaworld", results)
    assert row["stack"] == "metaworld"
    assert (row["mujoco"], row["episodes"], row["succeeded"]) == ("3.3.0", 30, 17)
    assert (row["live_mean_ms"], row["live_mean_expansions"]) == (49.0, 54.0)
    assert row["capture_ap_window2"] == "0.944 (**ahead** +0.027 [+0.017, +0.037]) against 0.917 (current state)"
    found = bench.questions(results)["capture_ap_window2"]
    assert (found["margin"], found["baseline"], found["baseline_ap"], found["word"]) == (
        0.944,
        "current_state",
        0.917,
        "ahead",
    )


def test_examples_that_evaluate_live_scores_too_are_read_from_their_analysis(bench) -> None:
    results = {
        "mujoco": "3.9.0",
        "episodes": [{"success": True}, {"success": False}],
        "success_rate": 0.5,
        "timing": {"mean_ms": 40.0, "mean_expansions": 20.0},
        "evaluate": {"analyze": _evaluation(0.6, 0.5, "ahead"), "live": _evaluation(0.1, 0.5, "behind")},
    }
    row = bench.row("robosuite", results)
    assert (row["episodes"], row["succeeded"]) == (2, 1)
    assert row["capture_ap"].startswith("0.600 (**ahead**")


def test_a_question_without_a_verdict_shows_its_ap_alone(bench) -> None:
    evaluation = _evaluation(0.9, 0.8, "level")
    evaluation["verdict"] = None
    results = {
        "mujoco": "3.8.1",
        "episodes": 6,
        "success_rate": 4 / 6,
        "timing": {"mean_ms": 36.0, "mean_expansions": 7.0},
        "evaluate": evaluation,
    }
    assert bench.row("aloha", results)["success_ap"] == "0.900"


def test_interpreters_default_to_the_stacks_nox_sessions_and_refuse_a_bad_name(bench, tmp_path) -> None:
    found = bench._interpreters([f"robosuite={tmp_path / 'python'}"])
    assert found["robosuite"] == tmp_path / "python"
    assert found["metaworld"].parts[-4:] == (".nox", "stack-metaworld", "bin", "python")
    with pytest.raises(SystemExit, match="NAME=PATH"):
        bench._interpreters(["nothing=/usr/bin/python"])
    with pytest.raises(SystemExit, match="NAME=PATH"):
        bench._interpreters(["robosuite"])


def test_keep_takes_the_other_stacks_entries_with_their_date(bench) -> None:
    previous = {
        "date": "2026-12-06",
        "machine": "m1",
        "stacks": {"metaworld": {"row": {"stack": "metaworld"}}, "robosuite": {"row": {"stack": "robosuite"}}},
    }
    kept = bench.kept_entries(previous, ["robosuite"])
    assert list(kept) == ["metaworld"]
    assert kept["metaworld"] == {"date": "2026-12-06", "machine": "m1", "row": {"stack": "metaworld"}}
    # An entry that has its own date keeps it.
    again = bench.kept_entries({"date": "2026-12-07", "stacks": kept}, [])
    assert again["metaworld"]["date"] == "2026-12-06"
    document = bench._in_order({"robosuite": {"row": {"stack": "robosuite"}}, **kept}, {"date": "d"})
    assert list(document["stacks"]) == ["metaworld", "robosuite"]
    assert [row["stack"] for row in document["rows"]] == ["metaworld", "robosuite"]
