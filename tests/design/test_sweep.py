from __future__ import annotations

import csv
import json
import shutil
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.scores import trajectory_success_score
from energy_margin.cli import main
from energy_margin.data.dataset import load_dataset
from energy_margin.data.scores_file import JOURNAL_FILE, SCORES_FILE, load_scores
from energy_margin.design.params import parse_param
from energy_margin.design.sweep import (
    DESIGNS_DIR,
    SweepDisplay,
    design_grid,
    design_sweep,
    format_table,
    rank_convergence,
    rank_correlations,
)
from energy_margin.design.sweep_results import SweepResult
from energy_margin.errors import EnergyMarginError
from energy_margin.evaluation.statistics import wilson_interval
from energy_margin.runs.lock import LOCK_FILE
from energy_margin.tasks import get_task

# The smallest sweep: 2 pusher widths, 2 trajectories of 2 frames, 2 cylinders, 8 expansions a frame.
TINY = {"n_trajectories": 2, "n_frames": 2, "n_objects": 2, "seed": 3, "bootstrap": 20, "subsets": 5}
PARAMS = [("pusher_width", [0.6, 0.8])]


def _sweep(out: Path, *, workers: int = 1, log: list[str] | None = None) -> dict:
    lines = log if log is not None else []
    results = design_sweep(
        "pushing", PARAMS, out=out, workers=workers, analyzer=AnalyzerConfig(expansions=8), log=lines.append, **TINY
    )
    assert isinstance(results, SweepResult)
    return results.to_dict()


@pytest.fixture(scope="module")
def tiny_sweep(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict, list[str]]:
    out = tmp_path_factory.mktemp("sweep") / "push"
    log: list[str] = []
    return out, _sweep(out, log=log), log


def test_parse_param() -> None:
    assert parse_param("scoop_angle=1.2,1.31") == ("scoop_angle", [1.2, 1.31])
    assert parse_param("friction_range=[0.1,0.2],[0.3,0.4]") == ("friction_range", [[0.1, 0.2], [0.3, 0.4]])
    for text, message in (
        ("scoop_angle", "expects NAME=LOW:HIGH or NAME=A,B,C"),
        ("=1,2", "expects NAME=LOW:HIGH or NAME=A,B,C"),
        ("scoop_angle=1,,2", "neither a range"),
        ("scoop_angle=abc", "neither a range"),
        ("scoop_angle=", "no values"),
        ("scoop_angle=1,1.0", "listed twice"),
    ):
        with pytest.raises(EnergyMarginError, match=message):
            parse_param(text)


def test_design_grid_is_the_product_with_aliases() -> None:
    designs = design_grid(get_task("scooping"), [("scoop_angle", [1.2, 1.4]), ("finger_stiffness", [200, 800, 1600])])
    assert len(designs) == 6
    assert [d.values for d in designs[:2]] == [
        {"scoop_angle": 1.2, "finger_stiffness": 200},
        {"scoop_angle": 1.2, "finger_stiffness": 800},
    ]
    assert designs[1].overrides == {"scoop_angle": 1.2, "stiffness_range": [800, 800]}
    assert designs[1].slug == "scoop_angle-1.2__finger_stiffness-800"
    assert len({d.slug for d in designs}) == 6
    (push,) = design_grid(get_task("pushing"), [("pusher_width", [0.6])], fixed={"pusher_mass": 3.0})
    assert push.overrides == {"pusher_mass": 3.0, "pusher_half_extents": [0.3, 0.1, 0.015]}


@pytest.mark.parametrize(
    ("task", "params", "fixed", "message"),
    [
        ("pushing", [("scoop_angle", [1.0])], {}, "is a setting of task 'scooping', not of 'pushing'"),
        ("scooping", [("pusher_width", [0.5])], {}, "is a setting of task 'pushing', not of 'scooping'"),
        ("scooping", [("tip_angle", [1.0])], {}, "tip_angle: unknown scooping parameter"),
        (
            "scooping",
            [("finger_stiffness", [0, 100])],
            {},
            "design finger_stiffness=0: .*stiffness_range must be a \\(low, high\\) pair of finite numbers > 0",
        ),
        ("scooping", [("open_gap", ["wide"])], {}, 'design open_gap="wide": .*open_gap must be a number'),
        (
            "pushing",
            [("pusher_width", [0.5])],
            {"pusher_half_extents": [0.3, 0.1, 0.01]},
            "which is fixed for every design",
        ),
        ("scooping", [("finger_stiffness", [100]), ("stiffness_range", [[1, 2]])], {}, "as finger_stiffness does"),
        ("scooping", [], {}, "at least one parameter"),
    ],
)
def test_design_grid_errors(task: str, params: list, fixed: dict, message: str) -> None:
    with pytest.raises(EnergyMarginError, match=message):
        design_grid(get_task(task), params, fixed=fixed)


