"""Why the adaptive budget loses AP with batched rounds: stopping rules replayed on batched trees.

On converge_ap.py's three 20 × 10 pushing sets of 10 objects (generation seeds 0, 1, 2, each
analysed with its own seed), every frame's tree is grown in rounds of ``--batch`` expansions
(``analyze --batch 32``) to the whole budget of 300 with both scores recorded after every round,
where ``analyze --converge`` checks a batched tree (``converge_every`` 25 is shorter than a round).
A tree stopped by a rule is the prefix of that tree (the rule draws no random numbers), so every
rule is replayed on the same trees; that the replay of ``--converge 0.02`` is what ``analyze`` gives
is checked on the first frame of every set. Each rule's AP (``evaluate``'s defaults, the tree's own
success) is compared with the one-at-a-time whole budget of the same set (converge_ap.py's
``defaults`` analysis, resumed from ``--work``). For the projected rule it also records how many
frames stop at the first check the rule can stop at, and the AP when only those frames take their
stopped scores (every other frame its whole batched tree's).

    python benchmarks/batched_converge.py --work runs/converge-ap --out docs/figures/batched_converge.json
"""

from __future__ import annotations

import multiprocessing
import time
from pathlib import Path
from typing import Any

import numpy as np

from converge_ap import analysed_copy
from energy_margin.analysis.convergence import frame_seeds, score_field, scores_settled
from energy_margin.analysis.frame import AnalyzerConfig, FrameAnalyzer, analyze_frame
from energy_margin.data.dataset import Dataset, load_dataset
from energy_margin.data.generate import generate_dataset
from energy_margin.evaluation.metrics import question_aps
from energy_margin.planning import CostField
from energy_margin.runs.versions import engine_versions
from results_document import document_head, work_arguments, write_document

__all__ = ["RULES", "replay"]

EXPANSIONS = 300
SEEDS = (0, 1, 2)
QUESTIONS = ("capture_ap", "capture_ap_window2", "success_ap", "success_ap_first_half")
#: Replayed rules: (tolerance, window, rule, no stop before this many expansions); None: the whole budget.
RULES: dict[str, tuple[float, int, str, int] | None] = {
    "whole budget": None,
    "projected 0.02": (0.02, 50, "projected", 0),
    "projected 0.02, no stop before 128": (0.02, 50, "projected", 128),
    "projected 0.02, no stop before 192": (0.02, 50, "projected", 192),
    "projected 0.02, window 100": (0.02, 100, "projected", 0),
    "projected 0.02, window 150": (0.02, 150, "projected", 0),
    "projected-reached 0.02": (0.02, 50, "projected-reached", 0),
}
_DATASET: Dataset | None = None
Row = tuple[int, float, float]


def _init(path: str) -> None:
    global _DATASET
    _DATASET = load_dataset(path)


def _trace(job: tuple[int, int, int, int]) -> tuple[int, int, list[Row]]:
    """Both scores after every round of one frame's batched tree, grown to the whole budget."""
    trajectory, frame, seed, batch = job
    dataset = _DATASET
    assert dataset is not None
    root, lam = dataset.frame(trajectory, frame), dataset.task.config.likelihood_lambda
    rows: list[Row] = []

    def record(field: CostField) -> bool:
        capture, success = score_field(dataset.task, root, field, lam)
        rows.append((field.expansions, capture, success))
        return False

    analyze_frame(
        dataset.task,
        root,
        friction=float(dataset.arrays["friction"][trajectory]),
        drive=dataset.arrays["drive"][trajectory],
        seed=seed,
        config=_config(batch),
        stop=record,
        check_every=1,
        start_time=float(dataset.arrays["frame_time"][trajectory, frame]),
    )
    return trajectory, frame, rows


def _config(batch: int, **fields: Any) -> AnalyzerConfig:
    return AnalyzerConfig(expansions=EXPANSIONS, batch=batch, continuation=0, capture_gate="none", **fields)


def replay(rows: list[Row], rule: tuple[float, int, str, int] | None) -> int:
    """Index of the row where ``rule`` stops (the last row when it never does)."""
    if rule is None:
        return len(rows) - 1
    tolerance, window, name, first = rule
    for index, (expansions, _, _) in enumerate(rows):
        if expansions < first:
            continue
        history = rows[: index + 1]
        if scores_settled(history, remaining=EXPANSIONS - expansions, tolerance=tolerance, window=window, rule=name):
            return index
    return len(rows) - 1


