"""Table I of the paper: AP on true states beside AP on perturbed states, and the score error.

:func:`compare_perturbed` reads a scored true-state dataset and scored perturbed copies of it
(:mod:`energy_margin.robustness.perturb`), which must correspond frame by frame (same task, T, K, n and the
same labels). Perturbed AP is the mean ± standard deviation (population, ddof = 0, as the paper's
values) over the copies; the score error is perturbed − true per frame, pooled over every frame
of every copy, mean ± standard deviation, for the capture score and the per-frame success score.
The copies must come from one perturbation protocol (``perturbation.protocol`` in their
``dataset.json``: ``valid`` or ``paper``; copies written before the choice existed are ``valid``),
which the result names.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.data.dataset import METADATA_FILE, Dataset, load_dataset
from energy_margin.data.scores_file import load_scores
from energy_margin.errors import EnergyMarginError, InvalidParameterError
from energy_margin.evaluation.metrics import Evaluation, evaluate, score_grid
from energy_margin.runs.results import plain_result

__all__ = [
    "PerturbedComparison",
    "compare_perturbed",
    "copy_protocol",
    "expand_compare_paths",
    "format_robustness_table",
]


def expand_compare_paths(paths: list[Path | str]) -> list[Path]:
    """Datasets named by ``paths``.

    Each path is a dataset directory itself, or a parent of dataset directories (e.g. ``perturb``'s
    ``out``: its sub-directories, in numeric then name order).
    """
    expanded: list[Path] = []
    for item in paths:
        path = Path(item)
        if (path / METADATA_FILE).is_file() or not path.is_dir():
            expanded.append(path)
            continue
        children = [child for child in path.iterdir() if (child / METADATA_FILE).is_file()]
        if not children:
            raise EnergyMarginError(f"{path} is neither a dataset nor a directory of datasets")
        children.sort(key=lambda child: (0, int(child.name), "") if child.name.isdigit() else (1, 0, child.name))
        expanded.extend(children)
    return expanded


def _check_correspondence(true: Dataset, other: Dataset, where: Path) -> None:
    for key in ("task", "n_trajectories", "n_frames", "n_objects"):
        if true.metadata.get(key) != other.metadata.get(key):
            raise EnergyMarginError(
                f"{where} does not correspond to the true-state dataset: {key} is "
                f"{other.metadata.get(key)!r}, expected {true.metadata.get(key)!r}"
            )
    for name in ("captured", "in_success"):
        if not np.array_equal(true.arrays[name], other.arrays[name]):
            raise EnergyMarginError(
                f"{where} does not correspond to the true-state dataset: its {name!r} labels differ"
            )


def copy_protocol(dataset: Dataset) -> str | None:
    """The perturbation protocol of a perturbed copy (``None`` for a dataset that is not one)."""
    info = dataset.metadata.get("perturbation")
    if not isinstance(info, dict):
        return None
    return str(info.get("protocol", "valid"))


def _mean_std(values: list[float | None] | np.ndarray) -> dict[str, Any]:
    if any(v is None for v in values):
        return {"mean": None, "std": None, "values": list(values)}
    array = np.asarray(values, dtype=float)
    return {"mean": float(array.mean()), "std": float(array.std()), "values": [float(v) for v in array]}


@dataclass(frozen=True, kw_only=True)
class PerturbedComparison(Evaluation):
    """The true states' :class:`~energy_margin.evaluation.metrics.Evaluation` and Table I's comparison.

    ``to_dict()`` is the JSON of ``evaluate --compare --json``.

    Attributes:
        capture_ap_perturbed: the copies' capture AP: ``mean``, ``std`` and ``values`` per copy.
        success_ap_perturbed: the copies' success AP, likewise.
        capture_score_error: a copy's capture score minus the true state's: ``mean``, ``std`` and
            the mean per copy (``values``).
        success_score_error: the same for the success score.
        n_repeats: perturbed copies compared.
        protocol: their perturbation protocol (``valid``, ``paper``; ``None`` for copies made otherwise).
        compare: the copies' directories.
        runtime_per_frame_perturbed_s: mean wall time of a copy's frame, s.

    """

    capture_ap_perturbed: dict[str, Any]
    success_ap_perturbed: dict[str, Any]
    capture_score_error: dict[str, Any]
    success_score_error: dict[str, Any]
    n_repeats: int
    protocol: str | None
    compare: list[str]
    runtime_per_frame_perturbed_s: float


def compare_perturbed(
    path: Path | str,
    compare: list[Path | str],
    *,
    capture_window: int = 0,
    success_frames: int = 3,
    weights: str = "linear",
    resamples: int = 1000,
    seed: int = 0,
) -> PerturbedComparison:
    """Evaluate the true-state dataset at ``path`` and its perturbed copies ``compare``.

    ``resamples`` and ``seed`` are those of the true-state dataset's verdict (``evaluate``).

    Returns:
        The :class:`PerturbedComparison`: :func:`~energy_margin.evaluation.metrics.evaluate`'s
        fields for the true states and the copies' APs and score errors.

    Raises:
        EnergyMarginError: when a copy is missing, unscored or does not correspond, or when the
            copies mix perturbation protocols.

    """
    options: dict[str, Any] = {"capture_window": capture_window, "success_frames": success_frames, "weights": weights}
    result = evaluate(path, **options, resamples=resamples, seed=seed).to_dict()
    others = _copy_paths(path, compare)
    true = load_dataset(path)
    true_scores = load_scores(path)
    true_capture = score_grid(true, true_scores, "capture_score")
    true_success = score_grid(true, true_scores, "success_score")
    capture_aps: list[float | None] = []
    success_aps: list[float | None] = []
    capture_errors: list[np.ndarray] = []
    success_errors: list[np.ndarray] = []
    runtimes: list[float] = []
    protocols: dict[str | None, Path] = {}
    for other_path in others:
        other = load_dataset(other_path)
        _check_correspondence(true, other, other_path)
        _add_protocol(protocols, copy_protocol(other), Path(other_path))
        other_result = evaluate(other_path, **options, resamples=0)  # a copy's AP, no verdict
        scores = load_scores(other_path)
        capture_errors.append(score_grid(other, scores, "capture_score") - true_capture)
        success_errors.append(score_grid(other, scores, "success_score") - true_success)
        capture_aps.append(other_result.capture_ap)
        success_aps.append(other_result.success_ap)
        runtimes.append(other_result.runtime_per_frame_s)
    result.update(
        {
            "capture_ap_perturbed": _mean_std(capture_aps),
            "success_ap_perturbed": _mean_std(success_aps),
            "capture_score_error": _error_summary(np.stack(capture_errors)),
            "success_score_error": _error_summary(np.stack(success_errors)),
            "n_repeats": len(others),
            "protocol": next(iter(protocols)),
            "compare": [str(p) for p in others],
            "runtime_per_frame_perturbed_s": float(np.mean(runtimes)),
        }
    )
    return PerturbedComparison.from_dict(result)


def _copy_paths(path: Path | str, compare: list[Path | str]) -> list[Path]:
    """The perturbed copies' directories (``compare`` expanded); refuses none, and the dataset itself."""
    others = expand_compare_paths(list(compare))
    if not others:
        raise InvalidParameterError("compare", "needs at least one perturbed dataset")
    for candidate in others:
        if candidate.resolve() == Path(path).resolve():
            raise InvalidParameterError(
                "compare", f"{candidate} compares the dataset with itself: name its perturbed copies"
            )
    return others


