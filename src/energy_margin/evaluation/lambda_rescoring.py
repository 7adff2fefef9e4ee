"""The likelihood lambda swept by re-scoring, not regrowing: one tree per frame, scored at every lambda.

A tree does not depend on lambda (its growth never reads it unless the adaptive budget
``converge`` is on), so :func:`rescore_lambdas` grows every frame's tree once and scores it with
every lambda of a grid (:class:`LambdaRescorer`). Each lambda gets a directory
(:func:`lambda_directory`) whose ``analysis.json`` and ``scores.csv`` are exactly those ``analyze``
would write at that lambda, each opened with :func:`energy_margin.analysis.run.open_analysis`
(locked, one resume rule), with one journal per lambda, so the sweep resumes too.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.analysis.continuation import continued_success
from energy_margin.analysis.executors import LocalExecutor
from energy_margin.analysis.frame import AnalyzerConfig, FrameAnalyzer, field_membership
from energy_margin.analysis.run import open_analysis, run_description, write_scores
from energy_margin.analysis.scores import gate_capture, region_score
from energy_margin.data.dataset import Dataset
from energy_margin.data.dataset_files import copy_dataset
from energy_margin.data.scores_file import load_scores, scores_journal
from energy_margin.data.validation import require_valid
from energy_margin.errors import EnergyMarginError, InvalidParameterError, check_float
from energy_margin.planning import CostField
from energy_margin.runs import progress_bar
from energy_margin.runs.progress import Progress
from energy_margin.world.state import FrameState

__all__ = [
    "LambdaRescorer",
    "lambda_directory",
    "rescore_lambdas",
    "result_root",
]


class LambdaRescorer(FrameAnalyzer):
    """Grows each frame's tree once and scores it with every lambda of a grid.

    The result of a frame index is ``{"trajectory", "frame", "rows"}``, ``rows`` holding one scores
    row per lambda (in the grid's order), each what :class:`FrameAnalyzer` gives at that lambda.
    """

    def __init__(self, dataset: Dataset, config: AnalyzerConfig, seed: int, *, lambdas: Sequence[float]) -> None:
        # A success continuation draws its nodes by likelihood: it runs again at every lambda (the
        # tree, grown once, without one).
        super().__init__(dataset, dataclasses.replace(config, continuation=0), seed)
        self.continued_config = config
        self.lambdas = tuple(float(lam) for lam in lambdas)

    def __call__(self, index: int) -> dict[str, Any]:
        """Rows of frame ``index`` at every lambda."""
        row, field = self.analyse(index)
        frame = self.dataset.frame(row["trajectory"], row["frame"])
        # Which nodes are in each set does not depend on lambda: tested once, weighted per lambda.
        captured, successful = field_membership(self.task, frame, field)
        captured_now = self.task.is_captured(frame)
        continued = self._continuation(index, frame, field) if self.continued_config.continuation else None
        rows = []
        for lam in self.lambdas:
            tree_capture = region_score(field.costs, captured, lam)
            capture = gate_capture(tree_capture, captured_now, self.config.capture_gate)
            success = continued(lam) if continued is not None else region_score(field.costs, successful, lam)
            rows.append({**row, "capture_score": capture, "success_score": success, "tree_capture_score": tree_capture})
        return {"trajectory": row["trajectory"], "frame": row["frame"], "rows": rows}

    def _continuation(self, index: int, frame: FrameState, field: CostField) -> Callable[[float], float]:
        """Frame ``index``'s success continuation as a function of lambda, drawn as ``analyze`` draws it."""
        dataset, config = self.dataset, self.continued_config
        trajectory, frame_index = divmod(index, dataset.n_frames)
        friction, drive = float(dataset.arrays["friction"][trajectory]), dataset.arrays["drive"][trajectory]
        simulator = self._simulator(friction, drive)
        start_time = float(dataset.arrays["frame_time"][trajectory, frame_index])
        samples = config.continuation or 0
        return lambda lam: continued_success(
            simulator, self.task, frame, field, drive, lam=lam, samples=samples, seed=self.seeds[index],
            start_time=start_time, horizon=config.continuation_horizon, batched_states=config.batch > 1,
            threads=config.threads,
        ).success_score  # fmt: skip


def lambda_directory(root: Path, method: str, budget: int, lam: float) -> Path:
    """Directory of the lambda ``lam`` re-scoring of ``method`` at ``budget`` under ``root``."""
    return root / f"{method}-{budget}-lambda-{lam:.6g}"


def rescore_lambdas(
    directory: Path | str,
    root: Path | str,
    lambdas: Sequence[float],
    *,
    config: AnalyzerConfig,
    seed: int = 0,
    workers: int = 1,
    progress: Progress = True,
    directories: dict[float, Path] | None = None,
) -> dict[float, dict[str, np.ndarray]]:
    """Grow every frame's tree of the dataset ``directory`` once and score it with each of ``lambdas``.

    Each lambda's scores go to :func:`lambda_directory` under ``root`` (a copy of the dataset with
    the ``analysis.json``, journal and ``scores.csv`` that ``analyze`` writes at that lambda); an
    interrupted run resumes, regrowing only frames missing from some lambda's journal.

    Args:
        directory: dataset directory.
        root: where the per-lambda directories go.
        lambdas: inverse temperatures, 1/J, each finite and >= 0, distinct.
        config: analysis settings of the trees (its ``likelihood_lambda`` is ignored); ``converge``
            must be ``None`` (an adaptive budget makes the tree depend on lambda).
        seed: analysis seed.
        workers: local worker processes.
        progress: show a per-frame progress bar.
        directories: output directories of some lambdas instead of :func:`lambda_directory`. The
            task's own lambda is recorded as ``analyze`` with its default lambda records it, so its
            directory can be the run of that very configuration.

    Returns:
        Scores columns by lambda.

    """
    values = [check_float("lambdas", lam, minimum=0.0) for lam in lambdas]
    if not values or len(set(values)) != len(values):
        raise InvalidParameterError("lambdas", f"must be distinct finite values >= 0, got {list(lambdas)!r}")
    config = config.fixed_continuation()  # one success score for every lambda, stated
    if config.converge is not None:
        raise EnergyMarginError("re-scoring lambda needs trees that do not depend on it: converge must be off")
    source, root = Path(directory), Path(root)
    dirs = {lam: lambda_directory(root, config.method, int(config.expansions or 0), lam) for lam in values}
    dirs.update({float(lam): Path(path) for lam, path in (directories or {}).items() if float(lam) in dirs})
    with contextlib.ExitStack() as stack:
        dataset, open_rows = _open_lambda_runs(stack, source, dirs, config, seed)
        if open_rows:
            _rescore_pending(stack, dataset, dirs, open_rows, values, config, seed, workers=workers, progress=progress)
            for lam, done in open_rows.items():
                write_scores(dirs[lam], done)
    return {lam: load_scores(work) for lam, work in dirs.items()}


def _open_lambda_runs(
    stack: contextlib.ExitStack[Any], source: Path, dirs: dict[float, Path], config: AnalyzerConfig, seed: int
) -> tuple[Dataset, dict[float, dict[tuple[int, int], dict[str, Any]]]]:
    """Open every lambda's analysis (locked until ``stack`` closes): the dataset and the unfinished ones' rows."""
    open_rows: dict[float, dict[tuple[int, int], dict[str, Any]]] = {}
    dataset: Dataset | None = None
    for lam, work in dirs.items():
        copy_dataset(source, work)
        dataset = dataset if dataset is not None else require_valid(work, overlaps=True, scores=False)
        own = lam == dataset.task.config.likelihood_lambda
        description = run_description(
            dataset, dataclasses.replace(config, likelihood_lambda=None if own else lam), seed
        )
        run, done = open_analysis(work, description, dataset, overwrite=False)
        stack.enter_context(run)
        if done is not None:
            open_rows[lam] = done
    assert dataset is not None
    return dataset, open_rows


def _rescore_pending(
    stack: contextlib.ExitStack[Any],
    dataset: Dataset,
    dirs: dict[float, Path],
    open_rows: dict[float, dict[tuple[int, int], dict[str, Any]]],
    values: list[float],
    config: AnalyzerConfig,
    seed: int,
    *,
    workers: int,
    progress: Progress,
) -> None:
    """Grow the trees of the frames some lambda still misses; journal each lambda's new rows."""
    n_frames = dataset.n_frames
    total = dataset.n_trajectories * n_frames
    pending = [i for i in range(total) if any(divmod(i, n_frames) not in done for done in open_rows.values())]
    factory = functools.partial(LambdaRescorer, lambdas=values)
    bar = progress_bar(total, desc="lambda", initial=total - len(pending), enabled=progress)
    try:
        journals = {lam: stack.enter_context(scores_journal(dirs[lam])) for lam in open_rows}
        for result in LocalExecutor(workers, analyzer=factory).run(dataset, config, seed, pending):
            key = (result["trajectory"], result["frame"])
            for lam, row in zip(values, result["rows"], strict=True):
                if lam in open_rows and key not in open_rows[lam]:
                    journals[lam].append(row)
                    open_rows[lam][key] = row
            bar.update(1)
    finally:
        bar.close()


def result_root(directory: Path) -> Path:
    """Where the lambda directories of the dataset ``directory`` go: ``<task>/lambda`` beside it."""
    return directory.parent / "lambda"
