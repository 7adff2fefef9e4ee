"""AP of the adaptive budget and the fast contact model against the whole budget, on the sets they were chosen on.

The table of docs/results/performance.md ("AP before and after"): each set analysed with
``analyze``'s budget of 300 expansions and with ``--converge 0.02``, ``--converge 0.03``,
``--contacts fast``, ``--contacts fast --converge 0.02``, ``--batch 32`` alone and with
``--converge 0.02`` and ``0.03``, ``--converge 0.02 --converge-rule projected-reached``, the
earlier rule ``--converge-rule window --converge 0.01`` with either contact model, and
``--projection ellipsoid`` (the tree's own success,
``--continuation 0``, two workers), then evaluated:

* the authors' 200 pushing frames (``import-reference planepush-10objects --no-scores``), analysis
  seeds 0, 1 and 2, their Table I protocol (``--weights uniform --success-frames 10``);
* three 20 × 10 pushing sets of 10 objects (generation seeds 0, 1, 2, each analysed with its own
  seed; the whole budget also with analysis seeds 10 and 11, which measures how far a mean moves
  when only the analysis seed changes), ``evaluate``'s defaults;
* a 20 × 10 scooping set of 5 boxes (generation seed 0; no fast contact model), the same.

Every analysis resumes from ``--work``.

    python benchmarks/converge_ap.py --work runs/converge-ap --out docs/figures/converge_ap.json

Without ``../shared`` the authors' frames are left out.
"""

from __future__ import annotations

import shutil
import time
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.run import analyze
from energy_margin.data.generate import generate_dataset
from energy_margin.data.reference import import_reference
from energy_margin.data.scores_file import load_scores
from energy_margin.evaluation.metrics import evaluate
from energy_margin.runs.versions import engine_versions
from engine_versions import REFERENCE_DATA
from results_document import document_head, work_arguments, write_document

__all__ = ["SETTINGS", "analysed_copy", "mean_row", "with_changes"]

EXPANSIONS = 300
#: The analyses compared, as ``AnalyzerConfig`` fields beside the budget.
SETTINGS: dict[str, dict[str, Any]] = {
    "defaults": {},
    "converge_0.02": {"converge": 0.02},
    "converge_0.03": {"converge": 0.03},
    "fast": {"contacts": "fast"},
    "fast_converge_0.02": {"contacts": "fast", "converge": 0.02},
    # Batched rounds (``--batch 32``; threads change the time, not the scores) alone and with the budget.
    "batch32": {"batch": 32},
    "converge_0.02_batch32": {"converge": 0.02, "batch": 32},
    "converge_0.03_batch32": {"converge": 0.03, "batch": 32},
    # The projected rule once the success score has left 0 (``--converge-rule projected-reached``).
    "reached_0.02": {"converge": 0.02, "converge_rule": "projected-reached"},
    # The earlier rule of the adaptive budget (the levers table), with both contact models.
    "window_0.01": {"converge": 0.01, "converge_rule": "window"},
    "fast_window_0.01": {"contacts": "fast", "converge": 0.01, "converge_rule": "window"},
    # The ellipsoid of the object centres as the EST's density projection (robustness.md).
    "ellipsoid": {"projection": "ellipsoid"},
}
#: Settings a task without a fast contact model (scooping) is analysed with.
RECORDED_ONLY = tuple(name for name, setting in SETTINGS.items() if "contacts" not in setting)
QUESTIONS = ("capture_ap", "capture_ap_window2", "success_ap", "success_ap_first_half")
THEIR_PROTOCOL = {"weights": "uniform", "success_frames": 10}
PUSHING_SEEDS = (0, 1, 2)
EXTRA_ANALYSIS_SEEDS = (10, 11)


def _copy(source: Path, out: Path) -> Path:
    """A copy of a dataset's files (not its analysis) at ``out``, kept when already there."""
    if not (out / "frames.npz").exists():
        out.mkdir(parents=True, exist_ok=True)
        for name in ("frames.npz", "dataset.json"):
            shutil.copy2(source / name, out / name)
    return out


def _analysed(
    source: Path, out: Path, setting: str, seed: int, workers: int, protocol: dict[str, Any]
) -> dict[str, Any]:
    """One analysis of a copy of ``source`` with ``setting``: AP per question and mean expansions."""
    return analysed_copy(source, out, SETTINGS[setting], seed, workers, protocol)


def analysed_copy(
    source: Path, out: Path, fields: dict[str, Any], seed: int, workers: int, protocol: dict[str, Any]
) -> dict[str, Any]:
    """One analysis of a copy of ``source`` (``AnalyzerConfig`` ``fields`` beside the budget, the tree's
    own success), resumed where ``out`` has one, then ``evaluate`` with ``protocol``: AP per question,
    mean expansions and the seed."""
    path = _copy(source, out)
    config = AnalyzerConfig(expansions=EXPANSIONS, continuation=0, capture_gate="none", **fields)
    analyze(path, config, seed=seed, workers=workers, progress=False)
    result = evaluate(path, resamples=0, **protocol)
    row: dict[str, Any] = {question: getattr(result, question) for question in QUESTIONS}
    scores = load_scores(path)
    row["mean_expansions"] = float(np.mean(scores["expansions"]))
    # Each frame's time in its worker (tree and scoring), and the physics part of it.
    row["seconds_per_frame"] = float(np.mean(scores["runtime_s"]))
    row["seconds_per_frame_sd"] = float(np.std(scores["runtime_s"]))
    row["physics_s"] = float(np.mean(scores["physics_s"]))
    row["seed"] = seed
    return row


