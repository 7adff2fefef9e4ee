"""The held-out report of a learned margin: R², AP beside the tree's AP, and the time per query."""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from energy_margin.analysis.scores import trajectory_success_score
from energy_margin.evaluation.metrics import average_precision
from energy_margin.learning.margin_file import (
    MarginModel,
)
from energy_margin.learning.margin_frames import (
    _Frames,
)
from energy_margin.runs.results import TypedResult
from energy_margin.world.state import FrameState

__all__ = ["MarginModelReport"]


@dataclass(frozen=True, kw_only=True)
class MarginModelReport(TypedResult):
    """How a learned margin does on held-out trajectories: the report of ``fit_margin_model``.

    :func:`~energy_margin.learning.margin_model.fit_margin_model` returns it; ``to_dict()`` is the
    report saved in the model file (``MarginModel.report``) and the JSON ``learn`` prints (the
    command's own keys after it).

    Attributes:
        r2: R² of the held-out frames' ``capture`` and ``success`` scores, learned against the
            tree's (``None`` where the tree's scores are constant).
        ap: per question (``capture``: per frame, labels at k-hat 0; ``capture_window2``: labels
            at k-hat 2; ``success``: per trajectory, from the last ``success_frames`` frames;
            ``success_first_half``: from the first half of the frames), the Average Precision of
            the ``learned`` scores beside the ``tree``'s on the same frames, in [0, 1] (``None``
            with one class of labels).
        success_frames: k-bar of the trajectory success AP.
        capture_positive_rate: fraction of held-out frames captured (k-hat 0), in [0, 1].
        success_positive_rate: fraction of held-out trajectories that succeed, in [0, 1].
        seconds_per_query: one batched predict over the held-out frames, per frame, wall time, s.
        seconds_single_query: one predict of a single frame, wall time, s.
        cpu_seconds_per_query: ``seconds_per_query`` in CPU time, s.
        cpu_seconds_single_query: ``seconds_single_query`` in CPU time, s.
        tree_seconds_per_frame: the analysis' mean wall time of the held-out frames
            (``scores.csv``), s.
        speedup: ``tree_seconds_per_frame / seconds_per_query`` (``None`` at zero query time).
        speedup_single_query: ``tree_seconds_per_frame / seconds_single_query`` (likewise).
        task: the task's registered name.
        kind: the regressor kind (``mlp``, ``boosting``, ``set``).
        seed: seed of the split and of the regressor.
        holdout: fraction of the trajectories held out, in (0, 1).
        feature_set: the features' identifier (``frame-statistics/1``, ``object-sets/1``).
        n_features: features per frame (channels per object for ``set``).
        n_trajectories: trajectories ``train`` and ``held_out``.
        n_frames: frames ``train`` and ``held_out``.
        fit_seconds: wall time of the regressor's fit, s.
        fit: what the regressor reports of its fit (iterations, losses; kind-specific).
        datasets: the datasets' directories, in the order given.

    """

    r2: dict[str, float | None]
    ap: dict[str, dict[str, float | None]]
    success_frames: int
    capture_positive_rate: float
    success_positive_rate: float
    seconds_per_query: float
    seconds_single_query: float
    cpu_seconds_per_query: float
    cpu_seconds_single_query: float
    tree_seconds_per_frame: float
    speedup: float | None
    speedup_single_query: float | None
    task: str
    kind: str
    seed: int
    holdout: float
    feature_set: str
    n_features: int
    n_trajectories: dict[str, int]
    n_frames: dict[str, int]
    fit_seconds: float
    fit: dict[str, Any]
    datasets: list[str]


def _r2(truth: np.ndarray, predicted: np.ndarray) -> float | None:
    """Coefficient of determination, or ``None`` when the truth is constant (variance below 1e-12)."""
    from sklearn.metrics import r2_score

    if float(np.var(truth)) < 1e-12:
        return None
    return float(r2_score(truth, predicted))


