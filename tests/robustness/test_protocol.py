"""The two perturbation protocols: ``valid`` (no overlaps) and ``paper`` (the authors' draw)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from energy_margin.cli import main
from energy_margin.data.dataset import load_dataset
from energy_margin.data.validation import check_dataset, overlaps_expected
from energy_margin.errors import EnergyMarginError, InvalidParameterError
from energy_margin.robustness.perturb import PROTOCOLS, perturb_dataset, perturb_frame
from energy_margin.sim import make_simulator
from energy_margin.world.ellipsoid import min_volume_ellipsoid


def _cluster(make_block_scene, make_resting_frame):  # type: ignore[no-untyped-def]
    # Four 5 cm cylinders side by side along x: their ellipse (flat axis 5 cm) is far too small for
    # four discs, so a draw that checks nothing makes them interpenetrate.
    scene = make_block_scene(4, motion="upright")
    return scene, make_resting_frame(scene, spacing=0.1)


def test_paper_draw_is_the_first_n_points_of_the_stream_with_overlaps(make_block_scene, make_resting_frame) -> None:  # type: ignore[no-untyped-def]
    scene, frame = _cluster(make_block_scene, make_resting_frame)
    simulator = make_simulator(scene)
    paper = perturb_frame(frame, simulator, np.random.default_rng(7), planar=True, min_thickness=0.05, protocol="paper")
    # Every centre at once from the (snapped) fit, nothing rejected, nothing grown.
    fit = min_volume_ellipsoid(frame.object_pos[:, :2], min_thickness=0.05).snapped()
    expected = fit.sample(np.random.default_rng(7), 4)
    assert np.array_equal(paper.frame.object_pos[:, :2], expected)
    assert (paper.candidates, paper.restarts, paper.growth) == (4, 0, 1.0)
    # Upright objects stand on the ground (one common height), at rest, yaw zero.
    assert np.ptp(paper.frame.object_pos[:, 2]) == 0.0
    assert abs(paper.frame.object_pos[0, 2] - 0.015) < 1e-3
    assert np.all(paper.frame.object_vel == 0.0)
    assert np.all(paper.frame.object_quat == [1.0, 0.0, 0.0, 0.0])
    # The draw lets them interpenetrate, as the authors'; the valid protocol does not.
    assert paper.penetration > 5e-3
    valid = perturb_frame(frame, simulator, np.random.default_rng(7), planar=True, min_thickness=0.05)
    assert valid.penetration <= 5e-4
    assert valid.candidates > 4 and not np.array_equal(valid.frame.object_pos, paper.frame.object_pos)


def test_unknown_protocol_is_a_value_error(make_block_scene, make_resting_frame) -> None:  # type: ignore[no-untyped-def]
    scene, frame = _cluster(make_block_scene, make_resting_frame)
    with pytest.raises(InvalidParameterError, match="protocol"):
        perturb_frame(
            frame, make_simulator(scene), np.random.default_rng(0), planar=True, min_thickness=0.05, protocol="x"
        )


def test_paper_copies_record_their_protocol_and_keep_the_labels(tiny_dataset: Path, tmp_path: Path) -> None:
    assert PROTOCOLS == ("valid", "paper")
    paper = perturb_dataset(tiny_dataset, repeats=2, seed=3, out=tmp_path / "paper", protocol="paper")
    valid = perturb_dataset(tiny_dataset, repeats=1, seed=3, out=tmp_path / "valid")
    true = load_dataset(tiny_dataset)
    copy = load_dataset(paper[0])
    info = copy.metadata["perturbation"]
    assert info["protocol"] == "paper" and "overlaps allowed" in info["method"]
    assert "tolerance_m" not in info and "max_attempts" not in info
    frames = true.n_trajectories * true.n_frames
    assert info["candidates"] == frames * true.n_objects and info["restarts"] == 0
    assert 0 <= info["frames_with_overlaps"] <= frames and info["deepest_penetration_m"] >= 0.0
    for name in ("captured", "in_success", "robot_q", "robot_v", "friction", "drive"):
        assert np.array_equal(copy.arrays[name], true.arrays[name]), name
    assert np.all(copy.arrays["object_vel"] == 0.0)
    valid_info = load_dataset(valid[0]).metadata["perturbation"]
    assert valid_info["protocol"] == "valid" and valid_info["tolerance_m"] == 5e-4
    assert valid_info["frames_with_overlaps"] == 0
    # Same seed, other protocol: other draws.
    assert not np.array_equal(copy.arrays["object_pos"], load_dataset(valid[0]).arrays["object_pos"])
    # Overlaps in a paper copy are expected: warnings of `check`, not problems.
    assert overlaps_expected(copy.metadata) and not overlaps_expected(load_dataset(valid[0]).metadata)
    assert check_dataset(paper[0]) == []


def test_overlaps_expected_only_for_imported_sets_and_paper_copies() -> None:
    assert overlaps_expected({"imported_from": "their/folder"})
    assert overlaps_expected({"perturbation": {"protocol": "paper"}})
    assert not overlaps_expected({"perturbation": {"protocol": "valid"}})
    assert not overlaps_expected({"perturbation": {}})
    assert not overlaps_expected({})


@pytest.mark.slow
def test_paper_copies_are_deterministic_with_one_or_two_workers(tiny_dataset: Path, tmp_path: Path) -> None:
    one = perturb_dataset(tiny_dataset, repeats=2, seed=4, out=tmp_path / "one", protocol="paper", workers=1)
    two = perturb_dataset(tiny_dataset, repeats=2, seed=4, out=tmp_path / "two", protocol="paper", workers=2)
    again = perturb_dataset(tiny_dataset, repeats=1, seed=4, out=tmp_path / "again", protocol="paper")
    for first, second in zip(one, two, strict=True):
        assert (first / "frames.npz").read_bytes() == (second / "frames.npz").read_bytes()
    assert (one[0] / "frames.npz").read_bytes() == (again[0] / "frames.npz").read_bytes()
    other = perturb_dataset(tiny_dataset, repeats=1, seed=5, out=tmp_path / "other", protocol="paper")
    assert (one[0] / "frames.npz").read_bytes() != (other[0] / "frames.npz").read_bytes()


def test_copies_of_another_protocol_are_not_reused(tiny_dataset: Path, tmp_path: Path) -> None:
    out = tmp_path / "copies"
    perturb_dataset(tiny_dataset, repeats=1, seed=0, out=out)
    with pytest.raises(EnergyMarginError, match="overwrite"):
        perturb_dataset(tiny_dataset, repeats=1, seed=0, out=out, protocol="paper")
    # A copy written before the protocol was recorded is a valid-protocol copy: kept as is.
    metadata_path = out / "1" / "dataset.json"
    metadata = json.loads(metadata_path.read_text())
    del metadata["perturbation"]["protocol"]
    metadata_path.write_text(json.dumps(metadata))
    before = (out / "1" / "frames.npz").stat().st_mtime_ns
    perturb_dataset(tiny_dataset, repeats=1, seed=0, out=out)
    assert (out / "1" / "frames.npz").stat().st_mtime_ns == before


def test_cli_protocol(tiny_dataset: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "paper"
    assert main(["perturb", str(tiny_dataset), "--protocol", "paper", "--repeats", "1", "--out", str(out)]) == 0
    assert "1 perturbed copies (paper protocol)" in capsys.readouterr().out
    assert json.loads((out / "1" / "dataset.json").read_text())["perturbation"]["protocol"] == "paper"


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--protocol", "authors"], "invalid choice: 'authors'"),
        (["--protocol", "paper", "--tolerance", "1"], "tolerance applies to the valid protocol only"),
    ],
)
def test_cli_bad_protocol_is_one_error_line(
    args: list[str], message: str, tiny_dataset: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    try:
        status = main(["perturb", str(tiny_dataset), "--out", str(out), *args])
    except SystemExit as exit_:  # argparse rejects a bad choice itself
        status = exit_.code
    assert status == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and message in err
    assert not out.exists()
