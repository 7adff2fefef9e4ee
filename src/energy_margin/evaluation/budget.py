"""AP against the expansion budget for every tree method, with bootstrap confidence intervals.

``budget_sweep`` analyses a dataset once per (method, budget) in its own working directory
``DIR/budget/<method>-<budget>/`` (a copy of the dataset files; ``DIR/scores.csv`` is never touched),
through :func:`energy_margin.analysis.run.analyze`, so every configuration writes its journal as frames
finish and an interrupted sweep resumes where it stopped. After each configuration the summary
(CSV, JSON and, with matplotlib installed, a PNG plot) is rewritten.

Questions: capture at k-hat = 0 and k-hat = 2, and trajectory success predicted from the first half
of the frames (the weighted last ``success_frames`` frames of that half, as ``evaluate``). The 95 %
confidence intervals resample whole trajectories with replacement (the same seeded resamples for
every row, so rows are paired); a resample whose labels hold a single class is skipped.
"""

from __future__ import annotations

import csv
import io
import shutil
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.run import analyze
from energy_margin.analysis.scores import trajectory_success_score
from energy_margin.data.dataset import FRAMES_FILE, METADATA_FILE, Dataset, load_dataset
from energy_margin.data.scores_file import load_scores
from energy_margin.errors import EnergyMarginError
from energy_margin.evaluation.baselines import distance_scores
from energy_margin.evaluation.metrics import score_grid
from energy_margin.planning.methods import METHODS
from energy_margin.runs.files import atomic_write_text, write_json

DEFAULT_BUDGETS = (10, 30, 100, 300, 1000)
WORK_DIR = "budget"
QUESTIONS = ("capture_ap", "capture_ap_window2", "success_ap_first_half")
FIELDS = (
    "method",
    "budget",
    *(f"{q}{suffix}" for q in QUESTIONS for suffix in ("", "_low", "_high")),
    "runtime_per_frame_s",
    "nodes_per_frame",
    "frames",
)


def average_precision(labels: np.ndarray, scores: np.ndarray) -> float | None:
    """Average Precision as scikit-learn computes it (ties form one threshold); ``None`` for one class."""
    labels = np.asarray(labels, dtype=bool).ravel()
    scores = np.asarray(scores, dtype=float).ravel()
    positives = int(labels.sum())
    if positives == 0 or positives == labels.size:
        return None
    order = np.argsort(-scores, kind="mergesort")
    ordered = scores[order]
    hits = np.cumsum(labels[order])
    last = np.r_[np.flatnonzero(np.diff(ordered)), labels.size - 1]
    true_positives = hits[last]
    precision = true_positives / (last + 1.0)
    recall = true_positives / positives
    return float(np.sum(np.diff(np.r_[0.0, recall]) * precision))


#: Names of the questions in plots and tables.
QUESTION_LABELS = {
    "capture_ap": "capture, k-hat = 0",
    "capture_ap_window2": "capture, k-hat = 2",
    "success_ap_first_half": "success from first half",
}


