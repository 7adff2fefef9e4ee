"""benchmarks/learned_margin.py: the table's cells from the comparison rows."""

from __future__ import annotations

from bench_modules import load_benchmark


def test_cells_give_learned_tree_and_the_paired_interval_or_a_dash() -> None:
    bench = load_benchmark("learned_margin")
    entry = {"learned": 0.99, "tree": 0.988, "difference": 0.002, "low": -0.004, "high": 0.009}
    assert bench.cell(entry) == "0.990 / 0.988 (+0.002 [-0.004, +0.009])"
    assert bench.cell({**entry, "low": None, "high": None}) == "0.990 / 0.988"
    assert bench.cell({**entry, "learned": None}) == "–"
    assert bench.cell(None) == "–"


def test_a_table_row_per_set_and_model_with_every_question() -> None:
    bench = load_benchmark("learned_margin")
    entry = {"learned": 1.0, "tree": 1.0, "difference": 0.0, "low": 0.0, "high": 0.0}
    row = {"set": "push5c", "kind": "set", "questions": {"capture k̂=0": entry}, "r2_capture": 0.87, "r2_success": None}
    (table,) = bench.table_rows([row])
    assert table["set"] == "push5c" and table["model"] == "set" and table["r2"] == "0.870 / –"
    assert table["q0"].startswith("1.000 / 1.000") and table["q1"] == "–"
    assert len([key for key in table if key.startswith("q")]) == 6


def test_every_study_fits_on_sets_learn_writes_and_scores_sets_of_other_seeds() -> None:
    bench = load_benchmark("learned_margin")
    for name, study in bench.STUDIES.items():
        learn_seed = study.learn[study.learn.index("--seed") + 1]
        for _, source in study.tests:
            assert source[source.index("--seed") + 1] != learn_seed, name
        assert all(part.startswith(("objects-", "scene")) for part in study.sets), name
    assert [name for name, study in bench.STUDIES.items() if study.speed] == ["pushing"]
