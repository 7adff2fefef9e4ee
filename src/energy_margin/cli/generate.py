"""``energy-margin generate``: record scripted roll-outs of a task as a dataset."""

from __future__ import annotations

import argparse

from energy_margin.cli.common import ProgressBar, add_engine, add_seed, add_set, scene_task_config, task_overrides
from energy_margin.tasks import available_tasks

__all__ = [
    "EXAMPLES",
    "NAME",
    "PARAMETER_FLAGS",
    "SUMMARY",
    "add_arguments",
    "run",
]

NAME = "generate"
SUMMARY = "record scripted roll-outs of a task, with their labels, as a dataset"
EXAMPLES = (
    "energy-margin generate --task pushing --objects 10 --trajectories 20 --frames 10 --seed 0 --out runs/push10",
    "energy-margin generate --scene my_scene.toml --trajectories 20 --frames 10 --seed 0 --out runs/mine",
)
#: Keyword arguments of :func:`~energy_margin.data.generate.generate_dataset` named otherwise here.
PARAMETER_FLAGS = {"n_objects": "--objects", "n_trajectories": "--trajectories", "n_frames": "--frames"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``generate``."""
    tasks = available_tasks()
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--task", choices=tasks, help=f"registered task: {', '.join(tasks)}")
    source.add_argument("--scene", metavar="SCENE.toml", help="a scene file (docs/howto/scenes.md) instead of a task")
    parser.add_argument("--objects", type=int, help="objects per scene (>= 1); a scene file fixes them")
    parser.add_argument("--trajectories", type=int, default=20, help="roll-outs (default 20)")
    parser.add_argument("--frames", type=int, default=10, help="frames per roll-out (default 10)")
    add_seed(parser)
    add_engine(parser, records=True)
    parser.add_argument("--out", required=True, help="dataset directory to create")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing directory")
    add_set(parser, "override a task setting, e.g. --set drive_jitter=0.1")


def run(args: argparse.Namespace) -> int:
    """Generate the dataset and print its label rates."""
    from energy_margin.data.generate import generate_dataset

    task, config = (
        scene_task_config(args.scene, task_overrides(args.set)) if args.scene else (args.task, task_overrides(args.set))
    )
    bar = ProgressBar(args.trajectories, "generate")
    try:
        dataset = generate_dataset(
            task,
            n_objects=args.objects,
            n_trajectories=args.trajectories,
            n_frames=args.frames,
            seed=args.seed,
            out=args.out,
            engine=args.engine,
            task_config=config,
            overwrite=args.overwrite,
            progress=bar.update,
        )
    finally:
        bar.close()
    labels = dataset.arrays
    print(
        f"dataset {args.out}: {dataset.n_trajectories} trajectories x {dataset.n_frames} frames, "
        f"{dataset.n_objects} objects; captured frames {labels['captured'].mean():.2f}, "
        f"successful trajectories {dataset.success_labels().mean():.2f}"
    )
    return 0
