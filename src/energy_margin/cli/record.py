"""``energy-margin record``: turn recorded MuJoCo roll-outs of a scene file's model into a dataset."""

from __future__ import annotations

import argparse

from energy_margin.cli.common import ProgressBar, positive_int

NAME = "record"
SUMMARY = "turn recorded MuJoCo roll-outs (time, qpos, qvel per .npz) of a scene file's model into a dataset"
EXAMPLES = ("energy-margin record --scene my_scene.toml logs/run*.npz --frames 10 --out runs/recorded",)
#: Keyword arguments of :func:`~energy_margin.data.record.record_dataset` named otherwise here.
PARAMETER_FLAGS = {"n_frames": "--frames"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``record``."""
    parser.add_argument("--scene", required=True, metavar="SCENE.toml", help="the scene file of the recorded model")
    parser.add_argument("rollouts", nargs="+", metavar="ROLLOUT", help=".npz files with time, qpos, qvel (and ctrl)")
    parser.add_argument("--frames", type=positive_int, default=10, help="frames per roll-out (default 10)")
    parser.add_argument("--out", required=True, help="dataset directory to create")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing directory")


def run(args: argparse.Namespace) -> int:
    """Record the dataset and print its label rates."""
    from energy_margin.data.record import record_dataset

    bar = ProgressBar(len(args.rollouts), "record")
    try:
        dataset = record_dataset(
            args.scene, args.rollouts, n_frames=args.frames, out=args.out, overwrite=args.overwrite, progress=bar.update
        )
    finally:
        bar.close()
    labels = dataset.arrays
    print(
        f"dataset {args.out}: {dataset.n_trajectories} roll-outs x {dataset.n_frames} frames, "
        f"{dataset.n_objects} objects; captured frames {labels['captured'].mean():.2f}, "
        f"successful roll-outs {dataset.success_labels().mean():.2f}"
    )
    return 0
