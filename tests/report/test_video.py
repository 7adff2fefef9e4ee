"""Videos: the roll-out run again at video rate, drawn, with the score strip; MP4 and GIF."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from energy_margin.cli import main
from energy_margin.data.dataset import load_dataset
from energy_margin.data.generate import replay_trajectory
from energy_margin.errors import EnergyMarginError
from energy_margin.report import video

iio = pytest.importorskip("imageio.v3")
pytest.importorskip("PIL")


def test_replayed_roll_out_passes_through_every_recorded_frame(tiny_dataset: Path) -> None:
    dataset = load_dataset(tiny_dataset)
    steps = dataset.task.frame_steps(dataset.n_frames)
    states = dict(replay_trajectory(dataset, 1, np.arange(steps[-1] + 1)))
    assert sorted(states) == list(range(steps[-1] + 1))
    for k, step in enumerate(steps):
        np.testing.assert_array_equal(states[int(step)].object_pos, dataset.arrays["object_pos"][1, k])
        np.testing.assert_array_equal(states[int(step)].robot_q, dataset.arrays["robot_q"][1, k])


def test_replay_refuses_a_trajectory_it_cannot_run_again(tiny_dataset: Path, rewrite_frames) -> None:
    dataset = load_dataset(tiny_dataset)
    rewrite_frames(tiny_dataset, friction=dataset.arrays["friction"] + 0.01)
    with pytest.raises(EnergyMarginError, match="does not start as seed 0 draws it"):
        next(replay_trajectory(load_dataset(tiny_dataset), 0, np.array([0])))


def test_video_steps_are_at_video_rate() -> None:
    steps = video.video_steps(2.0, 1.0 / 120.0, 30.0)
    assert len(steps) == 61 and steps[0] == 0 and steps[-1] == 240
    assert set(np.diff(steps)) == {4}
    assert len(video.video_steps(2.3, 0.002, 30.0)) == 70


def test_strip_plots_scores_at_their_times() -> None:
    strip = video.score_strip(
        400, 96, duration=2.0, times=np.array([0.0, 1.0, 2.0]), capture=np.full(3, 0.5), success=np.zeros(3), now=1.5
    )
    assert strip.shape == (96, 400, 3)
    left, right, top, bottom = 8, 392, 96 // 3 + 4, 88
    x, y = round(left + (right - left) * 0.5), round(bottom - (bottom - top) * 0.5)
    assert tuple(strip[y, x]) == video._CAPTURE_COLOUR
    column = [tuple(pixel) for pixel in strip[bottom - 2 : bottom + 2, x + 20]]
    assert video._SUCCESS_COLOUR in column and video._CAPTURE_COLOUR not in column
    # The cursor at t = 1.5 s.
    cursor = round(left + (right - left) * 0.75)
    assert strip[(top + bottom) // 2, cursor].max() < 100


def test_render_writes_an_mp4_of_the_expected_length_and_size(
    analysed: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("ENERGY_MARGIN_PROGRESS", "1")
    out = tmp_path / "push.mp4"
    assert main(["render", str(analysed), "--trajectory", "1", "--fps", "10", "--out", str(out)]) == 0
    captured = capsys.readouterr()
    assert "video: " in captured.out and "21 pictures, 640 x 480" in captured.out
    assert "render: 100%" in captured.err and "21/21" in captured.err
    pictures = iio.imread(out, index=None, plugin="FFMPEG")
    assert pictures.shape == (21, 480, 640, 3)
    assert iio.immeta(out, plugin="FFMPEG")["fps"] == pytest.approx(10.0)
    # Every picture shows a scene (not blank) and the pictures change as the roll-out runs.
    assert all(float(picture.std()) > 10 for picture in pictures)
    assert float(np.abs(pictures[0].astype(int) - pictures[-1]).mean()) > 1.0


def test_gif_pictures_are_the_drawn_states(analysed: Path, tmp_path: Path) -> None:
    from energy_margin.report.render import dataset_renderer, scene_view

    out = tmp_path / "push.gif"
    assert main(["render", str(analysed), "--trajectory", "0", "--fps", "5", "--out", str(out)]) == 0
    pictures = iio.imread(out, index=None)[..., :3]
    assert pictures.shape == (11, 480, 640, 3)
    dataset = load_dataset(analysed)
    # Picture 5 is t = 1.0 s, the dataset's frame 1: drawn again from the recorded state, it matches.
    with dataset_renderer(dataset, 0, height=480 - 96) as renderer:
        frames = [dataset.frame(0, k) for k in range(dataset.n_frames)]
        view = scene_view(renderer.simulator.scene, np.concatenate([renderer.view_points(f) for f in frames]))
        same = renderer.render(frames[1], view=view).astype(int)
        other = renderer.render(frames[2], view=view).astype(int)
    picture = pictures[5, : 480 - 96].astype(int)
    assert float(np.abs(picture - same).mean()) < 3.0 < float(np.abs(picture - other).mean())


def test_without_an_encoder_the_video_is_a_gif(
    analysed: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from energy_margin.report import render

    monkeypatch.setattr(video, "_encoder_available", lambda: False)
    monkeypatch.setattr(render, "_warned", set())
    out = tmp_path / "push.mp4"
    assert main(["render", str(analysed), "--trajectory", "0", "--fps", "2", "--out", str(out)]) == 0
    assert not out.exists() and (tmp_path / "push.gif").is_file()
    assert iio.imread(tmp_path / "push.gif", index=None).shape[0] == 5
    warnings = [line for line in capsys.readouterr().err.splitlines() if "warning" in line]
    assert len(warnings) == 1 and "no MP4 encoder" in warnings[0]


def test_render_bad_input_is_one_line(analysed: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cases = [
        (["--trajectory", "9"], "has no trajectory 9 (trajectories 0 to 1)"),
        (["--trajectory", "0", "--width", "650"], "--width must be a multiple of 16 for MP4, got 650 x 480"),
        (["--trajectory", "0", "--out", str(tmp_path / "no" / "v.mp4")], "is not a directory"),
    ]
    for arguments, message in cases:
        assert main(["render", str(analysed), *arguments]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and message in err[0], err
    assert main(["render", str(tmp_path / "none"), "--trajectory", "0"]) == 2
    assert not (tmp_path / "no").exists() and not list(analysed.glob("*.mp4"))