@pytest.mark.parametrize(
    "argv",
    [
        ["--task", "pushing", "--param", "scoop_angle=1,2"],
        ["--task", "scooping", "--param", "scoop_angle=1,,2"],
        ["--task", "scooping", "--param", "nonsense=1"],
        ["--task", "scooping", "--param", "scoop_angle=1", "--param", "scoop_angle=2"],
        ["--task", "scooping", "--param", "scoop_angle=1,2"],  # no --objects
        ["--task", "pushing", "--param", "pusher_width=0.5", "--trajectories", "1", "--objects", "2"],
    ],
)
def test_cli_bad_input_is_one_line(argv: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "sweep"
    full = ["sweep", *argv, "--out", str(out)]
    if "--trajectories" not in argv:
        full += ["--trajectories", "2"]
    code = main(full)
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and err.startswith("energy-margin: error: "), err
    assert not out.exists()  # nothing written before the input is known to be good


def test_tiny_sweep_table(tiny_sweep: tuple[Path, dict, list[str]]) -> None:
    out, results, log = tiny_sweep
    rows = results["rows"]
    assert [row["pusher_width"] for row in rows] == [0.6, 0.8]
    assert len(log) == 2 and log[0].startswith("sweep [1/2] pusher_width=0.6: success ")
    for row in rows:
        directory = out / DESIGNS_DIR / row["design"]
        dataset = load_dataset(directory)
        labels = dataset.success_labels()
        assert row["trajectories"] == 2 and row["successes"] == int(labels.sum())
        assert row["success_rate"] == labels.mean()
        assert (row["success_rate_low"], row["success_rate_high"]) == wilson_interval(int(labels.sum()), 2)
        # The margins, recomputed from the design's scores.csv.
        scores = load_scores(directory)
        order = np.lexsort((scores["frame"], scores["trajectory"]))
        success = scores["success_score"][order].reshape(2, 2)
        capture = scores["capture_score"][order].reshape(2, 2)
        assert row["capture_score"] == pytest.approx(capture.mean())
        assert row["success_score"] == pytest.approx(success.mean())
        assert row["early_success_score"] == pytest.approx(trajectory_success_score(success[:, :1], last=3).mean())
        assert dataset.metadata["task_config"]["pusher_half_extents"] == [row["pusher_width"] / 2, 0.1, 0.015]
    # Common random numbers: every design's trajectory i starts from the same draws.
    first, second = (load_dataset(out / DESIGNS_DIR / row["design"]).arrays for row in rows)
    assert np.array_equal(first["friction"], second["friction"]) and np.array_equal(first["drive"], second["drive"])
    assert np.array_equal(first["object_pos"][:, 0], second["object_pos"][:, 0])
    # Files: the table (CSV, JSON), the settings and the plot.
    with (out / "results.csv").open() as stream:
        table = list(csv.DictReader(stream))
    assert [float(r["success_rate"]) for r in table] == [row["success_rate"] for row in rows]
    assert json.loads((out / "results.json").read_text())["rows"] == rows
    settings = json.loads((out / "sweep.json").read_text())
    assert settings["designs"][0]["task_config"] == {"pusher_half_extents": [0.3, 0.1, 0.015]}
    assert settings["seed"] == 3 and settings["analyzer"]["expansions"] == 8
    assert (out / "results.png").stat().st_size > 0
    assert set(results["correlations"]) == {"early_success_score", "success_score", "capture_score"}
    assert [row["trajectories"] for row in results["convergence"]] == [1, 2]
    text = format_table(results)
    assert "Spearman rank correlation" in text and "0.6" in text


def test_rank_statistics_on_known_outcomes() -> None:
    from energy_margin.design.sweep import DesignOutcome

    def outcome(success: list[int], margin: list[float]) -> DesignOutcome:
        values = np.array(margin)
        return DesignOutcome(np.array(success, bool), values, values, values, 0.0)

    # Four designs whose margins order them as their success rates do (0/4, 1/4, 3/4, 4/4).
    outcomes = [
        outcome([0, 0, 0, 0], [0.1, 0.1, 0.2, 0.0]),
        outcome([1, 0, 0, 0], [0.3, 0.2, 0.2, 0.1]),
        outcome([1, 1, 0, 1], [0.6, 0.5, 0.4, 0.6]),
        outcome([1, 1, 1, 1], [0.9, 0.8, 0.9, 0.7]),
    ]
    correlations = rank_correlations(outcomes, bootstrap=50)
    assert correlations["early_success_score"]["rho"] == pytest.approx(1.0)
    assert correlations["early_success_score"]["p_value"] == pytest.approx(2 / 24)
    convergence = rank_convergence(outcomes, [1, 4], subsets=30)
    assert convergence[-1]["success_rate"] == pytest.approx(1.0) and convergence[-1]["subsets"] == 1
    assert convergence[0]["subsets"] == 30 and convergence[0]["early_success_score"] > 0.7
    # Two designs, [1, 0] and [1, 1] successful: one trajectory of index 0 ties them (rho counts as 0),
    # index 1 orders them (rho = 1); constant margins never rank them (None).
    pair = [outcome([1, 0], [0.5, 0.5]), outcome([1, 1], [0.5, 0.5])]
    (single,) = rank_convergence(pair, [1], subsets=200)
    assert 0 < single["success_rate_defined"] < 200
    assert single["success_rate"] == pytest.approx(single["success_rate_defined"] / 200)
    assert single["early_success_score"] is None and single["early_success_score_defined"] == 0


@pytest.mark.slow
def test_sweep_resumes_and_is_deterministic(tiny_sweep: tuple[Path, dict, list[str]], tmp_path: Path) -> None:
    out, results, _ = tiny_sweep
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    finished = copy / DESIGNS_DIR / results["rows"][0]["design"]
    partial = copy / DESIGNS_DIR / results["rows"][1]["design"]
    finished_scores = (finished / SCORES_FILE).read_bytes()
    # Interrupt the second design after one analysed frame: its journal keeps that frame only.
    (partial / SCORES_FILE).unlink()
    journal = (partial / JOURNAL_FILE).read_text().splitlines(keepends=True)
    (partial / JOURNAL_FILE).write_text("".join(journal[:2]))
    log: list[str] = []
    again = _sweep(copy, log=log)
    assert log[0].endswith("(already analysed)") and not log[1].endswith("(already analysed)")
    assert (finished / SCORES_FILE).read_bytes() == finished_scores
    assert again["rows"][0] == results["rows"][0]
    assert [r["success_rate"] for r in again["rows"]] == [r["success_rate"] for r in results["rows"]]
    for name in ("capture_score", "success_score", "early_success_score"):
        assert [r[name] for r in again["rows"]] == [r[name] for r in results["rows"]]
    # The same seed with two workers in a fresh directory: identical table.
    fresh = _sweep(tmp_path / "fresh", workers=2)
    for name in ("success_rate", "capture_score", "success_score", "early_success_score"):
        assert [r[name] for r in fresh["rows"]] == [r[name] for r in results["rows"]]
    assert fresh["correlations"] == results["correlations"]
    # Other settings in the same directory are refused.
    with pytest.raises(EnergyMarginError, match=r"holds a sweep of other settings .*n_trajectories"):
        design_sweep("pushing", PARAMS, out=copy, **{**TINY, "n_trajectories": 3})


def test_cli_prints_the_table_of_a_finished_sweep(
    tiny_sweep: tuple[Path, dict, list[str]], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out, results, _ = tiny_sweep
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    argv = ["sweep", "--task", "pushing", "--param", "pusher_width=0.6,0.8", "--trajectories", "2", "--frames", "2"]
    code = main([*argv, "--objects", "2", "--seed", "3", "--expansions", "8", "--out", str(copy), "--bootstrap", "20"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    lines = captured.out.splitlines()
    assert lines[0].split()[:3] == ["pusher_width", "success", "rate"]
    for line, row in zip(lines[2:4], results["rows"], strict=True):
        assert line.split()[:2] == [json.dumps(row["pusher_width"]), f"{row['successes']}/2"]
    assert captured.err.count("(already analysed)") == 2


def test_a_design_that_cannot_be_generated_is_reported_and_skipped(tmp_path: Path) -> None:
    # Two cylinders cannot be placed 5 m apart in the 0.6 m spawn band: that design fails, the other runs.
    log: list[str] = []
    results = design_sweep(
        "pushing",
        [("min_separation", [0.1, 5.0])],
        out=tmp_path / "sweep",
        analyzer=AnalyzerConfig(expansions=4),
        log=log.append,
        **{**TINY, "n_frames": 1},
    ).to_dict()
    assert [row["min_separation"] for row in results["rows"]] == [0.1]
    (failed,) = results["failed"]
    assert failed["min_separation"] == 5.0 and "cannot place 2 objects 5.0 m apart" in failed["error"]
    assert "successes" not in failed  # no roll-outs were written
    assert "not analysed: cannot generate pushing trajectories" in log[1]
    assert "correlations" not in results  # one analysed design ranks nothing
    assert not (tmp_path / "sweep" / DESIGNS_DIR / "min_separation-5.0").exists()
    with (tmp_path / "sweep" / "results.csv").open() as stream:
        table = list(csv.DictReader(stream))
    assert [r["error"] != "" for r in table] == [False, True]
    assert "not analysed" in format_table(results)


# A process that holds the writer's lock of a directory until it is killed.
HOLD = """
import sys, time
from energy_margin.runs.lock import RunLock
lock = RunLock(sys.argv[1]).acquire()
print("held", flush=True)
time.sleep(60)
"""
# A process that tries to take the lock and says whether it could.
PROBE = """
import sys
from energy_margin.runs.lock import RunLock, RunLockedError
try:
    RunLock(sys.argv[1]).acquire()
except RunLockedError as error:
    print("refused:", error)
else:
    print("taken")
"""
CLI_TINY = ["--trajectories", "2", "--frames", "2", "--objects", "2", "--seed", "3", "--expansions", "8"]


def _cli(out: Path, *extra: str) -> int:
    argv = ["sweep", "--task", "pushing", "--param", "pusher_width=0.6,0.8", *CLI_TINY, "--bootstrap", "20"]
    return main([*argv, "--out", str(out), *extra])


def test_a_second_writer_is_refused_in_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "sweep"
    out.mkdir()
    holder = subprocess.Popen([sys.executable, "-c", HOLD, str(out)], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "held"
        code = _cli(out)
        err = capsys.readouterr().err
        assert code == 2 and err.count("\n") == 1, err
        assert f"is being written by process {holder.pid} on {socket.gethostname()}" in err
        assert sorted(path.name for path in out.iterdir()) == [LOCK_FILE]  # nothing written
    finally:
        holder.kill()
        holder.wait()


def test_the_sweep_holds_its_lock_until_it_returns(tmp_path: Path) -> None:
    out = tmp_path / "sweep"
    probes: list[str] = []

    def probe(line: str) -> None:
        del line
        result = subprocess.run([sys.executable, "-c", PROBE, str(out)], capture_output=True, text=True, check=True)
        probes.append(result.stdout.strip())

    design_sweep(
        "pushing", PARAMS, out=out, analyzer=AnalyzerConfig(expansions=4), log=probe, **{**TINY, "n_frames": 1}
    )
    assert len(probes) == 2 and all(p.startswith("refused:") and "is being written by" in p for p in probes), probes
    assert not (out / LOCK_FILE).exists()  # released at the end
    probe("after the sweep")
    assert probes[-1] == "taken"


def test_overwrite_replaces_a_sweep_of_other_settings_and_nothing_else(
    tiny_sweep: tuple[Path, dict, list[str]], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out, results, _ = tiny_sweep
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    (copy / "notes.txt").write_text("mine")
    stale = copy / DESIGNS_DIR / "pusher_width-1.5"
    stale.mkdir()
    argv = ["sweep", "--task", "pushing", "--param", "pusher_width=0.6,0.8", "--trajectories", "2", "--frames", "1"]
    argv += ["--objects", "2", "--seed", "3", "--expansions", "4", "--bootstrap", "20", "--out", str(copy)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "holds a sweep of other settings (n_frames: 2 there, 1 now)" in err
    assert "--overwrite" in err
    assert main([*argv, "--overwrite"]) == 0, capsys.readouterr().err
    assert (copy / "notes.txt").read_text() == "mine"  # not the sweep's: kept
    assert not stale.exists()  # the old designs went with the old sweep
    settings = json.loads((copy / "sweep.json").read_text())
    assert settings["n_frames"] == 1 and settings["analyzer"]["expansions"] == 4
    for row in results["rows"]:
        assert load_dataset(copy / DESIGNS_DIR / row["design"]).n_frames == 1
    again = json.loads((copy / "results.json").read_text())
    assert [row["design"] for row in again["rows"]] == [row["design"] for row in results["rows"]]
    assert again["settings"]["n_frames"] == 1


def test_the_display_draws_from_a_result(
    tiny_sweep: tuple[Path, dict, list[str]], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    _, results, _ = tiny_sweep
    display = SweepDisplay.from_result(json.loads(json.dumps(results)))
    assert display.names == ["pusher_width"] and display.n_trajectories == 2 and len(display.rows) == 2
    assert display.plot().figure_ is not None
    left, right = display.figure_.axes
    assert left.get_title().startswith("Spearman rho = ") and "(2 designs)" in left.get_title()
    assert [int(tick) for tick in right.get_xticks()] == [1, 2]
    assert len(right.get_lines()) == 4  # three margins and the success rate of t trajectories
    assert display.save(tmp_path / "figure.png") == tmp_path / "figure.png"
    assert (tmp_path / "figure.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    monkeypatch.setattr("energy_margin.runs.display.pyplot", lambda: None)
    assert display.save(tmp_path / "none.png") is None and not (tmp_path / "none.png").exists()
    with pytest.raises(EnergyMarginError, match="at least two analysed designs"):
        SweepDisplay.from_result({key: value for key, value in results.items() if key != "correlations"})