def _add_protocol(protocols: dict[str | None, Path], protocol: str | None, path: Path) -> None:
    """Record the copy's perturbation protocol (the first copy of each); refuses a second protocol."""
    protocols.setdefault(protocol, path)
    if len(protocols) > 1:
        (first, first_path), (second, second_path) = list(protocols.items())[:2]
        raise InvalidParameterError(
            "compare",
            f"mixes perturbation protocols: {first_path} is {first or 'not a perturbed copy'}, "
            f"{second_path} is {second or 'not a perturbed copy'}; compare one protocol at a time",
        )


def _error_summary(error: np.ndarray) -> dict[str, Any]:
    """Mean and standard deviation of score errors of shape (copies, ...), and each copy's mean."""
    return {
        "mean": float(error.mean()),
        "std": float(error.std()),
        "values": [float(e.mean()) for e in error],
    }


def _pm(entry: dict[str, Any], signed: bool = False) -> str:
    if entry["mean"] is None:
        return "n/a"
    sign = "+" if signed else ""
    return f"{entry['mean']:{sign}.2f} ± {entry['std']:.2f}"


def format_robustness_table(result: PerturbedComparison | dict[str, Any]) -> str:
    """Table I row of :func:`compare_perturbed`'s result (or its dictionary), human-readable."""
    result = plain_result(result)

    def cell(value: float | None) -> str:
        return "n/a" if value is None else f"{value:.2f}"

    header = f"{'score':10s} {'true state':>11s} {'perturbed state':>16s} {'error':>14s}"
    protocol = result.get("protocol")
    named = f", {protocol} protocol" if protocol else ""
    lines = [
        f"Table I ({result['task']}, {result['n_objects']} objects, {result['n_repeats']} perturbed repeats{named}; "
        "perturbed: mean ± std over repeats; error: perturbed - true over every frame)",
        header,
        "-" * len(header),
        f"{'capture':10s} {cell(result['capture_ap']):>11s} {_pm(result['capture_ap_perturbed']):>16s} "
        f"{_pm(result['capture_score_error'], True):>14s}",
        f"{'success':10s} {cell(result['success_ap']):>11s} {_pm(result['success_ap_perturbed']):>16s} "
        f"{_pm(result['success_score_error'], True):>14s}",
    ]
    return "\n".join(lines)
