"""Score every frame of a dataset with a learned margin: ``scores.csv`` without growing trees.

:func:`score_dataset` is ``energy-margin analyze DIR --model MODEL``: it predicts the capture and
success scores of every frame with a model written by ``energy-margin learn``
(:class:`~energy_margin.learning.margin_model.MarginModel`) and writes the same ``scores.csv`` a
tree analysis writes (:mod:`energy_margin.data.scores_file`), so ``evaluate``, ``perturb``'s
comparison (Table I), ``learn`` and the report read it unchanged.

``analysis.json`` beside it records the learned equivalent of a tree analysis's settings: the
analyzer ``"learned margin"`` (a string where a tree analysis has its settings), the model (path,
SHA-256 of the file, regressor kind, feature definition, task, training range of objects), the
dataset, the task settings, the seed and the versions. Both kinds of analysis open the dataset's
folder with the one rule of :func:`energy_margin.runs.open_run`: the analyzer, the model's file
contents (not its path), the dataset and the task settings decide the scores, so a tree analysis
refuses to replace learned scores (and a learned one tree scores, or those of another model)
without ``overwrite``. The same model again keeps the finished ``scores.csv``.
"""

from __future__ import annotations

import hashlib
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.analysis.run import write_scores
from energy_margin.data.dataset import Dataset
from energy_margin.data.scores_file import CONFIG_FILE, JOURNAL_FILE, SCORES_FILE, UNKNOWN_COUNT
from energy_margin.data.validation import require_valid
from energy_margin.errors import EnergyMarginError, check_positive_int, check_seed
from energy_margin.learning.margin_file import MarginModel, load_margin_model
from energy_margin.runs import RunSpec, open_run, progress_bar
from energy_margin.runs.directory import run_versions
from energy_margin.runs.progress import Progress

__all__ = [
    "FRAMES_PER_CALL",
    "LEARNED_ANALYSIS_RUN",
    "LEARNED_ANALYZER",
    "LEARNED_NODES",
    "LearnedFrameScorer",
    "file_sha256",
    "learned_description",
    "predict_rows",
    "score_dataset",
]

#: ``analyzer`` of ``analysis.json`` for learned scores (a tree analysis records its settings there).
LEARNED_ANALYZER = "learned margin"
#: Frames per :meth:`MarginModel.predict` call.
FRAMES_PER_CALL = 256
#: ``nodes`` of a learned row: the frame's own state only, no tree grown (``scores.csv`` requires >= 1).
LEARNED_NODES = 1


def _normalize(settings: dict[str, Any], earlier: bool) -> dict[str, Any]:
    """The settings as they decide the scores: the model by its contents, not by where its file lies."""
    del earlier
    model = settings.get("model")
    if isinstance(model, dict):
        settings["model"] = {key: value for key, value in model.items() if key != "path"}
    return settings


#: A learned analysis of a dataset: ``analysis.json`` beside the dataset's files, then
#: ``scores.csv`` (the tree analysis's journal is one of its outputs only so that ``overwrite``
#: removes it). The analyzer, the model (SHA-256 and what the file declares), the dataset and the
#: task settings decide the scores; the model's path, the seed and the versions do not.
LEARNED_ANALYSIS_RUN = RunSpec(
    contents="scores",
    settings_file=CONFIG_FILE,
    outputs=(JOURNAL_FILE, SCORES_FILE),
    compared=("analyzer", "model", "dataset", "task_config"),
    shared_directory=True,
    normalize=_normalize,
)


def file_sha256(path: Path | str) -> str:
    """SHA-256 of the file at ``path``, hex.

    Raises:
        EnergyMarginError: the file cannot be read.
    """
    digest = hashlib.sha256()
    try:
        with Path(path).open("rb") as stream:
            for block in iter(lambda: stream.read(1 << 20), b""):
                digest.update(block)
    except OSError as error:
        raise EnergyMarginError(f"margin model {path} cannot be read ({error.strerror})") from None
    return digest.hexdigest()