class Questions:
    """Labels of one dataset and the AP of score grids on a resample of its trajectories.

    Capture questions score every frame against the capture label with a look-ahead window
    (k-hat); success questions score every trajectory from the weighted last ``success_frames``
    frame scores of a span of its frames.

    Args:
        dataset: the dataset.
        success_frames: k-bar, the frames averaged by a success question.
        capture_windows: question name -> k-hat (default: budget's two capture questions).
        success_spans: question name -> frame slice ``(start, stop)`` (``None`` bounds as in Python
            slices; default: the first half of the frames).

    """

    def __init__(
        self,
        dataset: Dataset,
        success_frames: int = 3,
        *,
        capture_windows: dict[str, int] | None = None,
        success_spans: dict[str, tuple[int | None, int | None]] | None = None,
    ) -> None:
        half = max(1, dataset.n_frames // 2)
        windows = capture_windows if capture_windows is not None else {"capture_ap": 0, "capture_ap_window2": 2}
        spans = success_spans if success_spans is not None else {"success_ap_first_half": (0, half)}
        self.capture = {name: dataset.capture_labels(window) for name, window in windows.items()}
        self.spans = {name: slice(*span) for name, span in spans.items()}
        self.success = dataset.success_labels()
        self.success_frames = success_frames
        self.names: tuple[str, ...] = (*self.capture, *self.spans)

    def answer(self, capture: np.ndarray, success: np.ndarray, rows: np.ndarray) -> dict[str, float | None]:
        """AP of each question on trajectories ``rows`` (indices, repeats allowed).

        Args:
            capture: capture scores, shape (T, K).
            success: success scores, shape (T, K).
            rows: trajectory indices, shape (n,).

        """
        result: dict[str, float | None] = {
            name: average_precision(labels[rows], capture[rows]) for name, labels in self.capture.items()
        }
        for name, span in self.spans.items():
            scores = trajectory_success_score(success[rows, span], last=self.success_frames)
            result[name] = average_precision(self.success[rows], scores)
        return result


def bootstrap_answers(
    questions: Questions, capture: np.ndarray, success: np.ndarray, resamples: np.ndarray
) -> dict[str, np.ndarray]:
    """Each question's AP on every resample, shape (n_resamples,), NaN where the resample has one class.

    Args:
        questions: the questions.
        capture: capture scores, shape (T, K).
        success: success scores, shape (T, K).
        resamples: trajectory indices of each resample, shape (n_resamples, T).

    """
    samples = {name: np.full(len(resamples), np.nan) for name in questions.names}
    for number, rows in enumerate(resamples):
        for name, value in questions.answer(capture, success, rows).items():
            if value is not None:
                samples[name][number] = value
    return samples


def percentile_interval(values: np.ndarray) -> tuple[float | None, float | None]:
    """The 95 % percentile interval of the finite ``values`` (shape (n,)); ``(None, None)`` if none."""
    finite = np.asarray(values, dtype=float)
    finite = finite[np.isfinite(finite)]
    if finite.size == 0:
        return None, None
    low, high = np.percentile(finite, [2.5, 97.5])
    return float(low), float(high)


def summarize(
    questions: Questions, capture: np.ndarray, success: np.ndarray, resamples: np.ndarray
) -> dict[str, float | None]:
    """Point estimates and 95 % percentile intervals over ``resamples`` (n, T) of trajectory indices."""
    point = questions.answer(capture, success, np.arange(capture.shape[0]))
    samples = bootstrap_answers(questions, capture, success, resamples)
    result: dict[str, float | None] = {}
    for name in questions.names:
        result[name] = point[name]
        result[f"{name}_low"], result[f"{name}_high"] = percentile_interval(samples[name])
    return result


def copy_dataset(directory: Path, work: Path) -> None:
    """Copy the dataset files of ``directory`` into the working directory ``work`` (kept if there)."""
    work.mkdir(parents=True, exist_ok=True)
    for name in (METADATA_FILE, FRAMES_FILE):
        target = work / name
        if not target.exists():
            shutil.copyfile(directory / name, target)


def _write_outputs(rows: list[dict[str, Any]], out: Path, meta: dict[str, Any]) -> list[Path]:
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=FIELDS, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: "" if row.get(k) is None else row[k] for k in FIELDS})
    atomic_write_text(out, buffer.getvalue())
    json_path = out.with_suffix(".json")
    write_json(json_path, {**meta, "rows": rows})
    written = [out, json_path]
    png = plot(rows, out.with_suffix(".png"), title=meta.get("title", ""))
    if png is not None:
        written.append(png)
    return written


