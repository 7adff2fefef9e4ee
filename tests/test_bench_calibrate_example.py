"""benchmarks/calibrate_example.py: each run is a fresh ``calibrate``, and a failing one stops the benchmark."""

from __future__ import annotations

from pathlib import Path

import pytest

from bench_modules import load_benchmark


def test_a_failing_calibrate_stops_with_its_error_and_leaves_no_earlier_run(tmp_path: Path) -> None:
    bench = load_benchmark("calibrate_example")
    out = tmp_path / "run"
    out.mkdir()
    (out / "stale.txt").write_text("an earlier run")
    with pytest.raises(SystemExit, match=r"(?s)calibrate .* failed:.*not_a_dataset"):
        bench.calibrate(tmp_path / "not_a_dataset", out, bench.RUNS["grow"], workers=1, seed=0)
    assert not (out / "stale.txt").exists()