def learned_description(
    dataset: Dataset, model: MarginModel, model_path: Path | str, sha256: str, *, seed: int
) -> dict[str, Any]:
    """What ``analysis.json`` records of a learned analysis: analyzer, model, seed, dataset, task, versions.

    Args:
        dataset: the scored dataset.
        model: the loaded model.
        model_path: its file (recorded as an absolute path).
        sha256: SHA-256 of that file, hex.
        seed: the seed of the command (recorded; a learned margin is deterministic).

    Returns:
        The JSON-compatible settings.
    """
    return {
        "analyzer": LEARNED_ANALYZER,
        "model": {
            "path": os.path.abspath(model_path),
            "sha256": sha256,
            "kind": model.kind,
            "task": model.task_name,
            "feature_set": model.feature_set,
            "n_objects": list(model.n_objects_range),
            "package_version": model.package_version,
        },
        "seed": int(seed),
        "dataset": dataset.identity(),
        "task_config": dataset.task.config.to_dict(),
        "frames_per_call": FRAMES_PER_CALL,
        "versions": run_versions(),
    }


def predict_rows(
    model: MarginModel, dataset: Dataset, *, frames_per_call: int = FRAMES_PER_CALL, progress: Progress = False
) -> dict[tuple[int, int], dict[str, Any]]:
    """The ``scores.csv`` rows of every frame of ``dataset``, by (trajectory, frame).

    Frames are predicted in trajectory-major order, ``frames_per_call`` per
    :meth:`MarginModel.predict` call. Each row holds ``capture_score`` and ``success_score`` in
    [0, 1]; ``runtime_s``, the wall time of its call divided by the frames of the call (s per
    frame, the features and the regressor, not reading the frames); ``nodes``
    :data:`LEARNED_NODES`, and ``expansions``, ``physics_s`` and ``seed`` 0 (no tree, no physics,
    nothing drawn).

    Args:
        model: the learned margin (of the dataset's task).
        dataset: the dataset, T trajectories of K frames.
        frames_per_call: frames per predict call, >= 1.
        progress: show a progress bar on standard error.

    Returns:
        T x K rows with the columns of :data:`energy_margin.data.scores_file.COLUMNS`.

    Raises:
        EnergyMarginError: the model cannot score a frame, or predicts a non-finite score.
        ValueError: ``frames_per_call`` is not a positive integer.
    """
    check_positive_int("frames_per_call", frames_per_call)
    task = dataset.task
    n_frames = dataset.n_frames
    total = dataset.n_trajectories * n_frames
    rows: dict[tuple[int, int], dict[str, Any]] = {}
    bar = progress_bar(total, desc="analyze", enabled=progress)
    try:
        for start in range(0, total, frames_per_call):
            keys = [divmod(index, n_frames) for index in range(start, min(start + frames_per_call, total))]
            frames = [dataset.frame(trajectory, index) for trajectory, index in keys]
            started = time.perf_counter()
            try:
                capture, success = model.predict(task, frames)
            except ValueError as error:
                raise EnergyMarginError(f"the margin model cannot score {dataset.path}: {error}") from None
            seconds = (time.perf_counter() - started) / len(keys)
            bad = np.flatnonzero(~(np.isfinite(capture) & np.isfinite(success)))
            if bad.size:
                trajectory, index = keys[int(bad[0])]
                raise EnergyMarginError(
                    f"the margin model predicts a non-finite score for trajectory {trajectory}, frame {index} "
                    f"of {dataset.path}"
                )
            for (trajectory, index), capture_score, success_score in zip(keys, capture, success, strict=True):
                rows[(trajectory, index)] = {
                    "trajectory": trajectory,
                    "frame": index,
                    "capture_score": float(capture_score),
                    "success_score": float(success_score),
                    "nodes": LEARNED_NODES,
                    "expansions": 0,
                    "runtime_s": float(seconds),
                    "physics_s": 0.0,
                    "seed": 0,
                    "rejected": UNKNOWN_COUNT,
                    "diverged": UNKNOWN_COUNT,
                }
            bar.update(len(keys))
    finally:
        bar.close()
    return rows


