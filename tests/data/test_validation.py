"""check_dataset, overlap detection, scores.csv checks and ``energy-margin check``."""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from energy_margin import compat
from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.run import analyze
from energy_margin.cli import main
from energy_margin.data.dataset import FRAMES_FILE, Problem, load_dataset
from energy_margin.data.scores_file import COLUMNS, CONFIG_FILE, JOURNAL_FILE, SCORES_FILE, load_scores
from energy_margin.data.validation import OVERLAP_FRACTION, check_dataset, overlap_problems, require_valid
from energy_margin.errors import EnergyMarginError
from energy_margin.evaluation.metrics import evaluate

SMALL = AnalyzerConfig(expansions=5)
HEADER = ",".join(COLUMNS)


def _arrays(directory: Path) -> dict[str, np.ndarray]:
    with np.load(directory / FRAMES_FILE) as archive:
        return {name: archive[name].copy() for name in archive.files}


def _strings(problems: list[Problem]) -> list[str]:
    return [str(p) for p in problems]


@pytest.fixture(scope="module")
def scored_source(tiny_dataset_source: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    target = tmp_path_factory.mktemp("validation") / "scored"
    shutil.copytree(tiny_dataset_source, target)
    analyze(target, SMALL, seed=0, progress=False)
    return target


@pytest.fixture
def scored(scored_source: Path, tmp_path: Path) -> Path:
    target = tmp_path / "scored"
    shutil.copytree(scored_source, target)
    return target


def _scores_lines(directory: Path) -> list[str]:
    return (directory / SCORES_FILE).read_text().splitlines()


def _write_scores(directory: Path, lines: list[str]) -> None:
    (directory / SCORES_FILE).write_text("\n".join(lines) + "\n")


# ---------------------------------------------------------------- valid datasets


def test_valid_dataset_has_no_problems(tiny_dataset: Path, scored: Path) -> None:
    assert check_dataset(tiny_dataset) == []
    assert check_dataset(tiny_dataset, scores=False) == []
    assert check_dataset(scored) == []  # scores.csv is checked when present
    assert check_dataset(scored, scores=True) == []
    assert overlap_problems(load_dataset(tiny_dataset)) == []
    assert require_valid(scored, scores=True).n_frames == 3


def test_scores_required_but_missing(tiny_dataset: Path) -> None:
    assert _strings(check_dataset(tiny_dataset, scores=True)) == [
        "scores.csv: file: does not exist; run `energy-margin analyze` first"
    ]
    with pytest.raises(EnergyMarginError, match=r"scores.csv: file: does not exist"):
        require_valid(tiny_dataset, scores=True)


# ---------------------------------------------------------------- array problems


def test_several_array_problems_are_listed_at_once(tiny_dataset: Path, rewrite_frames: Callable[..., None]) -> None:
    arrays = _arrays(tiny_dataset)
    arrays["object_pos"][0, 1, 1, 2] = np.nan
    arrays["robot_v"][1, 2, 3] = np.inf
    arrays["object_vel"][1, 0, 0, 5] = -np.inf
    rewrite_frames(tiny_dataset, **{k: arrays[k] for k in ("object_pos", "robot_v", "object_vel")})
    problems = check_dataset(tiny_dataset)
    assert _strings(problems)[:2] == [
        "frames.npz: object_pos [trajectory 0, frame 1, object 1]: NaN or infinite value",
        "frames.npz: object_vel [trajectory 1, frame 0, object 0]: NaN or infinite value",
    ]
    assert len(problems) == 3
    assert str(problems[2]).startswith("frames.npz: robot_v [trajectory 1, frame 2")
    assert str(problems[2]).endswith("]: NaN or infinite value")
    assert all(p.file == FRAMES_FILE for p in problems)
    # The reader stops at the first, naming how many more there are.
    with pytest.raises(EnergyMarginError, match=r"object_pos .* \(and 2 more; run `energy-margin check`"):
        load_dataset(tiny_dataset)


@pytest.mark.parametrize("name", ["robot_q", "robot_v"])
def test_robot_array_locations_do_not_name_an_object(
    tiny_dataset: Path, rewrite_frames: Callable[..., None], name: str
) -> None:
    arrays = _arrays(tiny_dataset)
    arrays[name][1, 2, 3] = np.nan
    rewrite_frames(tiny_dataset, **{name: arrays[name]})
    (problem,) = check_dataset(tiny_dataset)
    assert problem.row == "trajectory 1, frame 2, joint 3"


def test_negative_friction_and_non_unit_quaternion_together(
    tiny_dataset: Path, rewrite_frames: Callable[..., None]
) -> None:
    arrays = _arrays(tiny_dataset)
    arrays["friction"][1] = -0.2
    arrays["object_quat"][0, 2, 1] = [1.0, 0.5, 0.0, 0.0]
    arrays["object_quat"][1, 0, 0] = [0.0, 0.0, 0.0, 0.0]
    rewrite_frames(tiny_dataset, friction=arrays["friction"], object_quat=arrays["object_quat"])
    problems = check_dataset(tiny_dataset)
    assert _strings(problems) == [
        "frames.npz: friction [trajectory 1]: negative coefficient",
        "frames.npz: object_quat [trajectory 0, frame 2, object 1]: not a unit quaternion",
        "frames.npz: object_quat [trajectory 1, frame 0, object 0]: not a unit quaternion",
    ]
    for problem in problems:
        assert "frames.npz" in str(problem)
        assert problem.field in str(problem)
        assert "trajectory" in problem.row


def test_problems_per_array_are_capped(tiny_dataset: Path, rewrite_frames: Callable[..., None]) -> None:
    arrays = _arrays(tiny_dataset)
    arrays["object_pos"][:] = np.nan
    arrays["frame_time"][0, 0] = np.nan
    rewrite_frames(tiny_dataset, object_pos=arrays["object_pos"], frame_time=arrays["frame_time"])
    problems = check_dataset(tiny_dataset)
    fields = [p.field for p in problems]
    assert fields == ["object_pos"] * 5 + ["frame_time"]
    assert problems[-1].row == "trajectory 0, frame 0"


def test_nan_does_not_hide_other_array_problems(tiny_dataset: Path, rewrite_frames: Callable[..., None]) -> None:
    arrays = _arrays(tiny_dataset)
    arrays["object_vel"][0, 0, 0, 0] = np.nan
    arrays["friction"][1] = -0.5
    arrays["object_quat"][1, 1, 1] = [2.0, 0.0, 0.0, 0.0]
    rewrite_frames(tiny_dataset, **{k: arrays[k] for k in ("object_vel", "friction", "object_quat")})
    assert [p.field for p in check_dataset(tiny_dataset, overlaps=False)] == [
        "object_vel",
        "friction",
        "object_quat",
    ]


# ---------------------------------------------------------------- overlaps


def _overlap_one_frame(directory: Path, rewrite: Callable[..., None], trajectory: int, frame: int) -> None:
    arrays = _arrays(directory)
    pos = arrays["object_pos"]
    pos[trajectory, frame, 1] = pos[trajectory, frame, 0] + [0.01, 0.0, 0.0]  # object 1 onto object 0
    rewrite(directory, object_pos=pos)


def test_objects_overlapping_each_other(tiny_dataset: Path, rewrite_frames: Callable[..., None]) -> None:
    _overlap_one_frame(tiny_dataset, rewrite_frames, 1, 2)
    problems = check_dataset(tiny_dataset)
    assert problems
    for problem in problems:
        assert problem.file == FRAMES_FILE
        assert problem.field == "object_pos"
        assert problem.row == "trajectory 1, frame 2"
        assert "overlaps object" in problem.message
        assert str(problem).startswith("frames.npz: object_pos [trajectory 1, frame 2]: object ")
    assert check_dataset(tiny_dataset, overlaps=False) == []


def test_each_overlap_is_listed_once(tiny_dataset: Path, rewrite_frames: Callable[..., None]) -> None:
    arrays = _arrays(tiny_dataset)
    pos = arrays["object_pos"]
    for trajectory, frame in ((0, 0), (1, 1), (1, 2)):
        pos[trajectory, frame, 1] = pos[trajectory, frame, 0] + [0.01, 0.0, 0.0]
    rewrite_frames(tiny_dataset, object_pos=pos)
    assert [p.row for p in check_dataset(tiny_dataset)] == [
        "trajectory 0, frame 0",
        "trajectory 1, frame 1",
        "trajectory 1, frame 2",
    ]


def test_object_sunk_into_the_ground(tiny_dataset: Path, rewrite_frames: Callable[..., None]) -> None:
    arrays = _arrays(tiny_dataset)
    pos = arrays["object_pos"]
    pos[0, 1, 0, 2] -= 0.04  # 40 mm into the ground; the limit is half the 50 mm radius
    rewrite_frames(tiny_dataset, object_pos=pos)
    problems = check_dataset(tiny_dataset)
    assert problems
    assert {p.row for p in problems} == {"trajectory 0, frame 1"}
    assert all("object 0 overlaps the end-effector or an obstacle" in p.message for p in problems)
    assert all("(limit 25.0 mm)" in p.message for p in problems)


@pytest.mark.skipif(
    not compat.mujoco_at_least(compat.CYLINDER_INSIDE_BOX_SINCE),
    reason="MuJoCo before 4.0 finds no contact for a cylinder whose centre is inside a box (the pusher)",
)
def test_object_inside_the_pusher(tiny_dataset: Path, rewrite_frames: Callable[..., None]) -> None:
    arrays = _arrays(tiny_dataset)
    pos = arrays["object_pos"]
    pos[1, 0, 1, :2] = arrays["robot_q"][1, 0, :2]  # object 1 at the pusher's centre
    rewrite_frames(tiny_dataset, object_pos=pos)
    problems = check_dataset(tiny_dataset)
    assert problems
    assert {p.row for p in problems} == {"trajectory 1, frame 0"}
    assert all("object 1 overlaps the end-effector or an obstacle" in p.message for p in problems)


def test_small_penetrations_are_tolerated(tiny_dataset: Path, rewrite_frames: Callable[..., None]) -> None:
    arrays = _arrays(tiny_dataset)
    pos = arrays["object_pos"]
    pos[0, 1, 0, 2] -= 0.02  # 20 mm: soft contacts, below the limit
    rewrite_frames(tiny_dataset, object_pos=pos)
    assert OVERLAP_FRACTION * 0.05 > 0.02
    assert check_dataset(tiny_dataset) == []


def test_analyze_refuses_overlaps_before_writing(
    tiny_dataset: Path, rewrite_frames: Callable[..., None], capsys: pytest.CaptureFixture[str]
) -> None:
    _overlap_one_frame(tiny_dataset, rewrite_frames, 0, 2)
    before = sorted(p.name for p in tiny_dataset.iterdir())
    with pytest.raises(EnergyMarginError, match=r"frames.npz: object_pos \[trajectory 0, frame 2\]: .*overlaps object"):
        analyze(tiny_dataset, SMALL, progress=False)
    with pytest.raises(EnergyMarginError, match="overlaps object"):
        analyze(tiny_dataset, SMALL, workers=2, progress=False)
    code = main(["analyze", str(tiny_dataset), "--expansions", "5", "--no-progress"])
    err = capsys.readouterr().err
    assert code == 2
    assert len(err.splitlines()) == 1
    assert err.startswith("energy-margin: error: dataset ")
    assert "overlaps object" in err
    assert sorted(p.name for p in tiny_dataset.iterdir()) == before
    assert not (tiny_dataset / CONFIG_FILE).exists()
    assert not (tiny_dataset / JOURNAL_FILE).exists()


def test_evaluate_refuses_overlaps(scored: Path, rewrite_frames: Callable[..., None]) -> None:
    _overlap_one_frame(scored, rewrite_frames, 1, 0)
    with pytest.raises(EnergyMarginError, match=r"\[trajectory 1, frame 0\]: .*overlaps object"):
        evaluate(scored)


# ---------------------------------------------------------------- scores.csv


def test_score_outside_the_unit_interval(scored: Path) -> None:
    lines = _scores_lines(scored)
    fields = lines[3].split(",")
    fields[COLUMNS.index("capture_score")] = "1.5"
    fields[COLUMNS.index("success_score")] = "-0.25"
    lines[3] = ",".join(fields)
    assert _write_and_check(scored, lines) == [
        "scores.csv: capture_score [line 4]: 1.5 is outside [0, 1]",
        "scores.csv: success_score [line 4]: -0.25 is outside [0, 1]",
    ]
    with pytest.raises(EnergyMarginError, match=r"scores.csv: capture_score \[line 4\]: 1.5 is outside"):
        evaluate(scored)


def _write_and_check(directory: Path, lines: list[str]) -> list[str]:
    _write_scores(directory, lines)
    return _strings(check_dataset(directory))


@pytest.mark.parametrize(
    ("edit", "expected"),
    [
        (
            lambda lines: [*lines[:4], lines[2], *lines[4:]],
            ["scores.csv: row [line 5]: duplicates line 3 (trajectory 0, frame 1)"],
        ),
        (
            lambda lines: [lines[0], *lines[1:5], *lines[6:]],
            ["scores.csv: row [trajectory 1, frame 1]: is missing"],
        ),
        (
            lambda lines: [*lines[:3], "0,2,0.5", *lines[4:]],
            [
                "scores.csv: row [line 4]: has 3 fields, expected 12",
                "scores.csv: row [trajectory 0, frame 2]: is missing",
            ],
        ),
        (
            lambda lines: [*lines[:2], lines[2].replace(",", ",x", 1), *lines[3:]],
            ["scores.csv: frame [line 3]: 'x1' is not a number", "scores.csv: row [trajectory 0, frame 1]: is missing"],
        ),
        (
            lambda lines: ["trajectory,frame,score", *lines[1:]],
            ["scores.csv: header [line 1]: expected " + HEADER],
        ),
        (lambda lines: [], ["scores.csv: header [line 1]: expected " + HEADER]),
        (
            lambda lines: [*lines, "2,0,0.5,0.5,31,30,0.01,0.005,7,0,0,0.5"],
            ["scores.csv: trajectory [line 8]: frame (2, 0) is outside the dataset"],
        ),
        (
            lambda lines: [*lines[:6], lines[6].replace(lines[6].split(",")[6], "-1.0", 1)],
            ["scores.csv: runtime_s [line 7]: -1.0 is not a non-negative time"],
        ),
    ],
    ids=["duplicate", "missing", "malformed", "not-a-number", "bad-header", "empty", "outside", "negative-time"],
)
def test_scores_problems(scored: Path, edit: Callable[[list[str]], list[str]], expected: list[str]) -> None:
    lines = edit(_scores_lines(scored))
    assert _write_and_check(scored, lines) == expected
    with pytest.raises(EnergyMarginError, match=r"scores\.csv"):
        evaluate(scored)


def test_a_scores_file_without_the_tree_capture_score_is_still_read(scored: Path) -> None:
    # Written before the tree's own capture score was kept: it reads as NaN (unknown).
    kept = load_scores(scored)
    assert np.isfinite(kept["tree_capture_score"]).all()
    lines = [line.rsplit(",", 1)[0] for line in _scores_lines(scored)]
    assert _write_and_check(scored, lines) == []
    scores = load_scores(scored)
    assert np.isnan(scores["tree_capture_score"]).all()
    np.testing.assert_array_equal(scores["capture_score"], kept["capture_score"])


def test_a_scores_file_without_the_tree_counts_is_still_read(scored: Path) -> None:
    # Written before the trees' rejections were counted: the counts read as -1 (unknown).
    lines = [",".join(line.split(",")[:9]) for line in _scores_lines(scored)]
    lines[0] = lines[0].replace("expansions", "iterations")  # the column's name then
    assert _write_and_check(scored, lines) == []
    scores = load_scores(scored)
    assert (scores["rejected"] == -1).all() and (scores["diverged"] == -1).all()


@pytest.mark.parametrize(
    ("edit", "expected"),
    [
        (
            lambda lines: [*lines[:2], ",".join([*lines[2].split(",")[:10], "-2", lines[2].split(",")[11]])],
            ["scores.csv: diverged [line 3]: -2 is not a count (-1: unknown)"],
        ),
        (
            lambda lines: [*lines[:2], lines[2].rsplit(",", 1)[0] + ",1.5"],
            ["scores.csv: tree_capture_score [line 3]: 1.5 is outside [0, 1] (nan: unknown)"],
        ),
    ],
    ids=["negative-count", "tree-capture-outside"],
)
def test_tree_count_problems(scored: Path, edit: Callable[[list[str]], list[str]], expected: list[str]) -> None:
    lines = edit(_scores_lines(scored))
    assert _write_and_check(scored, lines)[:1] == expected


def test_several_scores_problems_at_once(scored: Path) -> None:
    lines = _scores_lines(scored)
    fields = lines[1].split(",")
    fields[COLUMNS.index("capture_score")] = "1.5"
    lines[1] = ",".join(fields)
    lines = [*lines[:5], "garbage", lines[2]]  # drops trajectory 1, frame 1 and 2; duplicates line 3
    assert _write_and_check(scored, lines) == [
        "scores.csv: capture_score [line 2]: 1.5 is outside [0, 1]",
        "scores.csv: row [line 6]: has 1 fields, expected 12",
        "scores.csv: row [line 7]: duplicates line 3 (trajectory 0, frame 1)",
        "scores.csv: row [trajectory 1, frame 1]: is missing",
        "scores.csv: row [trajectory 1, frame 2]: is missing",
    ]


# ---------------------------------------------------------------- energy-margin check


def test_check_command_on_a_good_dataset(scored: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", str(scored)]) == 0
    captured = capsys.readouterr()
    assert captured.out == f"{scored}: ok\n"
    assert captured.err == ""


def test_check_command_on_a_bad_dataset(
    scored: Path, rewrite_frames: Callable[..., None], capsys: pytest.CaptureFixture[str]
) -> None:
    arrays = _arrays(scored)
    arrays["object_pos"][1, 0, 0, 0] = np.nan
    arrays["drive"][0, 0] = np.inf
    rewrite_frames(scored, object_pos=arrays["object_pos"], drive=arrays["drive"])
    before = {p.name: p.read_bytes() for p in scored.iterdir()}
    assert main(["check", str(scored)]) == 2
    captured = capsys.readouterr()
    assert captured.out.splitlines() == [
        "frames.npz: object_pos [trajectory 1, frame 0, object 0]: NaN or infinite value",
        "frames.npz: drive [trajectory 0]: NaN or infinite value",
    ]
    assert captured.err.splitlines() == [f"energy-margin: error: 2 problem(s) in {scored}"]
    assert {p.name: p.read_bytes() for p in scored.iterdir()} == before  # check writes nothing


def test_check_command_lists_overlaps_and_scores(
    scored: Path, rewrite_frames: Callable[..., None], capsys: pytest.CaptureFixture[str]
) -> None:
    _overlap_one_frame(scored, rewrite_frames, 0, 1)
    lines = _scores_lines(scored)
    _write_scores(scored, lines[:-1])  # trajectory 1, frame 2 missing
    assert main(["check", str(scored)]) == 2
    captured = capsys.readouterr()
    out = captured.out.splitlines()
    assert out[-1] == "scores.csv: row [trajectory 1, frame 2]: is missing"
    assert all(line.startswith("frames.npz: object_pos [trajectory 0, frame 1]: ") for line in out[:-1])
    assert len(captured.err.splitlines()) == 1
    assert captured.err.startswith(f"energy-margin: error: {len(out)} problem(s) in ")

    assert main(["check", str(scored), "--no-overlaps"]) == 2
    captured = capsys.readouterr()
    assert captured.out.splitlines() == ["scores.csv: row [trajectory 1, frame 2]: is missing"]


def test_check_command_on_a_missing_dataset(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    missing = tmp_path / "nope"
    assert main(["check", str(missing)]) == 2
    captured = capsys.readouterr()
    assert captured.out.splitlines() == [f"{missing}: directory does not exist or is not a directory"]
    assert captured.err.splitlines() == [f"energy-margin: error: 1 problem(s) in {missing}"]


def test_drive_size_that_does_not_match_the_task(tiny_dataset: Path, rewrite_frames: Callable[..., None]) -> None:
    metadata_path = tiny_dataset / "dataset.json"
    metadata = json.loads(metadata_path.read_text())
    assert metadata["n_drive"] == 2
    metadata["n_drive"] = 0
    metadata_path.write_text(json.dumps(metadata))
    rewrite_frames(tiny_dataset, drive=_arrays(tiny_dataset)["drive"][:, :0].copy())
    assert [p.field for p in check_dataset(tiny_dataset)] == ["n_drive"]


def test_overlaps_of_a_recorded_set_are_warnings(scored: Path, rewrite_frames: Callable[..., None]) -> None:
    """A recorded set's frames are the user's simulation's own states: its penetrations are kept, not refused."""
    _overlap_one_frame(scored, rewrite_frames, 1, 0)
    metadata_path = scored / "dataset.json"
    metadata = json.loads(metadata_path.read_text())
    metadata["recorded_from"] = [{"file": "episode.npz", "sha256": "0" * 64}]
    metadata_path.write_text(json.dumps(metadata))
    warnings: list = []
    assert check_dataset(scored, warnings=warnings) == []
    assert warnings and "overlaps object" in warnings[0].message
    assert evaluate(scored).n_frames > 0


def test_small_objects_get_the_overlap_floor(tmp_path: Path) -> None:
    from energy_margin.data.generate import generate_dataset
    from energy_margin.data.validation import OVERLAP_FLOOR

    out = tmp_path / "scoop"
    generate_dataset("scooping", out=out, n_objects=2, n_trajectories=1, n_frames=2, seed=0)
    dataset = load_dataset(out)
    arrays = dict(dataset.arrays)
    pos, quat = arrays["object_pos"].copy(), arrays["object_quat"].copy()
    quat[0, 0, :2] = [1.0, 0.0, 0.0, 0.0]
    width = 2 * dataset.task.build_scene(2, 0.5).objects[0].geom.size[0]
    assert OVERLAP_FRACTION * width / 2 < 0.003 < OVERLAP_FLOOR  # 1 cm boxes: 2.5 mm without the floor
    # Box 1 pressed 3 mm into box 0 along x, then 6 mm.
    pos[0, 0, 1] = pos[0, 0, 0] + [width - 0.003, 0.0, 0.0]
    np.savez_compressed(out / FRAMES_FILE, **{**arrays, "object_pos": pos, "object_quat": quat})
    assert not [p for p in check_dataset(out) if "overlaps object" in p.message]
    pos[0, 0, 1] = pos[0, 0, 0] + [width - 0.006, 0.0, 0.0]
    np.savez_compressed(out / FRAMES_FILE, **{**arrays, "object_pos": pos, "object_quat": quat})
    assert any("overlaps object" in p.message and "(limit 4.0 mm)" in p.message for p in check_dataset(out))


def test_a_scores_file_of_release_0_2_with_its_iterations_column_is_still_read(scored: Path) -> None:
    before = load_scores(scored)
    lines = [line.rsplit(",", 1)[0] for line in _scores_lines(scored)]  # no tree capture score then
    lines[0] = lines[0].replace(",expansions,", ",iterations,")
    assert _write_and_check(scored, lines) == []
    after = load_scores(scored)
    np.testing.assert_array_equal(after["expansions"], before["expansions"])
    assert "iterations" not in after
