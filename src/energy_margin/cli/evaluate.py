"""``energy-margin evaluate``: Average Precision of the scores against the labels (and Table I)."""

from __future__ import annotations

import argparse

from energy_margin.cli.common import add_seed, non_negative_int, positive_int, print_json, say_notes

__all__ = [
    "EXAMPLES",
    "NAME",
    "SUMMARY",
    "add_arguments",
    "run",
]

NAME = "evaluate"
SUMMARY = "Average Precision of a scored dataset against its labels; with --compare, Table I"
EXAMPLES = (
    "energy-margin evaluate runs/push10",
    "energy-margin evaluate runs/push10 --capture-window 2 --json",
    "energy-margin evaluate runs/push10 --explain",
    "energy-margin evaluate runs/push10 --compare runs/push10-perturbed",
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``evaluate``."""
    parser.add_argument("dataset", help="dataset directory with scores.csv")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--capture-window", type=non_negative_int, default=0, help="k-hat (default 0)")
    parser.add_argument("--success-frames", type=positive_int, default=3, help="k-bar (default 3)")
    parser.add_argument(
        "--weights", choices=("linear", "uniform"), default="linear", help="trajectory success weights (default linear)"
    )
    parser.add_argument(
        "--resamples",
        type=non_negative_int,
        default=1000,
        help="bootstrap resamples of the trajectories behind the verdict (margin - best baseline, paired "
        "interval); 0: no verdict (default 1000)",
    )
    add_seed(parser)
    parser.add_argument(
        "--explain",
        action="store_true",
        help="for each failed trajectory, list the objects that left the capture region or missed the success "
        "region, with the frame, its time and the object's position (JSON: explanations)",
    )
    parser.add_argument(
        "--compare",
        nargs="+",
        default=None,
        metavar="DIR",
        help="scored perturbed copies of the dataset (or their parent directory): print Table I",
    )


def run(args: argparse.Namespace) -> int:
    """Print the AP table (or JSON)."""
    from energy_margin.data.provenance import dataset_note, scores_note
    from energy_margin.evaluation.metrics import evaluate, format_table

    # One line: the scores' engine against the frames' when they differ, else the frames' against this one.
    say_notes(scores_note(args.dataset) or dataset_note(args.dataset))
    options = {"capture_window": args.capture_window, "success_frames": args.success_frames, "weights": args.weights}
    verdict = {"resamples": args.resamples, "seed": args.seed}
    if args.compare:
        from energy_margin.robustness.compare import compare_perturbed, format_robustness_table

        result = compare_perturbed(args.dataset, args.compare, **options, **verdict).to_dict()
        if args.explain:
            from energy_margin.data.dataset import load_dataset
            from energy_margin.evaluation.explain import explain_failures

            result["explanations"] = [item.to_dict() for item in explain_failures(load_dataset(args.dataset))]
        text = format_table(result) + "\n\n" + format_robustness_table(result)
    else:
        result = evaluate(args.dataset, **options, **verdict, explain=args.explain).to_dict()
        text = format_table(result)
    from energy_margin.data.scores_file import load_scores, tree_rejections

    rejections = tree_rejections(load_scores(args.dataset))
    if rejections is not None:
        result["tree_rejections"] = rejections
        text += (
            f"\ntree states rejected per frame: {rejections['rejected_per_frame']:.1f} outside the state box, "
            f"{rejections['diverged_per_frame']:.1f} diverged ({100 * rejections['rejected_share']:.1f}% and "
            f"{100 * rejections['diverged_share']:.1f}% of the expansions)"
        )
    if args.json:
        print_json(result)
    else:
        print(text)
    return 0
