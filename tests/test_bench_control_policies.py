"""benchmarks/control_policies.py: the cells, their table rows and the comparisons within a group."""

from __future__ import annotations

from typing import Any

from bench_modules import load_benchmark


def _entry(source: str, policy: str, successes: int, *, model: str | None = None) -> dict[str, Any]:
    from energy_margin.evaluation.statistics import wilson_interval

    return {
        "source": source, "objects": 5, "disturbance": "hard", "policy": policy, "model": model,
        "summary": {
            "n_objects": 5, "episodes": 100, "success_rate": successes / 100,
            "success_interval": list(wilson_interval(successes, 100)),
            "captured_fraction": 0.8, "mean_capture_score": 0.75,
        },
    }  # fmt: skip


def test_every_cell_is_named_once_and_every_learned_cell_has_a_model() -> None:
    bench = load_benchmark("control_policies")
    names = [bench.cell_name(*cell) for cell in bench.CELLS]
    assert len(set(names)) == len(names)
    assert bench.cell_name("pushing", 5, "hard", "learned", "push_set") == "pushing5-hard-learned-push_set"
    for source, _, _, policy, model in bench.CELLS:
        assert (policy == "learned") == (model is not None)
        assert model is None or model in bench.MODELS
        assert model != "scoop5-boosting" or source == "scooping"


def test_rows_follow_the_cells_order_and_name_the_set_network() -> None:
    bench = load_benchmark("control_policies")
    cells = {
        "pushing5-hard-learned-push_set": _entry("pushing", "learned", 91, model="push_set"),
        "pushing5-hard-scripted": _entry("pushing", "scripted", 61),
    }
    rows = bench.table_rows(cells)
    assert [row["policy"] for row in rows] == ["`scripted`", "`learned`, set network"]
    assert rows[1]["success"] == 0.91 and rows[1]["low"] < 0.91 < rows[1]["high"]


def test_a_comparison_is_significant_only_when_the_intervals_are_apart() -> None:
    bench = load_benchmark("control_policies")
    cells = {
        "pushing5-hard-scripted": _entry("pushing", "scripted", 61),
        "pushing5-hard-task": _entry("pushing", "task", 65),
        "pushing5-hard-margin": _entry("pushing", "margin", 90),
    }
    found = {(row["policy"], row["against"]): row for row in bench.comparisons(cells)}
    assert set(found) == {("`task`", "`scripted`"), ("`margin`", "`scripted`"), ("`margin`", "`task`")}
    assert found["`task`", "`scripted`"]["verdict"] == "intervals overlap"
    assert found["`margin`", "`scripted`"]["verdict"] == "significant"
    assert abs(found["`margin`", "`task`"]["difference"] - 0.25) < 1e-12
