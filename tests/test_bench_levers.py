"""benchmarks/bench_levers.py: every variant's time and score changes against the default's, paired by frame."""

from __future__ import annotations

import pytest

from bench_modules import load_benchmark


def test_variants_time_and_score_changes_are_against_the_defaults_on_the_same_frames() -> None:
    bench = load_benchmark("bench_levers")
    rows = {
        "default": [
            {"cpu_s": 0.2, "expansions": 300, "capture": 0.5, "success": 0.1},
            {"cpu_s": 0.4, "expansions": 300, "capture": 0.9, "success": 0.0},
        ],
        "fast": [
            {"cpu_s": 0.1, "expansions": 300, "capture": 0.6, "success": 0.1},
            {"cpu_s": 0.2, "expansions": 300, "capture": 0.9, "success": 0.3},
        ],
    }
    default, fast = bench.summarise(rows)
    assert default["ratio"] == 1.0 and default["capture_change_max"] == 0.0
    assert fast["ratio"] == pytest.approx(0.5)
    assert fast["capture_change_max"] == pytest.approx(0.1) and fast["capture_change_mean"] == pytest.approx(0.05)
    assert fast["success_change_max"] == pytest.approx(0.3)
    assert fast["title"] == bench.VARIANTS["fast"].title


def test_every_variant_changes_one_kind_of_setting_and_the_default_none() -> None:
    bench = load_benchmark("bench_levers")
    assert not any(vars(bench.VARIANTS["default"]).get(kind) for kind in ("task", "analyzer", "options"))
    for name, variant in bench.VARIANTS.items():
        if name != "default":
            assert sum(bool(part) for part in (variant.task, variant.analyzer, variant.options)) == 1, name
