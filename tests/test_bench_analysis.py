"""benchmarks/bench_analysis.py: its results file gathers the rows of several settings, run by run."""

from __future__ import annotations

import json
from pathlib import Path

from bench_modules import load_benchmark


def test_a_settings_rows_replace_its_earlier_rows_only(tmp_path: Path) -> None:
    bench = load_benchmark("bench_analysis")
    path = tmp_path / "analysis.json"
    bench.write_rows(
        path, "default", [{"label": "default", "n_objects": 1}, {"label": "default", "n_objects": 3}], {"run": 1}
    )
    bench.write_rows(path, "240 Hz", [{"label": "240 Hz", "n_objects": 10}], {"run": 1})
    bench.write_rows(path, "default", [{"label": "default", "n_objects": 10}], {"run": 2})
    kept = json.loads(path.read_text())
    assert kept["rows"] == [{"label": "240 Hz", "n_objects": 10}, {"label": "default", "n_objects": 10}]
    assert kept["runs"] == {"default": {"run": 2}, "240 Hz": {"run": 1}}
