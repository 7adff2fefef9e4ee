"""The static HTML report of ``energy-margin reproduce``: one page, PNG figures, no JavaScript."""

from __future__ import annotations

import html
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.data.io import atomic_write_text
from energy_margin.report.config import ReproduceConfig
from energy_margin.report.paper import PAPER_FIG_2, PAPER_TABLE_I

SECTIONS = (
    ("table-1", "Table I: scores on true and perturbed states"),
    ("ablation", "Fig. 2: number of objects"),
    ("pushing-frames", "Pushing frames (top view)"),
    ("scooping-frames", "Scooping frames (side view)"),
    ("cost-field", "Energy-cost field and likelihood"),
    ("trajectories", "Scores along every trajectory"),
    ("precision-recall", "Precision-recall curves"),
)


def _fmt(value: Any) -> str:
    if value is None:
        return "n/a"
    if isinstance(value, dict):
        return "n/a" if value.get("mean") is None else f"{value['mean']:.2f} ± {value['std']:.2f}"
    if isinstance(value, tuple | list):
        return f"{value[0]:.2f} ± {value[1]:.2f}"
    return f"{value:.2f}" if isinstance(value, float) else html.escape(str(value))


def _table(header: list[str], rows: list[list[Any]]) -> str:
    head = "".join(f"<th>{html.escape(cell)}</th>" for cell in header)
    body = "".join("<tr>" + "".join(f"<td>{_fmt(cell)}</td>" for cell in row) + "</tr>" for row in rows)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def _figure(name: str, caption: str) -> str:
    return (
        f'<figure><img src="figures/{name}" alt="{html.escape(caption)}">'
        f"<figcaption>{html.escape(caption)}</figcaption></figure>"
    )


def _pick_trajectories(dataset: Any) -> list[int]:
    """A successful and a failed trajectory when both exist."""
    labels = dataset.success_labels()
    picks = []
    for wanted in (True, False):
        matches = np.flatnonzero(labels == wanted)
        if matches.size:
            picks.append(int(matches[0]))
    return picks or [0]


