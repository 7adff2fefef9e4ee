"""Learning curve of a learned margin: held-out AP against analysed frames, random or actively selected.

Usage::

    python benchmarks/bench_learning_curve.py DIR... [--kind boosting] [--sizes 50,100,200,400,800]
        [--strategies random,uncertainty] [--seed 0] [--holdout 0.25] [--success-frames 3]
        [--initial N] [--ensemble 4] [--ensemble-rounds 40] [--random-fraction 0.25] [--batch N]
        [--tolerance 0.02] [--options JSON] [--repeats 1] [--json]

Each DIR is an analysed dataset (``scores.csv`` beside it), all of one task. For every strategy,
:func:`energy_margin.learning.curve.learning_curve` fits the margin (``--kind``, regressor options
from ``--options``, e.g. ``'{"max_iter": 100}'``) on the first N frames the strategy selects from
the training pool, for every N of ``--sizes``, and scores it on the held-out trajectories (fixed by
``--seed`` and ``--holdout``, as ``energy-margin learn`` holds them out). The protocol (a pool of
already analysed frames whose scores are revealed once selected) is in that module's docstring.

It prints one row per strategy and size: frames used (= trees grown), trajectories touched, the
held-out AP of capture (k-hat 0 and 2, per frame) and of trajectory success (last
``--success-frames`` frames, and first half only), each ``learned/tree``, R² of both scores, and the
seconds of the reported fit and of the selection so far; then a ``pool`` row, the fit on the whole
training pool (the model ``energy-margin learn`` fits); then, per strategy, the fewest frames from
which the curve stays within ``--tolerance`` of the pool row's learned AP on every question.

With ``--repeats R`` it does all that for the seeds ``--seed`` .. ``--seed + R - 1`` (each its own
held-out split, pool order and ensembles) and prints the mean of every number over the seeds
(an AP that is undefined for some seed is averaged over the others), then the frames needed of
each seed: one seed's 30-odd held-out trajectories make the trajectory-success AP noisy.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from typing import Any

from energy_margin.errors import EnergyMarginError
from energy_margin.learning.curve import QUESTIONS, STRATEGIES, CurvePoint, frames_needed, learning_curve
from energy_margin.learning.margin_model import load_training_datasets

HEADINGS = {
    "capture": "capture k̂=0",
    "capture_window2": "capture k̂=2",
    "success": "success last {k}",
    "success_first_half": "success 1st half",
}


def integers(text: str) -> list[int]:
    return [int(part) for part in text.split(",") if part.strip()]


def names(text: str) -> list[str]:
    return [part.strip() for part in text.split(",") if part.strip()]


def measure(args: argparse.Namespace, seed: int) -> dict[str, Any]:
    datasets = load_training_datasets(args.datasets)
    options = json.loads(args.options) if args.options else {}
    active = {
        "initial": args.initial,
        "ensemble": args.ensemble,
        "ensemble_rounds": args.ensemble_rounds,
        "random_fraction": args.random_fraction,
        "batch": args.batch,
    }
    curves = []
    reference: CurvePoint | None = None
    for strategy in args.strategies:
        curve = learning_curve(
            datasets,
            kind=args.kind,
            sizes=args.sizes,
            strategy=strategy,
            seed=seed,
            holdout=args.holdout,
            success_frames=args.success_frames,
            reference=reference is None,
            **(active if strategy == "uncertainty" else {}),
            **options,
        )
        reference = curve.reference if reference is None else reference
        curves.append(curve)
    assert reference is not None
    needed = {curve.strategy: frames_needed(curve, reference, tolerance=args.tolerance) for curve in curves}
    return {
        "seed": seed,
        "curves": [curve.to_dict() for curve in curves],
        "reference": reference.to_dict(),
        "frames_needed": needed,
    }


def mean(values: list[Any]) -> Any:
    """The mean of numbers (``None`` left out), or of dicts and lists of dicts entry by entry; else the first."""
    first = values[0]
    if isinstance(first, dict):
        return {key: mean([value[key] for value in values]) for key in first}
    if isinstance(first, list) and first and isinstance(first[0], dict):
        return [mean(list(items)) for items in zip(*values, strict=True)]
    if isinstance(first, int | float | type(None)) and not isinstance(first, bool):
        numbers = [value for value in values if value is not None]
        if len(set(numbers)) <= 1:  # a setting (the same for every seed) keeps its type
            return numbers[0] if numbers else None
        return sum(numbers) / len(numbers)
    return first


def run(args: argparse.Namespace) -> dict[str, Any]:
    import sklearn.ensemble  # noqa: F401  (imported before any fit is timed)

    started = time.perf_counter()
    runs = [measure(args, args.seed + repeat) for repeat in range(args.repeats)]
    return {
        "datasets": [str(path) for path in args.datasets],
        "kind": args.kind,
        "seeds": [item["seed"] for item in runs],
        "tolerance": args.tolerance,
        "runs": runs,
        "mean": {
            "curves": mean([item["curves"] for item in runs]),
            "reference": mean([item["reference"] for item in runs]),
        },
        "seconds": time.perf_counter() - started,
        "machine": f"{platform.machine()}, {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f}",
    }


def number(value: float | None) -> str:
    return "  -  " if value is None else f"{value:.3f}"


def row(label: str, point: dict[str, Any]) -> str:
    aps = "  ".join(
        f"{number(point['ap'][q]['learned'])}/{number(point['ap'][q]['tree'])}".center(len(HEADINGS[q]) + 1)
        for q in QUESTIONS
    )
    return (
        f"{label:<12} {point['frames']:6.0f} {point['trajectories']:5.0f}  {aps}  {number(point['r2']['capture'])}"
        f"  {number(point['r2']['success'])}  {point['fit_seconds']:6.2f} {point['selection_seconds']:7.2f}"
    )


def print_table(result: dict[str, Any]) -> None:
    table = result["mean"]
    first = table["curves"][0]
    seeds = result["seeds"]
    print(
        f"{first['kind']} learned margin on {', '.join(result['datasets'])}; "
        f"{'seed ' + str(seeds[0]) if len(seeds) == 1 else f'mean over seeds {seeds[0]}..{seeds[-1]}'}; "
        f"pool {first['pool_frames']} frames of {first['pool_trajectories']} trajectories, held out "
        f"{first['held_out_frames']} frames of {len(result['runs'][0]['curves'][0]['held_out'])} trajectories; "
        f"{result['machine']}"
    )
    for curve in table["curves"]:
        if curve["strategy"] == "uncertainty":
            print(
                f"uncertainty: {curve['initial']} random frames first, ensemble of {curve['ensemble']} x "
                f"{curve['ensemble_rounds']} rounds, random fraction {curve['random_fraction']}, "
                f"batch {curve['batch'] or 'up to the next size'}"
            )
    headings = "  ".join(HEADINGS[q].format(k=first["success_frames"]).center(len(HEADINGS[q]) + 1) for q in QUESTIONS)
    print("AP learned/tree on the held-out trajectories")
    print(f"{'strategy':<12} {'frames':>6} {'traj':>5}  {headings}  R²cap  R²suc  fit s  select s")
    for curve in table["curves"]:
        for point in curve["points"]:
            print(row(curve["strategy"], point))
    print(row("pool", table["reference"]))
    print(f"frames to come within {result['tolerance']} of the pool fit on every question (and stay there):")
    for strategy in (curve["strategy"] for curve in table["curves"]):
        needed = [item["frames_needed"][strategy] for item in result["runs"]]
        print(f"  {strategy}: {', '.join('not reached' if value is None else str(value) for value in needed)}")
    print(f"total {result['seconds']:.0f} s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("datasets", nargs="+")
    parser.add_argument("--kind", default="boosting")
    parser.add_argument("--sizes", type=integers, default=[50, 100, 200, 400, 800])
    parser.add_argument("--strategies", type=names, default=list(STRATEGIES))
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--holdout", type=float, default=0.25)
    parser.add_argument("--success-frames", type=int, default=3)
    parser.add_argument("--initial", type=int, default=None)
    parser.add_argument("--ensemble", type=int, default=4)
    parser.add_argument("--ensemble-rounds", type=int, default=40)
    parser.add_argument("--random-fraction", type=float, default=0.25)
    parser.add_argument("--batch", type=int, default=None)
    parser.add_argument("--tolerance", type=float, default=0.02)
    parser.add_argument("--options", default=None, help="regressor options as JSON")
    parser.add_argument("--repeats", type=int, default=1, help="seeds --seed .. --seed + repeats - 1")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    try:
        result = run(args)
    except EnergyMarginError as error:  # a bad argument or dataset: one line, exit status 2
        parser.error(str(error))
    if args.json:
        print(json.dumps(result, sort_keys=True))
        return
    print_table(result)


if __name__ == "__main__":
    main()