def plot(
    rows: list[dict[str, Any]],
    path: Path,
    *,
    title: str = "",
    questions: Sequence[str] = QUESTIONS,
    labels: dict[str, str] | None = None,
) -> Path | None:
    """AP against budget per method (one panel per question, CIs shaded); ``None`` without matplotlib.

    Args:
        rows: summary rows (``method``, ``budget`` and each question with ``_low``/``_high``);
            rows of a method outside the tree methods are drawn as horizontal baselines.
        path: the PNG to write.
        title: figure title.
        questions: the questions, one panel each.
        labels: panel titles by question (default :data:`QUESTION_LABELS`).

    """
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    labels = labels if labels is not None else QUESTION_LABELS
    # At most three panels a row: budget's three questions in one row, the study's six in two.
    columns = min(3, len(questions))
    rows_of_panels = -(-len(questions) // columns)
    figure, grid = plt.subplots(
        rows_of_panels, columns, figsize=(4.2 * columns, 3.6 * rows_of_panels), sharey=True, squeeze=False
    )
    axes = list(grid.ravel()[: len(questions)])
    for spare in grid.ravel()[len(questions) :]:
        spare.set_visible(False)
    methods = [m for m in dict.fromkeys(r["method"] for r in rows)]
    baseline_colors = {"current_state": "grey", "distance": "black", "chance": "tab:brown"}
    for axis, question in zip(axes, questions, strict=True):
        for method in methods:
            mine = [r for r in rows if r["method"] == method and r.get(question) is not None]
            if not mine:
                continue
            if method in METHODS:
                budgets = [r["budget"] for r in mine]
                values = [r[question] for r in mine]
                line = axis.plot(budgets, values, marker="o", label=method)[0]
                low = [r[f"{question}_low"] for r in mine]
                high = [r[f"{question}_high"] for r in mine]
                if None not in low and None not in high:
                    axis.fill_between(budgets, low, high, color=line.get_color(), alpha=0.15)
                    below = [v - lo for v, lo in zip(values, low, strict=True)]
                    above = [hi - v for v, hi in zip(values, high, strict=True)]
                    axis.errorbar(budgets, values, yerr=[below, above], fmt="none", ecolor=line.get_color(), capsize=3)
            else:
                axis.axhline(
                    mine[0][question],
                    linestyle="--",
                    linewidth=1,
                    label=method,
                    color=baseline_colors.get(method, "black"),
                )
        axis.set_xscale("log")
        axis.set_xlabel("expansions per frame")
        axis.set_title(labels.get(question, question))
        axis.grid(True, alpha=0.3)
    for row_axes in grid:
        row_axes[0].set_ylabel("AP (95 % CI over trajectories)")
    axes[-1].legend(fontsize=8, loc="lower right")
    if title:
        figure.suptitle(title)
    figure.tight_layout()
    figure.savefig(path, dpi=120)
    plt.close(figure)
    return path


def budget_sweep(
    path: Path | str,
    *,
    budgets: Sequence[int] = DEFAULT_BUDGETS,
    methods: Sequence[str] = METHODS,
    workers: int = 1,
    seed: int = 0,
    bootstrap: int = 1000,
    out: Path | str | None = None,
    base: AnalyzerConfig | None = None,
    log: Callable[[str], None] | None = None,
) -> list[dict[str, Any]]:
    """Analyse the dataset at every (method, budget), write the summary and return its rows.

    Args:
        path: dataset directory.
        budgets: iterations per frame, each >= 1.
        methods: tree methods.
        workers: worker processes of each analysis.
        seed: analysis seed (the same per-frame seeds for every configuration) and bootstrap seed.
        bootstrap: trajectory resamples for the confidence intervals (0: none).
        out: summary CSV (JSON and PNG beside it); ``DIR/budget/budget.csv`` by default.
        base: other analysis settings (cost, lambda, batch, ...); its iterations are replaced.
        log: receives one progress line per configuration (standard error by default).

    """
    if not budgets or any(isinstance(b, bool) or not isinstance(b, int) or b < 1 for b in budgets):
        raise EnergyMarginError(f"budgets must be integers >= 1, got {list(budgets)!r}")
    unknown = [m for m in methods if m not in METHODS]
    if not methods or unknown:
        raise EnergyMarginError(f"methods must be among {', '.join(METHODS)}, got {list(methods)!r}")
    if isinstance(bootstrap, bool) or not isinstance(bootstrap, int) or bootstrap < 0:
        raise EnergyMarginError(f"bootstrap must be an integer >= 0, got {bootstrap!r}")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise EnergyMarginError(f"seed must be a non-negative integer, got {seed!r}")
    say = log if log is not None else (lambda line: print(line, file=sys.stderr, flush=True))
    directory = Path(path)
    dataset = load_dataset(directory)
    out_path = Path(out) if out is not None else directory / WORK_DIR / "budget.csv"
    out_path.parent.mkdir(parents=True, exist_ok=True)
    base = base if base is not None else AnalyzerConfig()
    questions = Questions(dataset)
    resamples = np.random.default_rng(seed).integers(0, dataset.n_trajectories, (bootstrap, dataset.n_trajectories))
    meta = {
        "dataset": str(directory),
        "task": dataset.metadata["task"],
        "n_trajectories": dataset.n_trajectories,
        "n_frames": dataset.n_frames,
        "n_objects": dataset.n_objects,
        "seed": seed,
        "bootstrap": bootstrap,
        "workers": workers,
        "analyzer": base.to_dict(),
        "title": f"{dataset.metadata['task']}, n_o = {dataset.n_objects}, "
        f"{dataset.n_trajectories} x {dataset.n_frames} frames",
    }
    rows: list[dict[str, Any]] = []
    for name, grids in baseline_grids(dataset).items():
        rows.append({"method": name, "budget": 0, **summarize(questions, *grids, resamples), "frames": 0})
    total = len(methods) * len(budgets)
    for number, (method, budget) in enumerate(((m, b) for m in methods for b in budgets), start=1):
        started = time.perf_counter()
        scores = analyze_configuration(
            directory,
            out_path.parent / f"{method}-{budget}",
            base,
            method=method,
            budget=budget,
            seed=seed,
            workers=workers,
        )
        capture = score_grid(dataset, scores, "capture_score")
        success = score_grid(dataset, scores, "success_score")
        row: dict[str, Any] = {"method": method, "budget": budget}
        row.update(summarize(questions, capture, success, resamples))
        row.update(cost_summary(scores))
        rows.append(row)
        _write_outputs(rows, out_path, meta)
        say(
            f"budget [{number}/{total}] {method} {budget}: capture AP {_fmt(row['capture_ap'])}, "
            f"k-hat=2 {_fmt(row['capture_ap_window2'])}, success (first half) {_fmt(row['success_ap_first_half'])}, "
            f"{row['runtime_per_frame_s']:.3f} s/frame ({time.perf_counter() - started:.0f} s)"
        )
    _write_outputs(rows, out_path, meta)
    return rows


def analyze_configuration(
    directory: Path,
    work: Path,
    base: AnalyzerConfig,
    *,
    method: str,
    budget: int,
    seed: int,
    workers: int,
    progress: bool = False,
) -> dict[str, np.ndarray]:
    """Analyse the dataset ``directory`` with ``method`` at ``budget`` iterations in its own ``work`` directory.

    ``work`` gets a copy of the dataset files and the resumable journal of
    :func:`energy_margin.analysis.run.analyze`; a finished configuration is read back, not rerun.

    Returns:
        The scores columns (:func:`energy_margin.data.scores_file.load_scores`).

    """
    copy_dataset(directory, work)
    fields = {**base.to_dict(), "iterations": budget, "nodes": None, "method": method}
    try:
        config = AnalyzerConfig(**fields)
    except ValueError as error:
        raise EnergyMarginError(str(error)) from None
    analyze(work, config, seed=seed, workers=workers, progress=progress)
    return load_scores(work)


def cost_summary(scores: dict[str, np.ndarray]) -> dict[str, Any]:
    """Mean wall time and nodes per frame of a scores file's columns, and its number of frames."""
    return {
        "runtime_per_frame_s": float(scores["runtime_s"].mean()),
        "nodes_per_frame": float(scores["nodes"].mean()),
        "frames": int(scores["runtime_s"].size),
    }


def baseline_grids(dataset: Dataset) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Capture and success score grids (each (T, K)) of the baselines: ``current_state`` and ``distance``."""
    grids = {
        "current_state": (
            dataset.arrays["captured"].astype(float),
            dataset.arrays["in_success"].astype(float),
        )
    }
    heuristic = distance_scores(dataset)
    if heuristic is not None:
        grids["distance"] = heuristic
    return grids


def _fmt(value: float | None) -> str:
    return "n/a" if value is None else f"{value:.3f}"


def format_table(
    rows: list[dict[str, Any]],
    *,
    questions: Sequence[str] = QUESTIONS,
    headers: Sequence[str] = ("capture k=0", "capture k=2", "success 1st half"),
    first: Sequence[str] = ("method",),
) -> str:
    """A text table of summary rows: the ``first`` columns, the budget, each question with its interval."""
    width = max([13, *(len(str(row.get(key, ""))) for row in rows for key in first)])
    header = (
        " ".join(f"{key:>{width}s}" for key in first)
        + f" {'budget':>6s} "
        + " ".join(f"{q:>24s}" for q in headers)
        + f" {'s/frame':>8s}"
    )
    lines = [header, "-" * len(header)]
    for row in rows:
        cells = []
        for question in questions:
            value, low, high = row.get(question), row.get(f"{question}_low"), row.get(f"{question}_high")
            text = _fmt(value) if low is None or high is None else f"{_fmt(value)} [{low:.3f}, {high:.3f}]"
            cells.append(f"{text:>24s}")
        runtime = row.get("runtime_per_frame_s")
        budget = str(row["budget"]) if row.get("budget") else "-"
        names = " ".join(f"{row.get(key, '')!s:>{width}s}" for key in first)
        lines.append(f"{names} {budget:>6s} {' '.join(cells)} {'' if runtime is None else f'{runtime:8.3f}'}")
    return "\n".join(lines)
