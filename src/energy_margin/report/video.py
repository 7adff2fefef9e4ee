"""Videos of a scripted roll-out at video rate, with the frame scores in a strip below the picture.

The roll-out of a generated dataset's trajectory is run again (generation is deterministic, see
:func:`~energy_margin.data.generate.replay_trajectory`) and drawn at ``fps`` pictures per second of
simulated time by :class:`~energy_margin.report.render.FrameRenderer`, with the capture region
built from each drawn state. Below the picture a strip plots the capture and success scores of the
recorded frames against time, with a cursor at the drawn time and the latest scores as text.
MP4 (H.264) is written through ``imageio-ffmpeg``, which brings its own ffmpeg; GIF (Pillow) when
the output ends in ``.gif`` or no encoder is found (one warning line).
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from energy_margin.errors import EnergyMarginError, InvalidParameterError, check_positive_float
from energy_margin.runs.progress import Progress, progress_bar

if TYPE_CHECKING:
    from energy_margin.data.dataset import Dataset
    from energy_margin.report.render import FrameRenderer
    from energy_margin.world.state import FrameState

__all__ = [
    "VideoResult",
    "output_path",
    "render_video",
    "score_strip",
    "video_steps",
]

#: Strip colours: capture (the capture region's blue) and success (the success region's purple).
_CAPTURE_COLOUR = (31, 120, 180)
_SUCCESS_COLOUR = (148, 64, 199)


@dataclass(frozen=True)
class VideoResult:
    """What :func:`render_video` wrote.

    Attributes:
        path: the written file (``.mp4`` or ``.gif``).
        frames: pictures in the file.
        width: picture width, pixels.
        height: picture height, pixels.
        fps: pictures per second.
        render_s: wall time of drawing the pictures (MuJoCo or the fallback), s.
        total_s: wall time of the whole video (roll-out, drawing, encoding), s.
        backend: ``"mujoco"`` or ``"matplotlib"`` (the fallback).
        poster: the middle picture (height, width, 3) uint8, for a page's still image.

    """

    path: Path
    frames: int
    width: int
    height: int
    fps: float
    render_s: float
    total_s: float
    backend: str
    poster: np.ndarray | None = None

    @property
    def seconds(self) -> float:
        """Length of the video, s."""
        return self.frames / self.fps


def video_steps(duration: float, timestep: float, fps: float) -> np.ndarray:
    """Physics steps drawn at ``fps`` over a roll-out of ``duration`` s with time step ``timestep`` s."""
    check_positive_float("fps", fps)
    n_steps = round(duration / timestep)
    times = np.arange(0.0, duration + 0.5 / fps, 1.0 / fps)
    return np.unique(np.clip(np.round(times / timestep).astype(int), 0, n_steps))


def _font(size: int) -> Any:
    from PIL import ImageFont

    try:
        return ImageFont.load_default(size=size)
    except TypeError:  # a Pillow without FreeType
        return ImageFont.load_default()


def score_strip(
    width: int,
    height: int,
    *,
    duration: float,
    times: np.ndarray,
    capture: np.ndarray | None,
    success: np.ndarray | None,
    now: float,
) -> np.ndarray:
    """The score strip (height, width, 3) uint8 at time ``now`` (s).

    Args:
        width: strip width, pixels.
        height: strip height, pixels.
        duration: the roll-out's length (the time axis), s.
        times: times of the recorded frames, shape (K,), s.
        capture: capture scores of the recorded frames, shape (K,), or ``None`` without scores.
        success: success scores, shape (K,), or ``None``.
        now: the drawn time, s.

    """
    from PIL import Image, ImageDraw

    image = Image.new("RGB", (width, height), (255, 255, 255))
    draw = ImageDraw.Draw(image)
    font = _font(max(10, height // 6))
    left, right, top, bottom = 8, width - 8, height // 3 + 4, height - 8

    def x_of(t: float) -> float:
        return left + (right - left) * t / duration

    def y_of(score: float) -> float:
        return bottom - (bottom - top) * score

    draw.rectangle((left, top, right, bottom), outline=(180, 180, 180))
    latest = np.flatnonzero(times <= now + 1e-9)
    if capture is None or success is None:
        text = f"t = {now:.2f} s   (no scores.csv: run energy-margin analyze for the scores)"
    else:
        for scores, colour in ((capture, _CAPTURE_COLOUR), (success, _SUCCESS_COLOUR)):
            points = [(x_of(float(t)), y_of(float(s))) for t, s in zip(times, scores, strict=True)]
            if len(points) > 1:
                draw.line(points, fill=colour, width=2)
            for x, y in points:
                draw.ellipse((x - 2.5, y - 2.5, x + 2.5, y + 2.5), fill=colour)
        if latest.size:
            k = int(latest[-1])
            text = f"t = {now:.2f} s   frame {k}: capture {capture[k]:.2f}   success {success[k]:.2f}"
        else:
            text = f"t = {now:.2f} s   (before the first recorded frame)"
    cursor = x_of(now)
    draw.line([(cursor, top), (cursor, bottom)], fill=(40, 40, 40), width=1)
    draw.text((left, 2), text, fill=(20, 20, 20), font=font)
    if capture is not None:
        legend_x = right - 150
        draw.text((legend_x, 2), "capture", fill=_CAPTURE_COLOUR, font=font)
        draw.text((legend_x + 70, 2), "success", fill=_SUCCESS_COLOUR, font=font)
    return np.asarray(image)


class _Writer:
    """Pictures to an MP4 (imageio-ffmpeg) or a GIF (Pillow), into a temporary file."""

    def __init__(self, path: Path, fps: float) -> None:
        import imageio.v2 as imageio

        self.path, self.fps = path, fps
        self._frames: list[np.ndarray] = []
        self._ffmpeg = None
        if path.suffix.lower() != ".gif":
            self._ffmpeg = imageio.get_writer(
                path, format="FFMPEG", fps=fps, codec="libx264", pixelformat="yuv420p", quality=7, macro_block_size=16
            )

    def append(self, picture: np.ndarray) -> None:
        if self._ffmpeg is not None:
            self._ffmpeg.append_data(picture)
        else:
            self._frames.append(picture)

    def close(self) -> None:
        if self._ffmpeg is not None:
            self._ffmpeg.close()
            return
        from PIL import Image

        images = [Image.fromarray(frame) for frame in self._frames]
        images[0].save(
            self.path,
            format="GIF",
            save_all=True,
            append_images=images[1:],
            duration=round(1000.0 / self.fps),
            loop=0,
            optimize=False,
        )


def _encoder_available() -> bool:
    try:
        import imageio_ffmpeg

        imageio_ffmpeg.get_ffmpeg_exe()
    except Exception:  # not installed, or no binary for this platform
        return False
    return True


def output_path(path: Path) -> Path:
    """The file a video for ``path`` goes to: ``path`` itself, or its ``.gif`` sibling without an MP4 encoder."""
    from energy_margin.report.render import warn_once

    if path.suffix.lower() == ".gif" or _encoder_available():
        return path
    warn_once(f"no MP4 encoder (pip install 'energy-margin[render]' brings imageio-ffmpeg); writing a GIF: {path}")
    return path.with_suffix(".gif")


def _check_size(path: Path, *, width: int, height: int, strip_height: int) -> None:
    """Refuse an MP4 size that is not a multiple of 16, a strip that leaves no picture, a missing folder."""
    if path.suffix.lower() != ".gif" and (width % 16 or height % 16):
        name = "width" if width % 16 else "height"
        raise InvalidParameterError(name, f"must be a multiple of 16 for MP4, got {width} x {height}")
    if not 16 <= strip_height < height - 16:
        raise InvalidParameterError("strip_height", f"must be in [16, {height - 16}), got {strip_height}")
    if not path.parent.is_dir():
        raise EnergyMarginError(f"cannot write {path}: {path.parent} is not a directory")


def render_video(
    dataset: Dataset,
    trajectory: int,
    path: Path | str,
    *,
    scores: dict[str, np.ndarray] | None = None,
    fps: float = 30.0,
    width: int = 640,
    height: int = 480,
    strip_height: int = 96,
    backend: str = "auto",
    progress: Progress = None,
) -> VideoResult:
    """Draw trajectory ``trajectory``'s roll-out at ``fps`` with its frame scores; write MP4 or GIF.

    Args:
        dataset: a generated dataset.
        trajectory: trajectory index.
        path: output file (``.mp4``, or ``.gif``); written atomically.
        scores: the dataset's ``scores.csv`` columns, or ``None`` (the strip then shows time only).
        fps: pictures per second of simulated time.
        width: picture width, pixels (a multiple of 16 for MP4).
        height: picture height including the strip, pixels (a multiple of 16 for MP4).
        strip_height: height of the score strip, pixels.
        backend: the :class:`~energy_margin.report.render.FrameRenderer` backend.
        progress: after each picture (:data:`~energy_margin.runs.progress.Progress`): ``True`` a
            bar on standard error, a callable is called with 1.

    """
    from energy_margin.evaluation.metrics import score_grid
    from energy_margin.report.render import check_trajectory, dataset_renderer

    started = time.perf_counter()
    check_trajectory(dataset, trajectory)
    path = output_path(Path(path))
    _check_size(path, width=width, height=height, strip_height=strip_height)
    times = np.asarray(dataset.arrays["frame_time"][trajectory], dtype=float)
    capture = success = None
    if scores is not None:
        capture = score_grid(dataset, scores, "capture_score")[trajectory]
        success = score_grid(dataset, scores, "success_score")[trajectory]
    strip = functools.partial(
        score_strip,
        width,
        strip_height,
        duration=dataset.task.config.duration,
        times=times,
        capture=capture,
        success=success,
    )
    renderer = dataset_renderer(dataset, trajectory, width=width, height=height - strip_height, backend=backend)
    try:
        bar = progress_bar(0, desc="render", unit="picture", enabled=progress)
        count, rendered, poster = _draw_roll_out(dataset, trajectory, renderer, path, fps, times, strip, bar.update)
        bar.close()
    finally:
        backend_used = renderer.backend
        renderer.close()
    total = time.perf_counter() - started
    return VideoResult(path, count, width, height, fps, rendered, total, backend_used, poster)


def _draw_roll_out(
    dataset: Dataset,
    trajectory: int,
    renderer: FrameRenderer,
    path: Path,
    fps: float,
    times: np.ndarray,
    strip: Callable[..., np.ndarray],
    progress: Callable[[int], None] | None,
) -> tuple[int, float, np.ndarray | None]:
    """Replay the roll-out and write its pictures at ``fps`` above their ``strip(now=...)`` to ``path``.

    ``times`` are the recorded frames' times (s). Returns the pictures written, the wall time of
    drawing them (s) and the middle one (the poster).
    """
    from energy_margin.data.generate import replay_trajectory
    from energy_margin.report.render import scene_view
    from energy_margin.runs.files import atomic_path

    task = dataset.task
    rendered = 0.0
    count = 0
    poster = None
    # One camera for the whole roll-out: it holds every recorded frame.
    recorded = [dataset.frame(trajectory, k) for k in range(dataset.n_frames)]
    view = scene_view(renderer.simulator.scene, np.concatenate([renderer.view_points(f) for f in recorded]))
    steps = video_steps(task.config.duration, task.config.timestep, fps)
    recorded_steps = {round(float(t) / task.config.timestep): k for k, t in enumerate(times)}
    wanted = np.union1d(steps, list(recorded_steps))
    drawn = set(int(s) for s in steps)
    with atomic_path(path) as temporary:
        writer = _Writer(temporary, fps)
        try:
            # The roll-out runs on its own simulator of the dataset's engine: drawing resets the
            # renderer's, which would disturb the roll-out's warm starts and servo targets.
            for step, state in replay_trajectory(dataset, trajectory, wanted):
                if step in recorded_steps:
                    _check_replayed(state, recorded[recorded_steps[step]], trajectory, recorded_steps[step])
                if step not in drawn:
                    continue
                now = step * task.config.timestep
                tick = time.perf_counter()
                picture = renderer.render(state, view=view)
                rendered += time.perf_counter() - tick
                composed = np.concatenate([picture, strip(now=now)], axis=0)
                writer.append(composed)
                if count == len(steps) // 2:
                    poster = composed
                count += 1
                if progress is not None:
                    progress(1)
        finally:
            writer.close()
    return count, rendered, poster


def _check_replayed(state: FrameState, stored: FrameState, trajectory: int, frame: int) -> None:
    """Warn once when the replayed ``state`` is not the recorded ``frame`` (objects 1e-6 m apart)."""
    from energy_margin.report.render import warn_once

    if not np.allclose(state.object_pos, stored.object_pos, atol=1e-6):
        warn_once(
            f"the roll-out of trajectory {trajectory} differs from its recorded frame "
            f"{frame} (another engine version?); the video shows the roll-out"
        )