def _task_figures(out: Path, figures: Path, task: str, row: dict[str, Any], config: ReproduceConfig) -> dict[str, str]:
    from energy_margin.analysis.frame import AnalyzerConfig, analyze_frame
    from energy_margin.analysis.scores import likelihood, trajectory_success_score
    from energy_margin.data.dataset import load_dataset
    from energy_margin.data.scores_file import load_scores
    from energy_margin.evaluation.metrics import score_grid
    from energy_margin.report import plots

    dataset = load_dataset(out / row["dataset"])
    scores = load_scores(out / row["dataset"])
    capture = score_grid(dataset, scores, "capture_score")
    success = score_grid(dataset, scores, "success_score")
    k = dataset.n_frames
    frames = sorted({0, k // 2, k - 1})
    parts: dict[str, str] = {}

    frame_html = []
    for trajectory in _pick_trajectories(dataset):
        name = f"{task}-frames-{trajectory}.png"
        plots.frame_figure(dataset, trajectory, frames, figures / name)
        outcome = "successful" if dataset.success_labels()[trajectory] else "failed"
        frame_html.append(_figure(name, f"{task}: frames {frames} of a {outcome} trajectory ({trajectory})"))
    parts["frames"] = "".join(frame_html)

    trajectory = _pick_trajectories(dataset)[0]
    frame_index = k // 2
    friction = float(dataset.arrays["friction"][trajectory])
    _, field = analyze_frame(
        dataset.task,
        dataset.frame(trajectory, frame_index),
        friction=friction,
        drive=dataset.arrays["drive"][trajectory],
        seed=config.seed,
        config=AnalyzerConfig(iterations=config.iterations, engine=config.engine),
        start_time=float(dataset.arrays["frame_time"][trajectory, frame_index]),
    )
    lam = dataset.task.config.likelihood_lambda
    name = f"{task}-cost-field.png"
    plots.cost_field_figure(dataset, trajectory, frame_index, field, likelihood(field.costs, lam), figures / name)
    parts["cost_field"] = _figure(
        name, f"{task}: reached states of one tree coloured by energy cost, and their likelihoods (λ = {lam:g} 1/J)"
    )

    name = f"{task}-trajectories.png"
    plots.trajectory_scores_figure(dataset, capture, success, figures / name)
    parts["trajectories"] = _figure(name, f"{task}: capture and success scores of every frame against the labels")

    half = max(1, k // 2)
    labels = dataset.success_labels()
    curves = {
        "capture, k̂ = 0": (dataset.capture_labels(0), capture),
        "capture, k̂ = 2": (dataset.capture_labels(2), capture),
        "success, last 3 frames": (labels, trajectory_success_score(success, last=3)),
        "success, first half": (labels, trajectory_success_score(success[:, :half], last=3)),
    }
    name = f"{task}-precision-recall.png"
    plots.precision_recall_figure(curves, figures / name, title=f"{task}: precision-recall of the energy-margin scores")
    parts["precision_recall"] = _figure(name, f"{task}: precision-recall curves")
    return parts


def write_report(
    out: Path, table_one: dict[str, dict[str, Any]], ablation: list[dict[str, Any]], config: ReproduceConfig
) -> Path:
    """Write ``out/report/index.html`` and its figures; return the page's path."""
    from energy_margin.report import plots

    report = out / "report"
    figures = report / "figures"
    figures.mkdir(parents=True, exist_ok=True)
    per_task = {task: _task_figures(out, figures, task, row, config) for task, row in table_one.items()}
    plots.runtime_figure(ablation, figures / "runtime.png")

    table_rows = []
    for task, row in table_one.items():
        paper = PAPER_TABLE_I[task]
        keys = (
            "capture_ap",
            "capture_ap_perturbed",
            "capture_score_error",
            "success_ap",
            "success_ap_perturbed",
            "success_score_error",
        )
        table_rows.append([task, row["n_objects"], "this project", *(row.get(key) for key in keys)])
        table_rows.append(["", paper["n_objects"], "paper", *(paper[key] for key in keys)])
    ablation_rows = []
    for row in ablation:
        paper_row = PAPER_FIG_2.get(row["n_objects"], {})
        ablation_rows.append(
            [
                row["n_objects"],
                row["capture_ap"],
                row["success_ap"],
                (row["runtime_per_frame_s"], row["runtime_per_frame_std_s"]),
                paper_row.get("capture_ap"),
                paper_row.get("success_ap"),
                paper_row.get("runtime"),
            ]
        )
    body = {
        "table-1": _table(
            [
                "task",
                "n_o",
                "",
                "capture AP true",
                "capture AP perturbed",
                "capture score error",
                "success AP true",
                "success AP perturbed",
                "success score error",
            ],
            table_rows,
        )
        + f"<p>{config.repeats} perturbed copies per task: object centres resampled inside the minimum-volume "
        "ellipse(oid) of the true centres, velocities zeroed, no overlaps. Perturbed AP: mean ± std over the "
        "copies; score error: perturbed − true over all frames and copies.</p>",
        "ablation": _table(
            [
                "n_o",
                "capture AP",
                "success AP",
                "runtime per frame [s]",
                "paper capture AP",
                "paper success AP",
                "paper runtime [s]",
            ],
            ablation_rows,
        )
        + _figure("runtime.png", "runtime per frame (mean ± std) against the number of objects, pushing"),
        "pushing-frames": per_task["pushing"]["frames"],
        "scooping-frames": per_task["scooping"]["frames"],
        "cost-field": per_task["pushing"]["cost_field"] + per_task["scooping"]["cost_field"],
        "trajectories": per_task["pushing"]["trajectories"] + per_task["scooping"]["trajectories"],
        "precision-recall": per_task["pushing"]["precision_recall"] + per_task["scooping"]["precision_recall"],
    }
    sections = "".join(
        f'<section id="{key}"><h2>{html.escape(title)}</h2>{body[key]}</section>' for key, title in SECTIONS
    )
    mode = "quick" if config.quick else "full"
    navigation = "".join(f'<li><a href="#{key}">{html.escape(title)}</a></li>' for key, title in SECTIONS)
    page = (
        '<!DOCTYPE html><html lang="en"><head><meta charset="utf-8"><title>energy-margin report</title>'
        "<style>body{font-family:sans-serif;max-width:1100px;margin:2em auto;padding:0 1em}"
        "table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #bbb;padding:4px 8px;text-align:right}"
        "figure{margin:1em 0}img{max-width:100%}figcaption{font-size:90%;color:#444}</style></head><body>"
        f"<h1>energy-margin: reproduction of the paper ({mode})</h1>"
        f"<p>{config.trajectories} trajectories × {config.frames} frames per task, {config.iterations} EST "
        f"iterations per frame, engine {html.escape(config.engine)}, seed {config.seed}. "
        "Tables as Markdown and JSON beside this page's folder: table1.md, ablation.md.</p>"
        f"<nav><ul>{navigation}</ul></nav>"
        f"{sections}</body></html>\n"
    )
    index = report / "index.html"
    atomic_write_text(index, page)
    return index
