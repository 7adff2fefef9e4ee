"""The failure alarm on live scores: Gymnasium's Pusher scored by the wrapper, the margin against the distance check.

Runs ``examples/gymnasium_pusher/live_scores.py`` three times on disjoint environment seeds, each
run its episodes scored live by ``MarginWrapper`` (``--policy-continuation K``: the success
score continued under the policy, the wrapper's way with a policy; 0: the tree's own) and kept as
a dataset whose ``scores.csv`` holds the live calls:

* the *selection* run picks, per alarm (margin, distance) and alpha, the watched score, first
  monitored call and persistence (``monitor_select.select_alarm``, as ``benchmarks/monitor.py``);
* the *calibration* run's successful episodes calibrate it (split-conformal);
* the *test* run, the example's reported seeds, measures detection, lead time and the realised
  false-alarm rate with 95 % bootstrap intervals.

The margin's calibration is also made from the calibration run's scores file read back as each
episode's calls (``evaluation.live_calibration.calibrate_episodes``), and must give the same
threshold (``live_calibration_agrees``): calibrating on a live dataset is calibrating on its calls.
A run whose ``results.json`` is in ``--work`` is reused. The live budget is wall-clock: the scores
depend on the machine's load, which the document records.

    python benchmarks/live_monitor.py --work runs/live_monitor --out docs/figures/live_monitor_pusher.json
"""

from __future__ import annotations

import importlib.util
import json
import math
import os
import sys
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.data.dataset import load_dataset
from energy_margin.data.scores_file import load_scores
from energy_margin.errors import InvalidParameterError
from energy_margin.evaluation.live_calibration import calibrate_episodes
from energy_margin.evaluation.monitor import MonitorCalibration, calibrate_monitor
from energy_margin.evaluation.monitor_report import evaluate_monitor
from energy_margin.evaluation.monitor_select import select_alarm
from energy_margin.runs.versions import engine_versions
from results_document import document_head, work_arguments, write_document

__all__ = ["ALPHAS", "episodes_of", "main"]

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "gymnasium_pusher" / "live_scores.py"
ALPHAS = (0.05, 0.1)
#: Beside each run: the load average when its episodes were scored (a reused run keeps its own).
LOAD_FILE = "load_average.json"


def _example() -> Any:
    """The example's module (loaded from its file)."""
    spec = importlib.util.spec_from_file_location("gymnasium_pusher_live_scores", EXAMPLE)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def episodes_of(scores: dict[str, np.ndarray]) -> list[list[dict[str, float]]]:
    """A scores file's rows as the live calls of each episode (trajectory), in frame order."""
    order = np.lexsort((scores["frame"], scores["trajectory"]))
    episodes: dict[int, list[dict[str, float]]] = {}
    for row in order.tolist():
        call = {name: float(scores[name][row]) for name in ("capture_score", "success_score", "tree_capture_score")}
        episodes.setdefault(int(scores["trajectory"][row]), []).append(call)
    return [episodes[key] for key in sorted(episodes)]


def _run(out: Path, env_seed: int, episodes: int, continuation: int, seed: int) -> Path:
    """The example's run into ``out`` (reused when its ``results.json`` is there): its dataset directory.

    A new run leaves the 1-minute load average at its end in ``load_average.json`` beside it.
    """
    if not (out / "results.json").is_file():
        _example().main(["--episodes", str(episodes), "--env-seed", str(env_seed), "--out", str(out),
                         "--policy-continuation", str(continuation), "--seed", str(seed)])  # fmt: skip
        (out / LOAD_FILE).write_text(json.dumps({"load_average": os.getloadavg()[0]}) + "\n")
    return out / "dataset"


def _load_average(dataset: Path) -> float | None:
    """The load average at the end of the run that scored ``dataset`` (``None``: not recorded)."""
    path = dataset.parent / LOAD_FILE
    return float(json.loads(path.read_text())["load_average"]) if path.is_file() else None


def _success_labels(dataset: Path) -> np.ndarray:
    """The success label of each episode of a run's dataset, shape (episodes,)."""
    return load_dataset(dataset).success_labels()


def _agrees(found: MonitorCalibration, calibration_set: Path) -> bool:
    """Whether the calibration run's scores file, read back as each episode's calls, gives the same calibration."""
    labels = _success_labels(calibration_set)
    live = calibrate_episodes(episodes_of(load_scores(calibration_set)), labels, alpha=found.alpha, score=found.score,
                              start_frame=found.start_frame, persistence=found.persistence)  # fmt: skip
    return math.isclose(live.threshold, found.threshold) and live.rank == found.rank


def main() -> None:
    parser = work_arguments(__doc__, workers=False)
    parser.add_argument("--policy-continuation", type=int, default=4, metavar="K")
    parser.add_argument("--selection-seed", type=int, default=3000, help="environment seed of selection episode 0")
    parser.add_argument("--calibration-seed", type=int, default=4000, help="environment seed of calibration episode 0")
    parser.add_argument("--test-seed", type=int, default=1000, help="environment seed of test episode 0 (reported)")
    parser.add_argument("--episodes", type=int, nargs=3, default=[60, 80, 50], metavar=("SELECT", "CALIBRATE", "TEST"))
    parser.add_argument("--seed", type=int, default=0, help="the example's --seed (trees, torque noise)")
    parser.add_argument("--resamples", type=int, default=1000)
    args = parser.parse_args()
    seeds = {"selection": args.selection_seed, "calibration": args.calibration_seed, "test": args.test_seed}
    paths = {
        role: _run(args.work.resolve() / role, seeds[role], count, args.policy_continuation, args.seed)
        for role, count in zip(seeds, args.episodes, strict=True)
    }
    loads = [_load_average(path) for path in paths.values()]
    document: dict[str, Any] = {
        **document_head("live_monitor.py"),
        "environment": "Pusher-v5",
        "policy_continuation": args.policy_continuation,
        "seeds": seeds,
        "episodes": dict(zip(seeds, args.episodes, strict=True)),
        # The highest 1-minute load average at the end of the three runs that scored the episodes.
        "load_average": None if None in loads else max(loads),  # type: ignore[type-var]
        "versions": engine_versions(),
    }
    for role, path in paths.items():
        document[f"{role}_success_rate"] = float(np.mean(_success_labels(path)))
    for alpha in ALPHAS:
        per_scorer: dict[str, Any] = {}
        for scorer in ("margin", "distance"):
            try:
                best = select_alarm(paths["selection"], alpha=alpha, scorer=scorer)
                found = calibrate_monitor(paths["calibration"], alpha=alpha, scorer=scorer, score=best.score,
                                          start_frame=best.start_frame, persistence=best.persistence)  # fmt: skip
            except InvalidParameterError as error:
                per_scorer[scorer] = {"refused": str(error)}
                continue
            result = evaluate_monitor(found, paths["test"], resamples=args.resamples, seed=args.seed)
            per_scorer[scorer] = {**result.to_dict(), "n_calibration_successes": found.n_successes}
            if scorer == "margin":
                per_scorer[scorer]["live_calibration_agrees"] = _agrees(found, paths["calibration"])
            print(
                f"alpha {alpha:.2f} {scorer:8s} score {best.score:7s} from call {best.start_frame}, persistence "
                f"{best.persistence}: detection {result.detection_rate} early {result.early_detection_rate} lead "
                f"{result.lead_time_s} s, false alarms {result.false_alarm_rate} (n = {found.n_successes})",
                flush=True,
            )
        document[f"alpha_{alpha:g}"] = per_scorer
    write_document(args.out, document)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    sys.exit(main())
