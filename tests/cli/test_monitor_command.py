from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import pytest

from energy_margin.cli.app import main
from energy_margin.data.dataset import load_dataset
from energy_margin.data.scores_file import SCORES_FILE
from energy_margin.evaluation.monitor import load_calibration


@pytest.fixture
def analysed(copy_dataset: Callable[[str], Path]) -> tuple[Path, Path]:
    """Two analysed copies of the tiny real dataset: one calibrates, the other is tested."""
    calibration, test = copy_dataset("calib"), copy_dataset("test")
    for path in (calibration, test):
        assert main(["analyze", str(path), "--iterations", "5", "--no-progress"]) == 0
    return calibration, test


def test_monitor_end_to_end(analysed: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    calibration, test = analysed
    successes = int(load_dataset(calibration).success_labels().sum())
    assert successes >= 1  # alpha 0.5 needs one
    saved = tmp_path / "alarm.json"
    capsys.readouterr()
    argv = ["monitor", str(calibration), str(test), "--alpha", "0.5", "--resamples", "20"]
    assert main([*argv, "--json", "--save", str(saved)]) == 0
    result = json.loads(capsys.readouterr().out)
    assert [entry["scorer"] for entry in result["evaluations"]] == ["margin", "distance"]
    assert result["calibrations"][0]["n_successes"] == successes
    assert result["calibration_seed"] == result["test_seed"] == 0
    loaded = load_calibration(saved)
    assert loaded.scorer == "margin" and loaded.threshold == result["calibrations"][0]["threshold"]
    assert main(["monitor", str(calibration), str(test), "--alpha", "0.5", "--resamples", "20"]) == 0
    assert "false alarms" in capsys.readouterr().out


def test_too_few_successes_is_one_line(analysed: tuple[Path, Path], capsys: pytest.CaptureFixture[str]) -> None:
    calibration, test = analysed
    capsys.readouterr()
    assert main(["monitor", str(calibration), str(test), "--alpha", "0.05"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert err.startswith("energy-margin: error: --alpha 0.05 needs at least 19 successful calibration roll-outs")
    assert "Traceback" not in err


def test_a_dataset_without_scores_is_one_line(tiny_dataset: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["monitor", str(tiny_dataset), str(tiny_dataset)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "scores.csv" in err


def test_persistence_is_recorded_and_checked(
    analysed: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    calibration, test = analysed
    frames = load_dataset(calibration).n_frames
    saved = tmp_path / "alarm.json"
    argv = ["monitor", str(calibration), str(test), "--alpha", "0.5", "--resamples", "20"]
    capsys.readouterr()
    assert main([*argv, "--persistence", "2", "--json", "--save", str(saved)]) == 0
    result = json.loads(capsys.readouterr().out)
    assert [entry["persistence"] for entry in result["evaluations"]] == [2, 2]
    assert load_calibration(saved).persistence == 2
    assert main([*argv, "--persistence", str(frames + 1)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("energy-margin: error: --persistence")


def test_select_chooses_on_a_third_set(
    analysed: tuple[Path, Path], copy_dataset: Callable[[str], Path], capsys: pytest.CaptureFixture[str]
) -> None:
    calibration, test = analysed
    selection = copy_dataset("select")
    assert main(["analyze", str(selection), "--iterations", "5", "--no-progress"]) == 0
    capsys.readouterr()
    argv = ["monitor", str(calibration), str(test), "--alpha", "0.5", "--resamples", "20", "--select", str(selection)]
    assert main([*argv, "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert [choice["selection_dataset"] for choice in result["choices"]] == [str(selection)] * 2
    for choice, found in zip(result["choices"], result["evaluations"], strict=True):
        assert (found["score"], found["start_frame"], found["persistence"]) == (
            choice["score"],
            choice["start_frame"],
            choice["persistence"],
        )
    assert main([*argv[:-1], str(selection.parent / "absent")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "absent" in err
    assert main([*argv[:-1], str(calibration)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("energy-margin: error: --select is the calibration set")


def test_a_capture_alarm_watches_the_trees_own_capture_and_old_gated_files_get_a_note(
    analysed: tuple[Path, Path], copy_dataset: Callable[[str], Path], capsys: pytest.CaptureFixture[str]
) -> None:
    calibration, test = analysed  # analysed at the defaults: capture gated
    ungated = copy_dataset("ungated")
    assert main(["analyze", str(ungated), "--iterations", "5", "--no-progress", "--capture-gate", "none"]) == 0
    argv = ["--alpha", "0.5", "--resamples", "20", "--score", "capture", "--json"]
    thresholds = []
    for directory in (calibration, ungated):
        capsys.readouterr()
        assert main(["monitor", str(directory), str(test), *argv]) == 0
        out, err = capsys.readouterr()
        assert err == ""
        thresholds.append(json.loads(out)["calibrations"][0]["threshold"])
    assert thresholds[0] == thresholds[1]  # the gate leaves the alarm's score alone
    # A gated scores file written before the tree's own capture score was kept: a note.
    scores = calibration / SCORES_FILE
    scores.write_text("".join(line.rsplit(",", 1)[0] + "\n" for line in scores.read_text().splitlines()))
    assert main(["monitor", str(calibration), str(test), *argv]) == 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "watches capture" in err and "--overwrite" in err
    assert main(["monitor", str(calibration), str(test), *argv[:4], "--score", "success"]) == 0
    assert capsys.readouterr().err == ""