def score_dataset(
    path_or_dataset: Path | str | Dataset,
    model_path: Path | str,
    *,
    overwrite: bool = False,
    progress: Progress = True,
    seed: int = 0,
) -> Path:
    """Score every frame of a dataset with a learned margin and write ``scores.csv`` beside it.

    The model is read for the dataset's task and checked against the dataset
    (:meth:`MarginModel.check_dataset`) before anything is written. ``analysis.json`` (the
    settings, :func:`learned_description`) is written first, then ``scores.csv`` atomically, one
    row per frame sorted by trajectory and frame, with the columns of a tree analysis
    (:func:`predict_rows` says what each holds). Running again with the same model file contents
    keeps the finished ``scores.csv``; an interrupted run predicts every frame again (no journal:
    a dataset takes seconds).

    Args:
        path_or_dataset: dataset directory, or a dataset loaded from one (``load_dataset``; it is
            not validated again).
        model_path: the model file written by ``energy-margin learn``.
        overwrite: replace scores of another configuration (a tree analysis, another model)
            instead of refusing.
        progress: show a progress bar on standard error.
        seed: non-negative integer, recorded in ``analysis.json``; a learned margin draws
            nothing, so it changes no score.

    Returns:
        The path of ``scores.csv``.

    Raises:
        EnergyMarginError: a dataset with a problem or without a directory; a missing, corrupt or
            foreign model file, a model of another task, or one that cannot score this dataset
            (its object count, its compiled model); scores of another configuration in the
            directory without ``overwrite``; another process writing there (one line each).
        InvalidParameterError: a bad ``seed``.
    """
    check_seed(seed)
    if isinstance(path_or_dataset, Dataset):
        dataset = path_or_dataset
        if dataset.path is None:
            raise EnergyMarginError("a dataset read from disk is needed: scores.csv is written beside it")
        directory = Path(dataset.path)
    else:
        dataset = require_valid(path_or_dataset, overlaps=True, scores=False)
        directory = Path(path_or_dataset)
    model = load_margin_model(model_path, task_name=str(dataset.metadata["task"]))
    model.check_dataset(dataset)
    description = learned_description(dataset, model, model_path, file_sha256(model_path), seed=seed)
    scores_path = directory / SCORES_FILE
    with open_run(directory, LEARNED_ANALYSIS_RUN, description, overwrite=overwrite) as run:
        if run.resumed and scores_path.exists():
            return scores_path
        return write_scores(directory, predict_rows(model, dataset, progress=progress))


class LearnedFrameScorer:
    """The learned objective of ``energy-margin design --objective learned``: :func:`score_dataset` of each design.

    The model is read, and checked against the task and the number of objects, when the scorer
    is made, so a search with a model that cannot score its designs is refused before it starts.

    Args:
        model_path: the model file written by ``energy-margin learn``.
        task_name: the searched task.
        n_objects: objects per scene of the search.

    Raises:
        EnergyMarginError: a missing, corrupt or foreign model file, a model of another task, or
            one fitted on other numbers of objects.

    """

    def __init__(self, model_path: Path | str, *, task_name: str, n_objects: int) -> None:
        model = load_margin_model(model_path, task_name=task_name)
        fewest, most = model.n_objects_range
        if not fewest <= n_objects <= most:
            raise EnergyMarginError(
                f"the margin model {model_path} was fitted on {fewest if fewest == most else f'{fewest} to {most}'} "
                f"objects, not {n_objects}"
            )
        self.model_path = str(model_path)
        self.sha256 = file_sha256(model_path)
        self.kind = model.kind
        self.feature_set = model.feature_set

    def settings(self) -> dict[str, Any]:
        """What decides the scores: the model's contents (SHA-256), kind and features, not its path."""
        return {"kind": "learned", "model_sha256": self.sha256, "model_kind": self.kind, "features": self.feature_set}

    def score(self, directory: Path, *, seed: int, workers: int) -> None:
        """Write the learned ``scores.csv`` of the dataset in ``directory`` (one process: it takes a moment)."""
        del workers
        score_dataset(directory, self.model_path, progress=False, seed=seed)
