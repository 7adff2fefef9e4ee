"""``energy-margin record``: turn recorded MuJoCo roll-outs of a scene file's model into a dataset."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from energy_margin.cli.common import DeprecatedAlias, ProgressBar, positive_int
from energy_margin.errors import EnergyMarginError

if TYPE_CHECKING:
    from energy_margin.data.dataset import Dataset

__all__ = [
    "EXAMPLES",
    "FORMATS",
    "NAME",
    "PARAMETER_FLAGS",
    "SUMMARY",
    "add_arguments",
    "positive_float",
    "run",
]

NAME = "record"
SUMMARY = (
    "turn recorded MuJoCo roll-outs (time, qpos, qvel per .npz or HDF5 group) of a scene file's model, "
    "or robomimic demonstrations, into a dataset"
)
EXAMPLES = (
    "energy-margin record --scene my_scene.toml logs/run*.npz --frames 10 --out runs/recorded",
    "energy-margin record --format robomimic demos.hdf5 --object-bodies 'cube*' --capture JSON --success JSON "
    "--frames 10 --out runs/demos",
)
#: Keyword arguments of :func:`~energy_margin.data.record.record_dataset` named otherwise here.
PARAMETER_FLAGS = {"n_frames": "--frames", "file_format": "--format", "scene_file": "--scene"}
FORMATS = ("npz", "hdf5", "robomimic")


def positive_float(text: str) -> float:
    """A finite number > 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not 0 < value < float("inf"):
        raise argparse.ArgumentTypeError(f"expected a finite number > 0, got {text}")
    return value


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``record``."""
    parser.add_argument(
        "--scene",
        metavar="SCENE.toml",
        help="the scene file of the recorded model (required, except with --format robomimic: "
        "its objects, perturbation, bounds, capture and success tables)",
    )
    parser.add_argument(
        "rollouts",
        nargs="+",
        metavar="ROLLOUT",
        help=".npz files with time, qpos, qvel (and ctrl), HDF5 files of such groups, or one robomimic file",
    )
    parser.add_argument(
        "--format",
        choices=FORMATS,
        default=None,
        help="npz, hdf5 (a group per roll-out) or robomimic (data/demo_*/states and model_file); "
        "default: by suffix (.h5, .hdf5: hdf5; else npz)",
    )
    parser.add_argument("--frames", type=positive_int, default=10, help="frames per roll-out (default 10)")
    parser.add_argument("--out", required=True, help="dataset directory to create")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing directory")
    parser.add_argument(
        "--drop-unphysical",
        action="store_true",
        help="leave out roll-outs with a physically impossible frame (an object outside the scene's bounds or "
        "faster than bounds.max_speed), counted in dataset.json's dropped, instead of refusing them",
    )
    robomimic = parser.add_argument_group("robomimic files (--format robomimic)")
    robomimic.add_argument(
        "--object-bodies",
        "--objects",
        dest="objects",
        action=DeprecatedAlias,
        old="--objects",
        metavar="PATTERN[,PATTERN]",
        help="object body names or glob patterns, without --scene (--objects is its old name)",
    )
    robomimic.add_argument(
        "--capture", metavar="JSON", help='the capture set\'s region table, e.g. \'{"type": "box", ...}\''
    )
    robomimic.add_argument("--success", metavar="JSON", help="the success set's region table")
    robomimic.add_argument(
        "--assets", metavar="DIR", help="folder of the model's asset files (robosuite's models/assets) for moved meshes"
    )
    robomimic.add_argument(
        "--dt", type=positive_float, metavar="S", help="seconds between rows of states without the time column"
    )
    robomimic.add_argument(
        "--robot",
        choices=("recorded", "coasting", "still"),
        help="the robot during analysis: recorded follows each demonstration's own joint path (the default), "
        "coasting keeps each frame's joint velocities, still holds it where the frame has it",
    )


#: What ``record --format robomimic`` says the robot does during analysis, per ``--robot``.
_ROBOT_NOTES = {
    "still": "the robot is held still during analysis: future capture and early success miss its motion",
    "coasting": "during analysis the robot keeps each frame's joint velocities",
    "recorded": "during analysis the robot follows each demonstration's recorded joint path from the frame on",
}


def _json_table(flag: str, text: str | None) -> dict[str, Any] | None:
    """The JSON object given to ``flag``, or ``None``."""
    if text is None:
        return None
    try:
        value = json.loads(text)
    except (ValueError, RecursionError) as error:
        raise EnergyMarginError(f"{flag}: {text!r} is not valid JSON ({error})") from None
    if not isinstance(value, dict):
        raise EnergyMarginError(f"{flag}: expected a JSON object (a region table with a type), got {text!r}")
    return value


def run(args: argparse.Namespace) -> int:
    """Record the dataset and print its label rates."""
    if args.format == "robomimic":
        dataset = _run_robomimic(args)
    else:
        from energy_margin.data.record import record_dataset

        robomimic_only = [
            flag
            for flag, value in (
                ("--object-bodies", args.objects),
                ("--capture", args.capture),
                ("--success", args.success),
                ("--assets", args.assets),
                ("--dt", args.dt),
                ("--robot", args.robot),
            )
            if value is not None
        ]
        if robomimic_only:
            raise EnergyMarginError(f"{robomimic_only[0]} applies to --format robomimic only")
        if args.scene is None:
            raise EnergyMarginError("record needs --scene SCENE.toml, the scene file of the recorded model")
        bar = ProgressBar(len(args.rollouts), "record")
        try:
            dataset = record_dataset(
                args.scene,
                args.rollouts,
                n_frames=args.frames,
                out=args.out,
                overwrite=args.overwrite,
                progress=bar.update,
                file_format=args.format,
                drop_unphysical=args.drop_unphysical,
            )
        finally:
            bar.close()
    labels = dataset.arrays
    dropped = dataset.metadata.get("dropped") or []
    if dropped:
        print(
            f"left out {len(dropped)} roll-out(s) with a physically impossible frame (listed in dataset.json's "
            f"dropped; the first: {dropped[0]['rollout']}: {dropped[0]['reason']})"
        )
    print(
        f"dataset {args.out}: {dataset.n_trajectories} roll-outs x {dataset.n_frames} frames, "
        f"{dataset.n_objects} objects; captured frames {labels['captured'].mean():.2f}, "
        f"successful roll-outs {dataset.success_labels().mean():.2f}"
    )
    if args.format == "robomimic":
        from energy_margin.data.robomimic import ROBOT_DURING_ANALYSIS

        robot = args.robot or ROBOT_DURING_ANALYSIS
        print(
            "note: the demonstrations carry no commands the analysis could follow, so "
            + _ROBOT_NOTES[robot]
            + " (docs/howto/integrations.md)",
            file=sys.stderr,
        )
    return 0


def _run_robomimic(args: argparse.Namespace) -> Dataset:
    """``record --format robomimic FILE``."""
    from energy_margin.data.robomimic import record_robomimic

    if len(args.rollouts) != 1:
        raise EnergyMarginError(f"--format robomimic reads one file, got {len(args.rollouts)}")
    capture = _json_table("--capture", args.capture)
    success = _json_table("--success", args.success)
    bar = ProgressBar(0, "record", unit="demo")
    try:
        return record_robomimic(
            Path(args.rollouts[0]),
            n_frames=args.frames,
            out=args.out,
            scene_file=args.scene,
            objects=args.objects,
            capture=capture,
            success=success,
            assets=args.assets,
            dt=args.dt,
            **({"robot": args.robot} if args.robot is not None else {}),
            overwrite=args.overwrite,
            progress=bar.update,
            drop_unphysical=args.drop_unphysical,
        )
    finally:
        bar.close()
