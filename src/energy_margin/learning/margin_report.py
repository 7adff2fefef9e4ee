"""The held-out report of a learned margin: R², AP beside the tree's AP, and the time per query."""

from __future__ import annotations

import time
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
from energy_margin.world.state import FrameState

__all__ = []


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
