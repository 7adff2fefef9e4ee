"""benchmarks/branch_studies.py: the studies' settings and the blades the design search chose."""

from __future__ import annotations

from bench_modules import load_benchmark


def test_small_changes_are_a_hundredth_of_the_controllers_and_ask_only_the_task_cost() -> None:
    bench = load_benchmark("branch_studies")
    default = bench.STUDIES["scooping"].noise
    for name, study in bench.STUDIES.items():
        assert study.task in bench.TIMES and len(bench.TIMES[study.task]) == 8, name
        if name.endswith(("_small", "_small_undisturbed", "_small_blades")):
            assert study.noise * 100 == default and study.scores == ("task",), name
        assert set(study.scores) <= {"task", "margin", "learned", "oracle_state", "oracle_friction"}, name


def test_the_blades_are_the_first_verified_designs_task_settings() -> None:
    bench = load_benchmark("branch_studies")
    design = {"verified": [{"task_config": {"scoop_angle": 1.1, "tip_length": 0.04}}, {"task_config": {}}]}
    assert bench.chosen_blades(design) == {"scoop_angle": 1.1, "tip_length": 0.04}
    assert bench.STUDIES["scooping_small_blades"].blades
