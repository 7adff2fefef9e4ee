"""``energy-margin render``: a video of one trajectory's roll-out with its frame scores."""

from __future__ import annotations

import argparse
from pathlib import Path

from energy_margin.cli.common import ProgressBar, non_negative_int, positive_int
from energy_margin.errors import EnergyMarginError

__all__ = [
    "EXAMPLES",
    "NAME",
    "SUMMARY",
    "add_arguments",
    "run",
]

NAME = "render"
SUMMARY = "render a trajectory's roll-out as a video (MP4, or GIF) with its capture and success scores"
EXAMPLES = (
    "energy-margin render runs/push10 --trajectory 0",
    "energy-margin render runs/scoop5 --trajectory 2 --out scoop.gif --fps 15",
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``render``."""
    parser.add_argument("dataset", help="a generated dataset directory (scores.csv, when present, is overlaid)")
    parser.add_argument("--trajectory", type=non_negative_int, required=True, help="trajectory index")
    parser.add_argument("--out", default=None, help="video file, .mp4 or .gif (default DATASET/trajectory-T.mp4)")
    parser.add_argument("--fps", type=positive_int, default=30, help="pictures per second of simulated time (30)")
    parser.add_argument("--width", type=positive_int, default=640, help="width in pixels (640; MP4: multiple of 16)")
    parser.add_argument("--height", type=positive_int, default=480, help="height in pixels with the score strip (480)")


def run(args: argparse.Namespace) -> int:
    """Run the roll-out again, draw it and write the video."""
    from energy_margin.data.dataset import load_dataset
    from energy_margin.data.scores_file import SCORES_FILE, load_scores
    from energy_margin.report.render import warn_once
    from energy_margin.report.video import render_video, video_steps

    try:
        import imageio  # noqa: F401
        import PIL  # noqa: F401
    except ImportError:
        raise EnergyMarginError("videos need imageio and Pillow: pip install 'energy-margin[render]'") from None
    dataset = load_dataset(args.dataset)
    scores = None
    if (Path(args.dataset) / SCORES_FILE).is_file():
        scores = load_scores(args.dataset)
    else:
        warn_once(f"{args.dataset} has no {SCORES_FILE}: the video shows no scores (run energy-margin analyze)")
    out = Path(args.out) if args.out else Path(args.dataset) / f"trajectory-{args.trajectory}.mp4"
    config = dataset.task.config
    total = len(video_steps(config.duration, config.timestep, args.fps))
    bar = ProgressBar(total, "render", unit="picture")
    try:
        result = render_video(
            dataset,
            args.trajectory,
            out,
            scores=scores,
            fps=float(args.fps),
            width=args.width,
            height=args.height,
            progress=bar.update,
        )
    finally:
        bar.close()
    print(
        f"video: {result.path} ({result.frames} pictures, {result.width} x {result.height}, {result.seconds:.2f} s "
        f"at {result.fps:g} fps; drawn in {result.render_s:.1f} s by {result.backend}, {result.total_s:.1f} s in all)"
    )
    return 0
