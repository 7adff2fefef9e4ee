"""``energy-margin perturb``: perception-noise copies, objects resampled inside their ellipsoid."""

from __future__ import annotations

import argparse

from energy_margin.cli.common import add_seed, non_negative_float, positive_int
from energy_margin.robustness.perturb import PROTOCOLS

__all__ = [
    "EXAMPLES",
    "NAME",
    "SUMMARY",
    "add_arguments",
    "run",
]

NAME = "perturb"
SUMMARY = "perturbed copies of a dataset: object centres resampled inside their minimum-volume ellipsoid"
EXAMPLES = (
    "energy-margin perturb runs/push10 --repeats 5 --seed 0 --out runs/push10-perturbed --workers 2",
    "energy-margin perturb runs/push10 --protocol paper --repeats 5 --seed 0 --out runs/push10-perturbed-paper",
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``perturb``."""
    parser.add_argument("dataset", help="true-state dataset directory")
    parser.add_argument("--repeats", type=positive_int, default=5, help="perturbed copies (default 5)")
    add_seed(parser)
    parser.add_argument("--out", required=True, help="parent directory of the copies OUT/1 ... OUT/R")
    parser.add_argument(
        "--protocol",
        choices=PROTOCOLS,
        default="valid",
        help="valid: physically valid states, overlaps rejected (default); paper: the authors' draw, every centre "
        "at once, overlaps allowed (docs/results/robustness.md)",
    )
    parser.add_argument(
        "--tolerance",
        type=non_negative_float,
        default=None,
        help="largest accepted penetration, m (default 5e-4; --protocol valid only)",
    )
    parser.add_argument(
        "--keep-orientation", action="store_true", help="keep recorded orientations (default: identity, as the paper)"
    )
    parser.add_argument("--overwrite", action="store_true", help="replace existing copies")
    parser.add_argument("--workers", type=positive_int, default=1, help="parallel processes (default 1)")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")


def run(args: argparse.Namespace) -> int:
    """Write the copies and list them."""
    from energy_margin.robustness.perturb import perturb_dataset

    paths = perturb_dataset(
        args.dataset,
        repeats=args.repeats,
        seed=args.seed,
        out=args.out,
        tolerance=args.tolerance,
        keep_orientation=args.keep_orientation,
        protocol=args.protocol,
        overwrite=args.overwrite,
        workers=args.workers,
        progress=not args.no_progress,
    )
    print(f"wrote {len(paths)} perturbed copies ({args.protocol} protocol): {', '.join(str(p) for p in paths)}")
    return 0
