"""The figures of one task in the HTML report: frames, renders, video, interactive view, perturbed states, scores.

:func:`_task_figures` writes them under the report's ``figures``, ``videos`` and ``views`` folders and
returns the HTML of each section's part.
"""

from __future__ import annotations

import html
import importlib.util
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.report.config import ReproduceConfig
from energy_margin.report.html_parts import (
    _figure,
    _grid,
    _image,
)

__all__ = []


def _pick_trajectories(dataset: Any) -> list[int]:
    """A successful and a failed trajectory when both exist."""
    labels = dataset.success_labels()
    picks = []
    for wanted in (True, False):
        matches = np.flatnonzero(labels == wanted)
        if matches.size:
            picks.append(int(matches[0]))
    return picks or [0]


def _membership_note(task: Any, frame: Any, drawn_inside: Any) -> str:
    """A check that every object drawn inside (outside) a region is labelled inside (outside)."""
    notes = []
    for label, region in (("capture", task.capture_region(frame)), ("success", task.success_region_at(frame))):
        labelled = np.asarray(region.contains(frame.object_pos, frame.object_vel), dtype=bool)
        drawn = drawn_inside(region, frame.object_pos)
        if drawn is None:
            continue
        # A falling object can be drawn inside but labelled outside: the drawing shows positions only.
        position_only = np.asarray(region.contains(frame.object_pos), dtype=bool)
        wrong = np.flatnonzero(drawn != position_only)
        if wrong.size:
            notes.append(f"{label}: objects {wrong.tolist()} lie at the drawn boundary")
        notes.append(f"{label}: {int(labelled.sum())}/{len(labelled)} inside")
    return "; ".join(notes)


