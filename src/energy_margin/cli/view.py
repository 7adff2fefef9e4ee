"""``energy-margin view``: an interactive 3-D view of one frame's energy-cost field (one HTML file)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from energy_margin.cli.common import non_negative_int

__all__ = [
    "EXAMPLES",
    "NAME",
    "PARAMETER_FLAGS",
    "SUMMARY",
    "add_arguments",
    "run",
]

NAME = "view"
SUMMARY = "write an interactive 3-D view of one analysed frame's tree (self-contained HTML, no server)"
EXAMPLES = (
    "energy-margin view runs/push10 --trajectory 0 --frame 5",
    "energy-margin view runs/push10 --trajectory 3 --frame 0 --out frame.html",
)
#: Keyword arguments of :func:`~energy_margin.report.frame_tree.analysed_tree` named otherwise here.
PARAMETER_FLAGS = {"frame_index": "--frame"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``view``."""
    parser.add_argument("dataset", help="an analysed dataset directory (with scores.csv and analysis.json)")
    parser.add_argument("--trajectory", type=non_negative_int, required=True, help="trajectory index")
    parser.add_argument("--frame", type=non_negative_int, required=True, help="frame index within the trajectory")
    parser.add_argument("--out", default=None, help="HTML file (default DATASET/view-T<t>-F<k>.html)")


def run(args: argparse.Namespace) -> int:
    """Grow the frame's tree again as the analysis did and write the view."""
    from energy_margin.report.frame_tree import analysed_tree
    from energy_margin.report.view import write_view

    tree = analysed_tree(args.dataset, args.trajectory, args.frame)
    if not tree.matches_stored:
        print(
            f"warning: the grown tree scores capture {tree.scores.capture_score:.6f}, success "
            f"{tree.scores.success_score:.6f}; scores.csv has {tree.stored['capture_score']:.6f}, "
            f"{tree.stored['success_score']:.6f} (another engine or package version?)",
            file=sys.stderr,
        )
    out = Path(args.out) if args.out else Path(args.dataset) / f"view-T{args.trajectory}-F{args.frame}.html"
    write_view(tree, out)
    print(f"view: {out} ({tree.field.nodes} nodes)")
    return 0