def mean_row(rows: list[dict[str, Any]]) -> dict[str, float | None]:
    """The mean of each question (and of the mean expansions) over ``rows``; None where any is None."""
    keys = (*QUESTIONS, "mean_expansions")
    found: dict[str, float | None] = {}
    for key in keys:
        values = [row[key] for row in rows]
        found[key] = None if any(value is None for value in values) else float(np.mean(values))
    return found


def with_changes(found: dict[str, Any]) -> dict[str, Any]:
    """Each setting's mean minus the whole budget's, per question, and the same run by run (paired by seed)."""
    reference = found["defaults"]
    for entry in found.values():
        entry["change"] = _difference(entry["mean"], reference["mean"])
        entry["change_by_run"] = [
            _difference(run, base) for run, base in zip(entry["runs"], reference["runs"], strict=True)
        ]
    return found


def _difference(row: dict[str, Any], base: dict[str, Any]) -> dict[str, float | None]:
    return {
        question: None if row[question] is None or base[question] is None else row[question] - base[question]
        for question in QUESTIONS
    }


def their_frames(work: Path, workers: int) -> dict[str, Any]:
    """The authors' 200 pushing frames, analysis seeds 0-2, every setting."""
    source = work / "their-frames"
    if not (source / "frames.npz").exists():
        import_reference(REFERENCE_DATA / "planepush-10objects", source, with_scores=False, overwrite=True)
    found: dict[str, Any] = {}
    for setting in SETTINGS:
        runs = [
            _analysed(source, work / f"their-{setting}-seed{seed}", setting, seed, workers, THEIR_PROTOCOL)
            for seed in PUSHING_SEEDS
        ]
        found[setting] = {"runs": runs, "mean": mean_row(runs)}
        print(f"their frames, {setting}: done", flush=True)
    return with_changes(found)


def _generated(work: Path, task: str, n_objects: int, seed: int) -> Path:
    out = work / f"{task}{n_objects}-s{seed}"
    if not (out / "frames.npz").exists():
        generate_dataset(task, n_objects=n_objects, n_trajectories=20, n_frames=10, seed=seed, out=out, overwrite=True)
    return out


def pushing(work: Path, workers: int) -> dict[str, Any]:
    """Three 20 × 10 pushing sets, each analysed with its own seed; the whole budget also with seeds 10, 11."""
    sources = {seed: _generated(work, "pushing", 10, seed) for seed in PUSHING_SEEDS}
    found: dict[str, Any] = {}
    for setting in SETTINGS:
        runs = [
            _analysed(source, work / f"push-{setting}-s{seed}", setting, seed, workers, {})
            for seed, source in sources.items()
        ]
        found[setting] = {"runs": runs, "mean": mean_row(runs)}
        print(f"pushing, {setting}: done", flush=True)
    extra = [
        _analysed(source, work / f"push-defaults-s{seed}-a{other}", "defaults", other, workers, {})
        for seed, source in sources.items()
        for other in EXTRA_ANALYSIS_SEEDS
    ]
    found["defaults"]["nine_analyses"] = mean_row(found["defaults"]["runs"] + extra)
    # The three sets' mean with every set analysed by one further seed (the own seeds: "mean").
    found["defaults"]["by_analysis_seed"] = {
        str(other): mean_row([row for row in extra if row["seed"] == other]) for other in EXTRA_ANALYSIS_SEEDS
    }
    return with_changes(found)


def scooping(work: Path, workers: int) -> dict[str, Any]:
    """A 20 × 10 scooping set of 5 boxes (generation seed 0), the recorded-contact settings."""
    source = _generated(work, "scooping", 5, 0)
    found: dict[str, Any] = {}
    for setting in RECORDED_ONLY:
        run = _analysed(source, work / f"scoop-{setting}", setting, 0, workers, {})
        found[setting] = {"runs": [run], "mean": mean_row([run])}
        print(f"scooping, {setting}: done", flush=True)
    return with_changes(found)


def main() -> None:
    parser = work_arguments(__doc__)
    args = parser.parse_args()
    started = time.perf_counter()
    sets: dict[str, Any] = {}
    if REFERENCE_DATA.is_dir():
        sets["their_frames"] = their_frames(args.work, args.workers)
    else:
        print(f"note: the authors' data is not at {REFERENCE_DATA}; their frames are left out")
    sets["pushing"] = pushing(args.work, args.workers)
    sets["scooping"] = scooping(args.work, args.workers)
    figures = {
        **document_head("converge_ap.py"),
        "versions": engine_versions(),
        "expansions": EXPANSIONS,
        "settings": SETTINGS,
        "wall_s": round(time.perf_counter() - started, 1),
        "sets": sets,
    }
    write_document(args.out, figures)
    for name, entries in sets.items():
        for setting, entry in entries.items():
            print(name, setting, {key: round(value, 4) for key, value in entry["mean"].items() if value is not None})


if __name__ == "__main__":
    main()
