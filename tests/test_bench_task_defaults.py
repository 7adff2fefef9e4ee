"""benchmarks/task_defaults.py: the pages' task constants come from the code's own defaults."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

from bench_modules import load_benchmark
from energy_margin.data import reference_convert
from energy_margin.tasks.pushing_config import PushingConfig
from energy_margin.tasks.scooping_config import ScoopingConfig

ROOT = Path(__file__).resolve().parents[1]


def test_the_dump_holds_every_default_and_import_constant() -> None:
    found = load_benchmark("task_defaults").defaults(ROOT)
    assert found["pushing"]["object_radius"] == PushingConfig().object_radius
    assert found["pushing"]["friction_range"] == list(PushingConfig().friction_range)
    assert found["scooping"]["scoop_angle"] == ScoopingConfig().scoop_angle
    assert found["reference_import"]["SCOOP_PRESSED_ZT"] == reference_convert.SCOOP_PRESSED_ZT
    assert set(found["pushing"]) == {field.name for field in dataclasses.fields(PushingConfig)}
    assert set(found["scooping"]) == {field.name for field in dataclasses.fields(ScoopingConfig)}


def test_the_file_the_pages_quote_is_that_of_this_code() -> None:
    kept = json.loads((ROOT / "docs/figures/task_defaults.json").read_text(encoding="utf-8"))
    found = load_benchmark("task_defaults").defaults(ROOT)
    for part in ("pushing", "scooping", "reference_import"):
        assert kept[part] == json.loads(json.dumps(found[part])), part
