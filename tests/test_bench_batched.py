"""benchmarks/bench_batched.py: a tiny run writes its rows, one per setting, with B = 1 as the reference."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from bench_modules import load_benchmark


@pytest.fixture(scope="module")
def bench():
    return load_benchmark("bench_batched")


def test_a_tiny_run_writes_every_setting(bench, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    out = tmp_path / "batched.json"
    argv = ["bench_batched.py", "--objects", "2", "--expansions", "10", "--batches", "4", "--threads", "1"]
    argv += ["--trajectories", "1", "--frames", "2", "--methods", "--out", str(out)]
    monkeypatch.setattr(sys, "argv", argv)
    bench.main()
    written = json.loads(out.read_text(encoding="utf-8"))
    settings = [(row["method"], row["batch"], row["threads"]) for row in written["rows"]]
    assert settings == [("est", 1, 1), ("est", 4, 1)]
    assert written["rows"][0]["speedup"] == pytest.approx(1.0)
    assert written["frames"] == 2
    assert all(row["per_frame_s"] > 0.0 for row in written["rows"])
