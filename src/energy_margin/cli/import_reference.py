"""``energy-margin import-reference``: the authors' published frames, labels and scores as a dataset."""

from __future__ import annotations

import argparse

from energy_margin.data.reference import DRIVES

__all__ = [
    "EXAMPLES",
    "NAME",
    "SUMMARY",
    "add_arguments",
    "run",
]

NAME = "import-reference"
SUMMARY = "convert the authors' published frames, labels and scores into a dataset"
EXAMPLES = (
    "energy-margin import-reference ../energy_margin_workshop/planepush-10objects --out runs/ref-push",
    "energy-margin import-reference PATH --out runs/ref-push-coast --drive coast --no-scores",
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``import-reference``."""
    parser.add_argument("path", help="a task folder of the authors' data, e.g. .../planepush-10objects")
    parser.add_argument("--out", required=True, help="dataset directory to create")
    parser.add_argument(
        "--scores",
        default=None,
        metavar="SUBDIR",
        help="sub-folder of the ao_est.csv to import ('.' = the folder itself; default original/original-data)",
    )
    parser.add_argument("--no-scores", action="store_true", help="import frames and labels only")
    parser.add_argument(
        "--drive",
        choices=DRIVES,
        default="nominal",
        help=(
            "pusher during analysis: this project's nominal drive (default) or coasting as in the authors' "
            "planner (the scooping gripper always replays its recorded motion)"
        ),
    )
    parser.add_argument("--overwrite", action="store_true", help="replace an existing directory")


def run(args: argparse.Namespace) -> int:
    """Import and describe the dataset."""
    from energy_margin.data.reference import import_reference
    from energy_margin.data.scores_file import SCORES_FILE

    dataset = import_reference(
        args.path,
        args.out,
        scores=args.scores,
        with_scores=not args.no_scores,
        overwrite=args.overwrite,
        drive=args.drive,
    )
    scored = " with their scores" if (dataset.path is not None and (dataset.path / SCORES_FILE).exists()) else ""
    print(
        f"dataset {args.out}: {dataset.metadata['task']}, {dataset.n_trajectories} trajectories x "
        f"{dataset.n_frames} frames, {dataset.n_objects} objects{scored}"
    )
    return 0
