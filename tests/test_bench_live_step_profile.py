"""benchmarks/live_step_profile.py: its account of a live call's time, on Gymnasium's Pusher."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import mujoco
import pytest

from bench_modules import load_benchmark

pytest.importorskip("gymnasium")


def _timers_record_durations() -> bool:
    model = mujoco.MjModel.from_xml_string(
        "<mujoco><worldbody><body><freejoint/><geom size='.1'/></body></worldbody></mujoco>"
    )
    data = mujoco.MjData(model)
    mujoco.mj_step(model, data, 50)
    return data.timer[mujoco.mjtTimer.mjTIMER_STEP].duration > 0.0


def test_the_account_of_a_live_call_adds_up(tmp_path: Path) -> None:
    bench = load_benchmark("live_step_profile")
    args = argparse.Namespace(stack="pusher", steps=3, budget=0.02, seed=0)
    row = bench.profile(args, tmp_path)
    assert row["stack"] == "pusher" and row["calls"] == 3
    # Pusher-v5 steps its model at 10 ms and a propagation lasts up to the scene's 0.1 s: between
    # one and ten physics steps per expansion.
    assert row["timestep"] == pytest.approx(0.01)
    assert 1.0 <= row["steps_per_expansion"] <= 10.0
    assert row["us_per_step"] > 0.0
    # Stepping is part of each call, and the stages MuJoCo times are part of each step (where this
    # MuJoCo records their durations; MuJoCo 3.3.0 counts them only).
    assert 0.0 < row["physics_share"] < 1.0
    if _timers_record_durations():
        assert 0.0 < row["collision_share"] < 1.0 and 0.0 < row["constraint_share"] < 1.0
        assert row["collision_share"] + row["constraint_share"] < 1.0
    else:
        assert row["collision_share"] is None and row["constraint_share"] is None
    # Nothing costs less than its physics: the calls reached no more expansions than the ceiling.
    assert row["expansions_median"] <= row["physics_ceiling"]
    assert row["other_ms_per_expansion"] > 0.0


def test_the_results_file_keeps_one_row_per_stack(tmp_path: Path) -> None:
    bench = load_benchmark("live_step_profile")
    path = tmp_path / "profile.json"
    bench.write_row(path, {"stack": "robosuite", "run": 1})
    bench.write_row(path, {"stack": "metaworld", "run": 1})
    bench.write_row(path, {"stack": "robosuite", "run": 2})
    rows = json.loads(path.read_text())["rows"]
    assert rows == [{"stack": "metaworld", "run": 1}, {"stack": "robosuite", "run": 2}]