def _aps(dataset: Dataset, chosen: dict[tuple[int, int], Row]) -> dict[str, float | None]:
    capture = np.zeros((dataset.n_trajectories, dataset.n_frames))
    success = np.zeros_like(capture)
    for (trajectory, frame), (_, capture_score, success_score) in chosen.items():
        capture[trajectory, frame], success[trajectory, frame] = capture_score, success_score
    found = question_aps(dataset, capture, success, capture_window=0, success_frames=3, weights="linear")
    return {question: found[question] for question in QUESTIONS}


def measure_set(work: Path, seed: int, batch: int, workers: int) -> dict[str, Any]:
    """One set: its traces, every rule's AP and mean expansions, the serial whole budget's AP."""
    source = work / f"pushing10-s{seed}"
    if not (source / "frames.npz").exists():
        generate_dataset("pushing", n_objects=10, n_trajectories=20, n_frames=10, seed=seed, out=source, overwrite=True)
    serial = analysed_copy(source, work / f"push-defaults-s{seed}", {}, seed, workers, {})
    dataset = load_dataset(source)
    seeds = frame_seeds(seed, dataset.n_trajectories * dataset.n_frames)
    jobs = [(index // dataset.n_frames, index % dataset.n_frames, seeds[index], batch) for index in range(len(seeds))]
    with multiprocessing.Pool(workers, initializer=_init, initargs=(str(source),)) as pool:
        traces = {(t, k): rows for t, k, rows in pool.map(_trace, jobs, chunksize=4)}
    # The replay is analyze's rule: check it on the first frame, analysed as analyze analyses it.
    row = FrameAnalyzer(dataset, _config(batch, converge=0.02), seed)(0)
    replayed = traces[(0, 0)][replay(traces[(0, 0)], RULES["projected 0.02"])]
    if replayed != (row["expansions"], row["capture_score"], row["success_score"]):
        raise SystemExit(f"set {seed}: the replayed rule is not analyze --converge 0.02 --batch {batch}")
    rules: dict[str, Any] = {}
    for name, rule in RULES.items():
        chosen = {key: rows[replay(rows, rule)] for key, rows in traces.items()}
        aps = _aps(dataset, chosen)
        rules[name] = {
            **aps,
            "mean_expansions": float(np.mean([row[0] for row in chosen.values()])),
            "change": {q: None if aps[q] is None or serial[q] is None else aps[q] - serial[q] for q in QUESTIONS},
        }
    # Where the projected rule's loss comes from: the frames it stops at its first possible check.
    stops = {key: rows[replay(rows, RULES["projected 0.02"])][0] for key, rows in traces.items()}
    first = min(stops.values())
    early = {key for key, stop in stops.items() if stop == first}
    mixed = {
        key: rows[replay(rows, RULES["projected 0.02"])] if key in early else rows[-1] for key, rows in traces.items()
    }
    return {
        "seed": seed,
        "serial_whole_budget": {question: serial[question] for question in QUESTIONS},
        "rules": rules,
        "first_stop": first,
        "frames_stopped_first": len(early),
        "frames": len(traces),
        "only_first_stops_replaced": _aps(dataset, mixed),
    }


def main() -> None:
    parser = work_arguments(__doc__, work_help="converge_ap.py's --work (its pushing sets and analyses, resumed)")
    parser.add_argument("--batch", type=int, default=32, help="expansions per round (default 32)")
    args = parser.parse_args()
    started = time.perf_counter()
    sets = [measure_set(args.work, seed, args.batch, args.workers) for seed in SEEDS]
    summary: dict[str, dict[str, Any]] = {}
    for name in RULES:
        changes = [entry["rules"][name]["change"] for entry in sets]
        summary[name] = {
            "mean_change": {q: float(np.mean([c[q] for c in changes])) for q in QUESTIONS},
            "worst_change": {q: float(np.min([c[q] for c in changes])) for q in QUESTIONS},
            "mean_expansions": float(np.mean([entry["rules"][name]["mean_expansions"] for entry in sets])),
        }
    document = {
        **document_head("batched_converge.py"),
        "versions": engine_versions(),
        "batch": args.batch,
        "expansions": EXPANSIONS,
        "wall_s": round(time.perf_counter() - started, 1),
        "summary": summary,
        "rows": [
            {
                "rule": name,
                **summary[name]["mean_change"],
                **{f"worst_{q}": v for q, v in summary[name]["worst_change"].items()},
                "mean_expansions": summary[name]["mean_expansions"],
            }
            for name in RULES
        ],
        "sets": sets,
    }
    write_document(args.out, document)
    for name, entry in summary.items():
        print(f"{name:38s}", {q: round(v, 4) for q, v in entry["mean_change"].items()}, round(entry["mean_expansions"]))


if __name__ == "__main__":
    main()
