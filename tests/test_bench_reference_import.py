"""benchmarks/reference_import.py: the import's constants come from the code, its helpers measure what they say."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from bench_modules import load_benchmark
from energy_margin.data import reference_convert
from energy_margin.tasks import get_task
from energy_margin.tasks.pushing_config import PushingConfig
from energy_margin.tasks.scooping_config import ScoopingConfig

ROOT = Path(__file__).resolve().parents[1]
KEPT = ROOT / "docs/figures/reference_import.json"


@pytest.fixture(scope="module")
def bench() -> ModuleType:
    return load_benchmark("reference_import")


def test_the_constants_are_the_codes(bench: ModuleType) -> None:
    found = bench.constants()
    assert found["reference_convert"]["SCOOP_BLADE_HALF_WIDTH"] == reference_convert.SCOOP_BLADE_HALF_WIDTH
    assert found["reference_convert"]["SCOOP_PRESSED_ZT"] == reference_convert.SCOOP_PRESSED_ZT
    assert set(found["reference_convert"]) == set(reference_convert.__all__)
    assert found["drive_factor_mean"] == pytest.approx(np.mean(PushingConfig().drive_factor))
    config = PushingConfig()
    touching = config.wall_y - config.object_radius
    assert found["push_success_band"] == pytest.approx(
        [touching - config.success_half_width, touching + config.success_half_width]
    )
    assert found["blade_half_widths"][0] == ScoopingConfig().tip_half_width
    assert found["blade_half_widths"][-1] == reference_convert.SCOOP_BLADE_HALF_WIDTH
    # The script is still closing the fingers at their first frame.
    assert 0.0 < found["scoop_script_finger_at_first_frame_cm"] < found["scoop_closed_travel_cm"]


def test_the_file_the_page_quotes_is_that_of_this_code(bench: ModuleType) -> None:
    if not KEPT.is_file():
        pytest.skip(f"{KEPT} is not written yet")
    kept = json.loads(KEPT.read_text(encoding="utf-8"))
    assert kept["constants"] == json.loads(json.dumps(bench.constants()))


def test_agreement_counts_both_sides(bench: ModuleType) -> None:
    ours = np.array([[True, True], [False, True]])
    theirs = np.array([[True, False], [False, True]])
    assert bench.agreement(ours, theirs) == {
        "count": 4,
        "agree": 3,
        "ours_positive": 3,
        "theirs_positive": 2,
        "ours_only": 1,
        "theirs_only": 0,
    }


def test_farthest_offset_looks_at_captured_frames_only(bench: ModuleType) -> None:
    positions = np.zeros((1, 2, 2, 3))
    positions[0, 0, 1, 1] = -0.026  # captured frame, second object
    positions[0, 1, 0, 1] = 0.05  # not captured
    assert bench.farthest_offset(positions, np.array([[True, False]])) == pytest.approx(0.026)
    assert bench.farthest_offset(positions, np.zeros((1, 2), dtype=bool)) == 0.0


def test_base_accelerations_recover_a_constant_acceleration(bench: ModuleType) -> None:
    times = np.tile(0.6 + 0.15 * np.arange(10), (2, 1))
    heights = np.stack([0.1 + 0.02 * times[0] + 0.5 * a * times[0] ** 2 for a in (0.05, 0.14)])
    assert bench.base_accelerations(times, heights) == pytest.approx([0.05, 0.14])


def test_scripted_config_widens_blades_and_drops_the_recorded_motion(bench: ModuleType) -> None:
    config = {**ScoopingConfig().to_dict(), "recorded_waypoints": 10}
    scripted = bench.scripted_config(config, 0.025)
    assert scripted["recorded_waypoints"] == 0
    assert scripted["tip_half_width"] == 0.025
    assert scripted["finger_half_extents"][1] == 0.025
    assert scripted["finger_half_extents"][0] == config["finger_half_extents"][0]
    assert config["tip_half_width"] == ScoopingConfig().tip_half_width  # the input is left alone
    assert get_task("scooping", scripted).config.tip_half_width == 0.025
    assert bench.with_blades(config, 0.03)["recorded_waypoints"] == 10


def test_blade_row_keeps_the_table_columns(bench: ModuleType) -> None:
    evaluated = {
        "capture_ap": 0.9,
        "capture_ap_window2": 0.8,
        "success_ap": 1.0,
        "success_ap_first_half": 0.5,
        "runtime_per_frame_s": 1.2,
        "baselines": {},
    }
    row = bench.blade_row(0.02, "script", evaluated)
    assert row == {
        "blade_half_width_m": 0.02,
        "motion": "script",
        "capture_ap": 0.9,
        "capture_ap_window2": 0.8,
        "success_ap": 1.0,
        "success_ap_first_half": 0.5,
        "runtime_per_frame_s": 1.2,
    }


def test_without_their_data_it_skips(
    bench: ModuleType, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(bench, "REFERENCE_DATA", tmp_path / "absent")
    monkeypatch.setattr(
        sys, "argv", ["reference_import.py", "--work", str(tmp_path), "--out", str(tmp_path / "o.json")]
    )
    bench.main()
    assert capsys.readouterr().out.startswith("skip:")
    assert not (tmp_path / "o.json").exists()


def test_height_label_is_their_capture_test(bench: ModuleType) -> None:
    positions = np.zeros((1, 3, 2, 3))
    velocities = np.zeros((1, 3, 2, 6))
    positions[..., 2] = 0.01  # every box 5 mm above a 5 mm resting height
    positions[0, 1, 0, 2] = 0.006  # one box only 1 mm up
    velocities[0, 2, 1, 2] = -0.02  # one box falling
    label = bench.height_label(positions, velocities, rest=0.005, margin=0.0025, fall=0.01)
    assert label.tolist() == [[True, False, False]]


def test_capture_scores_are_read_by_frame(bench: ModuleType, tmp_path: Path) -> None:
    rows = ["trajectory,frame,capture_score", "0,0,0.5", "0,1,0.25", "1,0,0.0"]
    (tmp_path / bench.SCORES_FILE).write_text("\n".join(rows) + "\n", encoding="utf-8")
    assert bench.capture_scores_at(tmp_path, [[1, 0], [0, 1]]) == [0.0, 0.25]
