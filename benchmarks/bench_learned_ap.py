"""Learned margins against the tree on analysed datasets they were not fitted on: AP with paired intervals.

Usage::

    python benchmarks/bench_learned_ap.py DIR [DIR ...] --model MODEL [--model MODEL2 ...]
        [--resamples 1000] [--seed 0] [--json]

Each DIR is an analysed dataset (``scores.csv`` of a tree analysis) that no model was fitted on
(another generation seed, or a held-out split written as its own dataset). For every dataset and
model this script predicts the capture and success scores of every frame
(``MarginModel.predict``) and asks the questions ``evaluate`` asks of both the tree's scores and
the learned ones: capture at k̂ = 0, 2 and 4, success from the last 3 frames and from the first 3
and first 5 frames (all with the linear weights of ``evaluate``). Each row gives the learned AP,
the tree's AP and learned − tree with a 95 % paired bootstrap interval over whole trajectories
(the same resamples for both), and R² of both scores against the tree's.
"""

from __future__ import annotations

import argparse
import json
from typing import Any

import numpy as np

from energy_margin.data.dataset import load_dataset
from energy_margin.data.scores_file import load_scores
from energy_margin.evaluation.bootstrap import Questions, paired_difference, score_questions
from energy_margin.evaluation.metrics import score_grid
from energy_margin.learning.margin_model import load_margin_model

#: Capture look-aheads k̂ and success spans (first frame, end) asked, by question name.
CAPTURE_WINDOWS = {"capture k̂=0": 0, "capture k̂=2": 2, "capture k̂=4": 4}
SUCCESS_SPANS = {"success, last 3": (None, None), "success, first 3": (0, 3), "success, first 5": (0, 5)}


def _r2(truth: np.ndarray, predicted: np.ndarray) -> float | None:
    variance = float(np.var(truth))
    return None if variance < 1e-12 else 1.0 - float(np.mean((predicted - truth) ** 2)) / variance


def compare(path: str, model_path: str, *, resamples: int, seed: int) -> dict[str, Any]:
    """One dataset and one model: every question's APs and paired difference, and R² of both scores."""
    dataset = load_dataset(path)
    model = load_margin_model(model_path, task_name=dataset.metadata["task"])
    model.check_dataset(dataset)
    scores = load_scores(path)
    tree_capture = score_grid(dataset, scores, "capture_score")
    tree_success = score_grid(dataset, scores, "success_score")
    frames = [dataset.frame(t, k) for t in range(dataset.n_trajectories) for k in range(dataset.n_frames)]
    capture, success = model.predict(dataset.task, frames)
    shape = (dataset.n_trajectories, dataset.n_frames)
    capture, success = capture.reshape(shape), success.reshape(shape)
    windows = {name: window for name, window in CAPTURE_WINDOWS.items() if window < dataset.n_frames}
    questions = Questions(dataset, success_frames=3, capture_windows=windows, success_spans=SUCCESS_SPANS)
    draws = np.random.default_rng(seed).integers(0, dataset.n_trajectories, size=(resamples, dataset.n_trajectories))
    learned = score_questions(questions, capture, success, draws)
    tree = score_questions(questions, tree_capture, tree_success, draws)
    difference = paired_difference(learned, tree)
    return {
        "dataset": str(path),
        "model": str(model_path),
        "kind": model.kind,
        "n_trajectories": dataset.n_trajectories,
        "questions": {
            name: {
                "learned": learned.point[name],
                "tree": tree.point[name],
                "difference": difference[name],
                "low": difference[f"{name}_low"],
                "high": difference[f"{name}_high"],
            }
            for name in questions.names
        },
        "r2_capture": _r2(tree_capture, capture),
        "r2_success": _r2(tree_success, success),
    }


def _cell(entry: dict[str, Any]) -> str:
    if entry["learned"] is None:
        return "– (one class)"
    low, high = entry["low"], entry["high"]
    interval = "" if low is None else f" [{low:+.3f}, {high:+.3f}]"
    return f"{entry['learned']:.3f} / {entry['tree']:.3f} ({entry['difference']:+.3f}{interval})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("datasets", nargs="+")
    parser.add_argument("--model", action="append", required=True)
    parser.add_argument("--resamples", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    rows = [
        compare(path, model, resamples=args.resamples, seed=args.seed) for path in args.datasets for model in args.model
    ]
    if args.json:
        print(json.dumps(rows, indent=1))
        return
    names = [*CAPTURE_WINDOWS, *SUCCESS_SPANS]
    print(f"learned / tree (learned − tree [95 % paired interval], {args.resamples} trajectory resamples)")
    print("| dataset | model | T | " + " | ".join(names) + " | R² capture / success |")
    print("|---|---|---:|" + "---:|" * len(names) + "---:|")
    for row in rows:
        cells = [_cell(row["questions"][name]) if name in row["questions"] else "–" for name in names]
        r2 = "/".join("–" if value is None else f"{value:.3f}" for value in (row["r2_capture"], row["r2_success"]))
        print(f"| {row['dataset']} | {row['kind']} | {row['n_trajectories']} | " + " | ".join(cells) + f" | {r2} |")


if __name__ == "__main__":
    main()