def _task_figures(out: Path, report: Path, task: str, row: dict[str, Any], config: ReproduceConfig) -> dict[str, str]:
    from energy_margin.data.dataset import load_dataset
    from energy_margin.data.scores_file import load_scores
    from energy_margin.evaluation.metrics import score_grid
    from energy_margin.report import plots
    from energy_margin.report.frame_tree import analysed_tree
    from energy_margin.report.html_failures import failures_html
    from energy_margin.report.render import warn_once

    figures = report / "figures"
    directory = out / row["dataset"]
    dataset = load_dataset(directory)
    scores = load_scores(directory)
    capture = score_grid(dataset, scores, "capture_score")
    success = score_grid(dataset, scores, "success_score")
    k = dataset.n_frames
    frames = sorted({0, k // 2, k - 1})
    picks = _pick_trajectories(dataset)
    tree_trajectory, tree_frame = picks[0], k // 2
    tree = analysed_tree(directory, tree_trajectory, tree_frame)
    parts: dict[str, str] = {}

    parts["frames"] = _frame_figures(figures, task, dataset, picks, frames)
    parts["renders"] = _render_figures(
        figures, task, dataset, capture, picks, frames, tree, tree_trajectory, tree_frame
    )
    missing = _missing_render_extra()
    if missing:
        warn_once(
            f"the report leaves out videos and interactive views: {missing} (pip install 'energy-margin[render]')"
        )
        parts["video"] = f"<p>{html.escape(task)}: no video ({html.escape(missing)}).</p>"
        parts["view"] = f"<li>{html.escape(task)}: no interactive view ({html.escape(missing)}).</li>"
    else:
        parts.update(_video_and_view(report, task, dataset, scores, tree, tree_trajectory, tree_frame))
    lam = tree.likelihood_lambda
    name = f"{task}-cost-field.png"
    plots.cost_field_figure(dataset, tree_trajectory, tree_frame, tree.field, tree.likelihoods, figures / name)
    parts["cost_field"] = _figure(
        name, f"{task}: reached states of one tree coloured by energy cost, and their likelihoods (λ = {lam:g} 1/J)"
    )

    parts["perturbed"] = _perturbed_figures(figures, out, task, row, dataset, tree_trajectory)
    parts.update(_score_figures(figures, task, dataset, capture, success))
    parts["failures"] = failures_html(task, dataset)
    return parts


def _frame_figures(figures: Path, task: str, dataset: Any, picks: list[int], frames: list[int]) -> str:
    """Top or side views of some frames of a successful and a failed trajectory."""
    from energy_margin.report import plots

    parts: dict[str, str] = {}
    frame_html = []
    for trajectory in picks:
        name = f"{task}-frames-{trajectory}.png"
        plots.frame_figure(dataset, trajectory, frames, figures / name)
        outcome = "successful" if dataset.success_labels()[trajectory] else "failed"
        frame_html.append(_figure(name, f"{task}: frames {frames} of a {outcome} trajectory ({trajectory})"))
    parts["frames"] = "".join(frame_html)

    return parts["frames"]


def _render_figures(
    figures: Path,
    task: str,
    dataset: Any,
    capture: np.ndarray,
    picks: list[int],
    frames: list[int],
    tree: Any,
    tree_trajectory: int,
    tree_frame: int,
) -> str:
    """The frames as the engine draws them, one analysed frame with its tree's nodes."""
    from energy_margin.report.render import dataset_renderer, drawn_inside, save_png

    parts: dict[str, str] = {}
    render_cells = []
    for trajectory in picks:
        outcome = "successful" if dataset.success_labels()[trajectory] else "failed"
        with dataset_renderer(dataset, trajectory) as renderer:
            for frame_index in frames:
                frame = dataset.frame(trajectory, frame_index)
                with_tree = trajectory == tree_trajectory and frame_index == tree_frame
                field = tree.field if with_tree else None
                likelihoods = tree.likelihoods if with_tree else None
                name = f"{task}-render-{trajectory}-{frame_index}.png"
                save_png(renderer.render(frame, field=field, likelihoods=likelihoods), figures / name)
                time_s = float(dataset.arrays["frame_time"][trajectory, frame_index])
                shape = dataset.task.capture_region_shape(frame)
                caption = (
                    f"{outcome} trajectory {trajectory}, frame {frame_index} (t = {time_s:.2f} s), "
                    f"capture score {capture[trajectory, frame_index]:.2f}; capture region: {shape}; "
                    + _membership_note(dataset.task, frame, drawn_inside)
                    + ("; tree nodes coloured by likelihood" if with_tree else "")
                )
                render_cells.append(_image(f"figures/{name}", caption))
        backend = renderer.backend
    drawn_by = "MuJoCo's offscreen renderer" if backend == "mujoco" else "matplotlib (no OpenGL context)"
    parts["renders"] = (
        f"<h3>{html.escape(task)}</h3><p>{html.escape(dataset.task.region_caption)} Drawn by {drawn_by}.</p>"
        + _grid(render_cells)
    )
    return parts["renders"]


def _perturbed_figures(
    figures: Path, out: Path, task: str, row: dict[str, Any], dataset: Any, tree_trajectory: int
) -> str:
    """One true frame beside copy 1 of its perturbed datasets (of each protocol), in one view."""
    from energy_margin.data.dataset import load_dataset
    from energy_margin.report.render import dataset_renderer, save_png, scene_view

    k = dataset.n_frames
    parts: dict[str, str] = {}
    perturbed_cells = []
    copies = row.get("perturbed") or []
    if copies:
        frame_index = k // 2
        true_frame = dataset.frame(tree_trajectory, frame_index)
        # Copy 1 of each protocol: (file name part, caption, dataset).
        shown = [("perturbed", "perturbed copy 1 (valid protocol)", load_dataset(out / copies[0]))]
        paper_copies = (row.get("by_protocol") or {}).get("paper", {}).get("perturbed") or []
        if paper_copies:
            shown.append(("paper", "perturbed copy 1 (paper protocol)", load_dataset(out / paper_copies[0])))
        states = [("true", "true", true_frame, dataset)] + [
            (part, label, source.frame(tree_trajectory, frame_index), source) for part, label, source in shown
        ]
        with dataset_renderer(dataset, tree_trajectory) as renderer:
            view = scene_view(
                renderer.simulator.scene,
                np.concatenate([renderer.view_points(state) for _, _, state, _ in states]),
            )
            for part, label, state, source_set in states:
                name = f"{task}-perturbed-{part}.png"
                save_png(renderer.render(state, view=view), figures / name)
                captured = bool(source_set.arrays["captured"][tree_trajectory, frame_index])
                perturbed_cells.append(
                    _image(
                        f"figures/{name}",
                        f"{task}, trajectory {tree_trajectory}, frame {frame_index}: {label} state "
                        f"(captured: {'yes' if captured else 'no'})",
                    )
                )
    parts["perturbed"] = f"<h3>{html.escape(task)}</h3>" + _grid(perturbed_cells)
    return parts["perturbed"]


def _score_figures(figures: Path, task: str, dataset: Any, capture: np.ndarray, success: np.ndarray) -> dict[str, str]:
    """The scores along every trajectory against the labels, and the precision-recall curves."""
    from energy_margin.analysis.scores import trajectory_success_score
    from energy_margin.report import plots

    k = dataset.n_frames
    parts: dict[str, str] = {}
    name = f"{task}-trajectories.png"
    plots.trajectory_scores_figure(dataset, capture, success, figures / name)
    parts["trajectories"] = _figure(name, f"{task}: capture and success scores of every frame against the labels")

    half = max(1, k // 2)
    labels = dataset.success_labels()
    curves = {
        r"capture, $\hat{k} = 0$": (dataset.capture_labels(0), capture),
        r"capture, $\hat{k} = 2$": (dataset.capture_labels(2), capture),
        "success, last 3 frames": (labels, trajectory_success_score(success, last=3)),
        "success, first half": (labels, trajectory_success_score(success[:, :half], last=3)),
    }
    name = f"{task}-precision-recall.png"
    plots.precision_recall_figure(curves, figures / name, title=f"{task}: precision-recall of the energy-margin scores")
    parts["precision_recall"] = _figure(
        name, f"{task}: precision-recall curves; dotted: chance (the positive rate); k̂: capture window in frames"
    )
    return parts


def _missing_render_extra() -> str:
    """What of the ``render`` extra is not installed ("" when everything is)."""
    missing = [
        name for name in ("imageio", "imageio_ffmpeg", "PIL", "plotly") if importlib.util.find_spec(name) is None
    ]
    return f"{', '.join(missing)} not installed" if missing else ""


def _video_and_view(
    report: Path, task: str, dataset: Any, scores: Any, tree: Any, tree_trajectory: int, tree_frame: int
) -> dict[str, str]:
    """The task's video and interactive view, written beside the page, and their HTML."""
    from energy_margin.report.render import save_png
    from energy_margin.report.video import render_video
    from energy_margin.report.view import write_view

    figures = report / "figures"
    parts: dict[str, str] = {}
    videos = report / "videos"
    videos.mkdir(exist_ok=True)
    result = render_video(dataset, tree_trajectory, videos / f"{task}.mp4", scores=scores)
    source = f"videos/{result.path.name}"
    caption = (
        f"{task}: trajectory {tree_trajectory} at {result.fps:g} pictures per second of simulated time "
        f"({result.frames} pictures, {result.width} × {result.height}); the strip plots the frame scores"
    )
    if result.path.suffix == ".gif":
        parts["video"] = _image(source, caption)
    else:
        poster = f"{task}-video-poster.png"
        if result.poster is not None:
            save_png(result.poster, figures / poster)
        parts["video"] = (
            f'<figure class="cell"><video src="{source}" poster="figures/{poster}" controls loop muted '
            f'preload="metadata" width="{result.width}"></video><figcaption>{html.escape(caption)}</figcaption>'
            "</figure>"
        )

    views = report / "views"
    views.mkdir(exist_ok=True)
    view_name = f"{task}-T{tree_trajectory}-F{tree_frame}.html"
    write_view(tree, views / view_name)
    parts["view"] = (
        f'<li><a href="views/{view_name}">{html.escape(task)}: trajectory {tree_trajectory}, frame {tree_frame}</a> '
        f"({tree.field.nodes} nodes, capture {tree.stored['capture_score']:.2f}, success "
        f"{tree.stored['success_score']:.2f}; opens in any browser, no server)</li>"
    )

    return parts
