"""One task of a study: its dataset (generated once in ``OUT/<task>/dataset``), questions and answers."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.data.dataset import Dataset, load_dataset
from energy_margin.data.generate import generate_dataset
from energy_margin.errors import EnergyMarginError
from energy_margin.evaluation.bootstrap import Questions, Scored, score_questions
from energy_margin.evaluation.metrics import score_grid
from energy_margin.experiments.budget import baseline_grids
from energy_margin.experiments.study_result import BASELINES, positive_rates, study_questions

__all__ = [
    "TaskState",
    "study_dataset",
]


@dataclass
class TaskState:
    """One task's dataset, questions, resamples and the answers so far.

    Attributes:
        task: the task's name.
        directory: its dataset, ``OUT/<task>/dataset``.
        dataset: the dataset.
        questions: the six questions on it.
        resamples: trajectory indices of every bootstrap resample, shape (n, T).
        rates: positive rate of each question.
        meta: what ``study.json`` records of the task.
        scored: the answers by (scorer, budget); the baselines at budget 0.
        lambda_differences: every lambda against the task's own, paired.

    """

    task: str
    directory: Path
    dataset: Dataset
    questions: Questions
    resamples: np.ndarray
    rates: dict[str, float]
    meta: dict[str, Any]
    scored: dict[tuple[str, int], Scored]
    lambda_differences: list[dict[str, Any]] = dataclasses.field(default_factory=list)

    @classmethod
    def open(
        cls, out: Path, task: str, spec: Any, n_trajectories: int, n_frames: int, seed: int, bootstrap: int
    ) -> TaskState:
        """Generate (or check) the dataset of ``task`` under ``out`` and answer its baselines.

        ``spec``: the task's objects per scene and generation seed (``objects``, ``seed``).
        """
        dataset = study_dataset(out, task, spec.objects, spec.seed, n_trajectories=n_trajectories, n_frames=n_frames)
        rates = positive_rates(dataset)
        meta = {
            "objects": dataset.n_objects,
            "dataset_seed": spec.seed,
            "positive_rates": rates,
            "likelihood_lambda": dataset.task.config.likelihood_lambda,
        }
        questions = study_questions(dataset)
        resamples = np.random.default_rng(seed).integers(0, n_trajectories, (bootstrap, n_trajectories))
        state = cls(task, out / task / "dataset", dataset, questions, resamples, rates, meta, {})
        grids = dict(baseline_grids(dataset))
        constant = np.full(dataset.arrays["captured"].shape, 0.5)
        grids["chance"] = (constant, constant)
        for name in BASELINES:
            if name in grids:
                state.scored[(name, 0)] = score_questions(questions, *grids[name], resamples)
        return state

    def score(self, scores: dict[str, np.ndarray]) -> Scored:
        """The answers of a scores file's columns, on the task's resamples."""
        capture = score_grid(self.dataset, scores, "capture_score")
        success = score_grid(self.dataset, scores, "success_score")
        return score_questions(self.questions, capture, success, self.resamples)


def study_dataset(out: Path, task: str, objects: int, seed: int, *, n_trajectories: int, n_frames: int) -> Dataset:
    """The dataset of ``task`` in ``OUT/<task>/dataset``: generated, or checked to be the one asked for."""
    directory = out / task / "dataset"
    if directory.exists():
        dataset = load_dataset(directory)
        found = (dataset.metadata["task"], dataset.n_objects, dataset.n_trajectories, dataset.n_frames)
        expected = (task, objects, n_trajectories, n_frames)
        if found != expected or dataset.metadata.get("seed") != seed:
            raise EnergyMarginError(
                f"{directory} holds another dataset (task, objects, trajectories, frames = {found}, "
                f"seed {dataset.metadata.get('seed')}); the study asks for {expected}, seed {seed}: "
                "use another output directory"
            )
        return dataset
    return generate_dataset(
        task, n_objects=objects, n_trajectories=n_trajectories, n_frames=n_frames, seed=seed, out=directory
    )