def _held_out_report(
    model: MarginModel,
    frames: list[_Frames],
    held: set[tuple[int, int]],
    test_x: np.ndarray,
    test_y: np.ndarray,
    *,
    success_frames: int,
) -> dict[str, Any]:
    """R², AP beside the tree's AP, and the time per query on the held-out trajectories."""
    task = frames[0].dataset.task
    learned = np.clip(model.regressor.predict(test_x), 0.0, 1.0)
    capture_labels, learned_capture, tree_capture = [], [], []
    success_labels, learned_success, tree_success = [], [], []
    future_labels, early_learned, early_tree = [], [], []
    runtimes: list[np.ndarray] = []
    states: list[FrameState] = []
    offset = 0
    for d, item in enumerate(frames):
        dataset, k = item.dataset, item.dataset.n_frames
        labels = dataset.capture_labels(0)
        trajectories = [t for t in range(dataset.n_trajectories) if (d, t) in held]
        if not trajectories:
            continue
        block = learned[offset : offset + len(trajectories) * k].reshape(len(trajectories), k, 2)
        offset += len(trajectories) * k
        capture_labels.append(labels[trajectories].ravel())
        learned_capture.append(block[:, :, 0].ravel())
        tree_capture.append(item.capture[trajectories].ravel())
        last = min(success_frames, k)
        success_labels.append(dataset.success_labels()[trajectories])
        learned_success.append(trajectory_success_score(block[:, :, 1], last=last, scheme="linear"))
        tree_success.append(trajectory_success_score(item.success[trajectories], last=last, scheme="linear"))
        future_labels.append(dataset.capture_labels(min(2, k - 1))[trajectories].ravel())
        half = max(1, k // 2)
        early_learned.append(trajectory_success_score(block[:, :half, 1], last=min(last, half), scheme="linear"))
        early_tree.append(
            trajectory_success_score(item.success[trajectories, :half], last=min(last, half), scheme="linear")
        )
        runtimes.append(item.runtime[trajectories].ravel())
        states.extend(dataset.frame(t, i) for t in trajectories for i in range(k))
    batched, batched_cpu = (
        value / len(states) for value in _seconds_per_call(lambda: model.predict(task, states), repeats=5)
    )
    single, single_cpu = _seconds_per_call(lambda: model.predict(task, states[:1]), repeats=50)
    tree_seconds = float(np.concatenate(runtimes).mean())
    return {
        "r2": {"capture": _r2(test_y[:, 0], learned[:, 0]), "success": _r2(test_y[:, 1], learned[:, 1])},
        "ap": {
            "capture": {
                "learned": average_precision(np.concatenate(capture_labels), np.concatenate(learned_capture)),
                "tree": average_precision(np.concatenate(capture_labels), np.concatenate(tree_capture)),
            },
            "success": {
                "learned": average_precision(np.concatenate(success_labels), np.concatenate(learned_success)),
                "tree": average_precision(np.concatenate(success_labels), np.concatenate(tree_success)),
            },
            "capture_window2": {
                "learned": average_precision(np.concatenate(future_labels), np.concatenate(learned_capture)),
                "tree": average_precision(np.concatenate(future_labels), np.concatenate(tree_capture)),
            },
            "success_first_half": {
                "learned": average_precision(np.concatenate(success_labels), np.concatenate(early_learned)),
                "tree": average_precision(np.concatenate(success_labels), np.concatenate(early_tree)),
            },
        },
        "success_frames": success_frames,
        "capture_positive_rate": float(np.concatenate(capture_labels).mean()),
        "success_positive_rate": float(np.concatenate(success_labels).mean()),
        "seconds_per_query": batched,
        "seconds_single_query": single,
        "cpu_seconds_per_query": batched_cpu,
        "cpu_seconds_single_query": single_cpu,
        "tree_seconds_per_frame": tree_seconds,
        "speedup": tree_seconds / batched if batched > 0 else None,
        "speedup_single_query": tree_seconds / single if single > 0 else None,
    }


def _seconds_per_call(call: Any, *, repeats: int) -> tuple[float, float]:
    """Median wall time and median CPU time of this process of ``call()`` over ``repeats`` calls, s.

    One warm-up call comes first. On a busy machine the wall time of a long call includes the
    time the process waits for a core; the CPU time does not.
    """
    call()
    wall, cpu = [], []
    for _ in range(repeats):
        tick, cpu_tick = time.perf_counter(), time.process_time()
        call()
        wall.append(time.perf_counter() - tick)
        cpu.append(time.process_time() - cpu_tick)
    return float(np.median(wall)), float(np.median(cpu))
