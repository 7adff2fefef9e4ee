"""``energy-margin monitor``: a failure alarm calibrated on successful roll-outs, margin against distance."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from energy_margin.cli.common import add_seed, non_negative_int, positive_int, print_json
from energy_margin.errors import EnergyMarginError

__all__ = [
    "EXAMPLES",
    "NAME",
    "PARAMETER_FLAGS",
    "SUMMARY",
    "add_arguments",
    "run",
]

NAME = "monitor"
SUMMARY = "calibrate a failure alarm on the successes of one scored dataset (conformal), test it on another"
EXAMPLES = (
    "energy-margin monitor runs/calib runs/test --alpha 0.05 0.1",
    "energy-margin monitor runs/calib runs/test --score success --start-frame 4 --save alarm.json --json",
    "energy-margin monitor runs/calib runs/test --persistence 3",
    "energy-margin monitor runs/calib runs/test --select runs/select",
)

#: Keyword arguments of the library named by another option.
PARAMETER_FLAGS = {"alphas": "--alpha", "selection": "--select"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``monitor``."""
    from energy_margin.evaluation.monitor import SCORES

    parser.add_argument("calibration", help="scored dataset directory whose successful trajectories calibrate")
    parser.add_argument("test", help="scored dataset directory the alarm is tested on")
    parser.add_argument(
        "--alpha",
        type=float,
        nargs="+",
        default=[0.05, 0.1],
        help="false-alarm rates to guarantee on successful roll-outs, each in (0, 1) (default 0.05 0.1)",
    )
    parser.add_argument(
        "--score",
        choices=SCORES,
        default="success",
        help="the per-frame score watched: success, capture or their minimum (default success)",
    )
    parser.add_argument("--start-frame", type=non_negative_int, default=0, help="first monitored frame (default 0)")
    parser.add_argument(
        "--persistence",
        type=positive_int,
        default=1,
        help="alarm at the Mth monitored frame below the threshold, calibrated to match (default 1: the first)",
    )
    parser.add_argument(
        "--select",
        metavar="DATASET",
        default=None,
        help="a third scored dataset on which to choose each alarm's score, start frame and persistence (1 to 3), "
        "instead of --score, --start-frame and --persistence",
    )
    parser.add_argument(
        "--resamples",
        type=positive_int,
        default=1000,
        help="bootstrap resamples of the test trajectories behind the intervals (default 1000)",
    )
    add_seed(parser)
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument(
        "--save", metavar="FILE", default=None, help="write the margin's calibrations (one per --alpha) to FILE"
    )


def _capture_gated(dataset: str) -> bool:
    """Whether ``dataset`` holds only gated capture scores.

    That is, it was analysed with capture gated by the frame's own state, and its scores file was
    written before the tree's own capture score was kept beside the gated one.
    """
    from energy_margin.analysis.run import recorded_analyzer
    from energy_margin.data.scores_file import CONFIG_FILE, load_scores
    from energy_margin.evaluation.monitor import tree_capture_known

    try:
        record = json.loads((Path(dataset) / CONFIG_FILE).read_text(encoding="utf-8"))
        scores = load_scores(dataset)
    except (OSError, ValueError, EnergyMarginError):
        return False
    analyzer = record.get("analyzer") if isinstance(record, dict) else None
    gated = isinstance(analyzer, dict) and recorded_analyzer(analyzer).get("capture_gate") == "current"
    return gated and not tree_capture_known(scores)


def run(args: argparse.Namespace) -> int:
    """Print the table (or JSON); write the calibration file when asked."""
    from energy_margin.evaluation.monitor import MonitorCalibration, write_calibration
    from energy_margin.evaluation.monitor_report import compare_monitors, format_table

    result = compare_monitors(
        args.calibration,
        args.test,
        alphas=tuple(args.alpha),
        score=args.score,
        start_frame=args.start_frame,
        persistence=args.persistence,
        selection=args.select,
        resamples=args.resamples,
        seed=args.seed,
    )
    if args.save:
        margin = [MonitorCalibration.from_dict(entry) for entry in result.calibrations if entry["scorer"] == "margin"]
        write_calibration(args.save, margin)
    watching = sorted({entry["score"] for entry in result.calibrations if entry["scorer"] == "margin"} - {"success"})
    if watching and _capture_gated(args.calibration):
        print(
            f"note: the margin alarm watches {' and '.join(watching)}, and {args.calibration} was analysed with "
            "capture gated (0 on a frame already out of its region), which lowers the threshold where a successful "
            "roll-out leaves its region for a moment; for a capture alarm, analyse it again (--overwrite) to keep "
            "the tree's own capture score",
            file=sys.stderr,
        )
    if args.json:
        print_json(result.to_dict())
    else:
        print(format_table(result))
        if args.save:
            print(f"wrote {args.save}")
    return 0
