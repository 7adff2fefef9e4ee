"""One example's row of docs/results/generality.md: the margin with the file's, derived and calibrated settings.

Given a dataset generated from an example's scene file as written, and the same trajectories generated
from the same file with its ``[perturbation]`` table left out (so every perturbation setting is derived
from the scene, tasks/scene_defaults.py), this

* runs ``calibrate`` on the first (resumable, under ``WORK/calibration``): the scores at the file's
  own settings, and the held-out scores (each trajectory at the λ chosen without it);
* runs ``analyze`` on the second (the derived settings);
* prints, for each of the three, capture AP at k̂ = 0, 2, 4 and early success from the first 3 and
  the first 5 frames (k̄ = 3), beside the current-state and distance baselines, each with the margin
  minus the best baseline, a paired 95 % bootstrap interval over trajectories and the word.

    python benchmarks/bench_generality.py jaco runs/g-jaco runs/g-jaco-derived --work runs/g-jaco-work \\
        --workers 2 --json runs/g-jaco.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.cli import main as cli_main
from energy_margin.data.dataset import load_dataset
from energy_margin.data.scores_file import load_scores
from energy_margin.evaluation.baselines import baseline_grids
from energy_margin.evaluation.bootstrap import Questions
from energy_margin.evaluation.calibration import calibrate
from energy_margin.evaluation.metrics import score_grid
from energy_margin.evaluation.verdict import verdicts

QUESTIONS = ("capture k̂ = 0", "capture k̂ = 2", "capture k̂ = 4", "success, first 3", "success, first 5")


def questions_of(dataset: Any) -> Questions:
    """Capture at k̂ = 0, 2, 4 and success from the first 3 and 5 frames (k̄ = 3, linear weights)."""
    return Questions(
        dataset,
        3,
        capture_windows={QUESTIONS[0]: 0, QUESTIONS[1]: 2, QUESTIONS[2]: 4},
        success_spans={QUESTIONS[3]: (0, 3), QUESTIONS[4]: (0, 5)},
    )


def _fold_lambdas(folds: list[dict[str, Any]]) -> str:
    return ", ".join(f"{fold['likelihood_lambda']:g}" for fold in folds)


def _cell(verdict: Any, value: float | None) -> str:
    if value is None:
        return "n/a"
    if verdict.difference is None or verdict.low is None or verdict.high is None:
        return f"{value:.3f}"
    return (
        f"{value:.3f} ({verdict.word} {verdict.difference:+.3f} [{verdict.low:+.3f}, {verdict.high:+.3f}], "
        f"{verdict.baseline})"
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("name", help="the example's name in the table")
    parser.add_argument("dataset", type=Path, help="generated from the example's scene file as written")
    parser.add_argument("derived", type=Path, help="the same trajectories from the file without [perturbation]")
    parser.add_argument("--work", type=Path, required=True, help="directory of the calibration run")
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--expansions", type=int, default=300, help="expansions per frame (default 300)")
    parser.add_argument("--resamples", type=int, default=1000)
    parser.add_argument("--json", type=Path, help="also write the rows as JSON here")
    parser.add_argument(
        "--variant",
        action="append",
        default=[],
        metavar="LABEL=DIR",
        help="another dataset of the same trajectories (e.g. other [perturbation] values) to analyse and add",
    )
    args = parser.parse_args(argv)

    started = time.perf_counter()
    config = AnalyzerConfig(expansions=args.expansions)
    calibration = calibrate(args.dataset, args.work / "calibration", config=config, workers=args.workers, seed=0)
    calibrate_seconds = time.perf_counter() - started
    extra = dict(item.split("=", 1) for item in args.variant)
    derived_seconds = 0.0
    for directory in (args.derived, *(Path(path) for path in extra.values())):
        if not (directory / "scores.csv").exists():
            started = time.perf_counter()
            code = cli_main(
                # The tree's own success score, as calibrate scores the calibrated side.
                [
                    "analyze",
                    str(directory),
                    "--expansions",
                    str(args.expansions),
                    "--workers",
                    str(args.workers),
                    "--continuation",
                    "0",
                ]
            )
            if code:
                return code
            if directory == args.derived:
                derived_seconds = time.perf_counter() - started

    dataset = load_dataset(args.dataset)
    derived = load_dataset(args.derived)
    others = {label: load_dataset(path) for label, path in extra.items()}
    for other_path, other in ((args.derived, derived), *((Path(extra[label]), data) for label, data in others.items())):
        for name in ("success", "capture"):
            mine = dataset.success_labels() if name == "success" else dataset.capture_labels(0)
            theirs = other.success_labels() if name == "success" else other.capture_labels(0)
            if not np.array_equal(mine, theirs):
                sys.exit(f"{other_path} does not hold the trajectories of {args.dataset} ({name} labels differ)")
    derived_scores = load_scores(args.derived)
    assert calibration.default_scores is not None and calibration.held_out_scores is not None
    variants = {
        f"the file's (λ {calibration.default_lambda:g})": calibration.default_scores,
        f"derived (λ {derived.task.config.likelihood_lambda:.3g})": (
            score_grid(derived, derived_scores, "capture_score"),
            score_grid(derived, derived_scores, "success_score"),
        ),
        f"calibrated (λ {_fold_lambdas(calibration.folds)} by fold)": calibration.held_out_scores,
    }
    for label, other in others.items():
        other_scores = load_scores(Path(extra[label]))
        variants[f"{label} (λ {other.task.config.likelihood_lambda:.3g})"] = (
            score_grid(other, other_scores, "capture_score"),
            score_grid(other, other_scores, "success_score"),
        )
    questions = questions_of(dataset)
    baselines = baseline_grids(dataset)
    every = np.arange(dataset.n_trajectories)
    rows: list[dict[str, Any]] = []
    print(f"| example | settings | {' | '.join(QUESTIONS)} |")
    print("|---|---|" + "---:|" * len(QUESTIONS))
    for variant, scores in variants.items():
        answers = questions.answer(*scores, every)
        found = verdicts(
            dataset,
            scores,
            baselines,
            capture_window=0,
            success_frames=3,
            weights="linear",
            resamples=args.resamples,
            seed=0,
            questions=questions,
        )
        cells = [_cell(found[question], answers[question]) for question in QUESTIONS]
        print(f"| {args.name} | {variant} | {' | '.join(cells)} |")
        rows.append(
            {
                "settings": variant,
                "ap": answers,
                "verdict": {question: found[question].to_dict() for question in QUESTIONS},
            }
        )
    baseline_rows = {name: questions.answer(*scores, every) for name, scores in baselines.items()}
    for name, answers in baseline_rows.items():
        values = " | ".join("n/a" if answers[q] is None else f"{answers[q]:.3f}" for q in QUESTIONS)
        print(f"| {args.name} | baseline: {name} | {values} |")
    success_rate = float(np.mean(dataset.success_labels()))
    print(
        f"{dataset.n_trajectories} trajectories x {dataset.n_frames} frames; success rate {success_rate:.2f}; "
        f"calibrate {calibrate_seconds:.0f} s (chosen lambda {calibration.likelihood_lambda:g}), "
        f"derived analysis {derived_seconds:.0f} s, {args.workers} workers"
    )
    if args.json:
        args.json.write_text(
            json.dumps(
                {
                    "example": args.name,
                    "trajectories": dataset.n_trajectories,
                    "frames": dataset.n_frames,
                    "success_rate": success_rate,
                    "rows": rows,
                    "baselines": baseline_rows,
                    "calibrate_seconds": calibrate_seconds,
                    "derived_seconds": derived_seconds,
                    "chosen_lambda": calibration.likelihood_lambda,
                },
                indent=2,
            )
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
