"""Score every frame of a dataset directory and write ``scores.csv`` beside it.

``analyze`` runs :class:`~energy_margin.analysis.frame.FrameAnalyzer` over the pending frames on an
executor (a local process pool or Ray), with a progress bar and an append-only journal, so an
interrupted run resumes where it stopped. Frame ``i`` (trajectory-major order) uses the seed
``SeedSequence(seed).spawn(n_frames_total)[i].generate_state(1, uint64)[0]``.
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path
from typing import Any

from energy_margin._renamed import renamed_keys
from energy_margin.analysis.continuation_rule import default_continuation, recorded_choice
from energy_margin.analysis.executors import make_executor
from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.data.dataset import Dataset
from energy_margin.data.generate import check_engine
from energy_margin.data.scores_file import CONFIG_FILE, JOURNAL_FILE, SCORES_FILE, format_row, header, scores_journal
from energy_margin.data.validation import require_valid
from energy_margin.errors import EnergyMarginError, InvalidParameterError, check_seed
from energy_margin.runs import RunDirectory, RunSpec, open_run, progress_bar
from energy_margin.runs.directory import difference, run_versions
from energy_margin.runs.files import atomic_write_text, read_json, write_json
from energy_margin.runs.progress import Progress
from energy_margin.tasks import with_contacts

__all__ = [
    "ANALYSIS_RUN",
    "analyze",
    "analyze_dataset",
    "open_analysis",
    "recorded_analyzer",
    "resolved_continuation",
    "run_description",
    "unchosen_lambda",
    "write_scores",
]


def run_description(dataset: Dataset, config: AnalyzerConfig, seed: int) -> dict[str, Any]:
    """What ``analysis.json`` records of a run: settings, seed, dataset, task and versions.

    ``versions`` is :func:`energy_margin.runs.directory.run_versions` of the analysis's engine:
    the package's version, the engine, MuJoCo's and numpy's (and PyBullet's with that engine).
    """
    description: dict[str, Any] = {
        "analyzer": config.to_dict(),
        "seed": int(seed),
        "dataset": dataset.identity(),
        "task_config": dataset.task.config.to_dict(),
        "likelihood_lambda": config.likelihood_lambda
        if config.likelihood_lambda is not None
        else dataset.task.config.likelihood_lambda,
        "versions": run_versions(config.engine),
    }
    if config.contacts != "recorded":
        # The settings the physics of the analysis used (the dataset's, with the contact model's).
        description["analysis_task_config"] = with_contacts(dataset.task, config.contacts).config.to_dict()
    return description


# Analyzer settings added after the first release take their defaults in an analysis.json without
# them (:func:`_comparable`), except these, whose behaviour before is not the new default.
_EARLIER_BEHAVIOUR = {"converge_rule": "window", "analysis_model": "full", "continuation": 0, "capture_gate": "none"}


def _comparable(analyzer: dict[str, Any], *, earlier: bool) -> dict[str, Any]:
    """Analyzer settings with every field present, as they decide the scores.

    ``earlier``: the settings of a file that may predate later fields (they take the defaults, or
    the behaviour of :data:`_EARLIER_BEHAVIOUR`). The convergence rule only matters with a
    tolerance: without one it takes the default, so a full-budget run resumes whatever file wrote it.
    """
    defaults = AnalyzerConfig().to_dict()
    filled = {**defaults, **(_EARLIER_BEHAVIOUR if earlier else {}), **renamed_keys(analyzer)}
    if filled.get("converge") is None:
        filled["converge_rule"] = defaults["converge_rule"]
    return filled


def recorded_analyzer(analyzer: dict[str, Any]) -> dict[str, Any]:
    """The analyzer settings an ``analysis.json`` record stands for, every field present.

    A field the file predates takes the behaviour of its time (:data:`_EARLIER_BEHAVIOUR`: the
    paper's capture score, the full model, ...) or, for the rest, today's default.
    """
    return _comparable(analyzer, earlier=True)


def _normalize(settings: dict[str, Any], earlier: bool) -> dict[str, Any]:
    if isinstance(settings.get("analyzer"), dict):
        settings["analyzer"] = _comparable(settings["analyzer"], earlier=earlier)
    return settings


#: An analysis of a dataset: ``analysis.json`` beside the dataset's files, then the journal and
#: ``scores.csv``. The analyzer, the seed, the dataset and the task settings decide the scores;
#: the versions recorded beside them do not.
ANALYSIS_RUN = RunSpec(
    contents="scores",
    settings_file=CONFIG_FILE,
    outputs=(JOURNAL_FILE, SCORES_FILE),
    compared=("analyzer", "seed", "dataset", "task_config"),
    shared_directory=True,
    normalize=_normalize,
    kept=("continuation_choice",),
)


def analyze(
    path: Path | str,
    config: AnalyzerConfig | None = None,
    *,
    seed: int = 0,
    workers: int = 1,
    executor: str = "local",
    address: str | None = None,
    overwrite: bool = False,
    progress: Progress = True,
) -> Path:
    """Score every frame of the dataset at ``path`` and write ``scores.csv`` beside it.

    The dataset is loaded and checked (:func:`~energy_margin.data.validation.require_valid`), then
    analysed by :func:`analyze_dataset`. With ``config.continuation`` ``None`` (the default) the
    success continuation is the engine's default (:mod:`~energy_margin.analysis.continuation_rule`:
    16 draws per frame where the engine continues), recorded in ``analysis.json`` with the
    configuration. Rows are appended to ``scores.journal.csv`` as frames finish; ``scores.csv``
    (sorted by trajectory and frame) is written atomically at the end. Running again after an
    interruption skips finished frames.

    Args:
        path: dataset directory.
        config: analysis settings.
        seed: non-negative integer seed of the analysis.
        workers: parallel workers, >= 1 (local processes or Ray actors).
        executor: ``"local"`` (default) or ``"ray"``.
        address: Ray cluster address for ``executor="ray"``; ``None`` starts a local instance.
        overwrite: discard scores of a different configuration instead of refusing.
        progress: show a progress bar on standard error.

    Returns:
        The path of ``scores.csv``.

    """
    check_seed(seed)
    dataset = require_valid(path, overlaps=True, scores=False)
    return analyze_dataset(
        dataset,
        config,
        seed=seed,
        workers=workers,
        executor=executor,
        address=address,
        overwrite=overwrite,
        progress=progress,
    )


def analyze_dataset(
    dataset: Dataset,
    config: AnalyzerConfig | None = None,
    *,
    seed: int = 0,
    workers: int = 1,
    executor: str = "local",
    address: str | None = None,
    overwrite: bool = False,
    progress: Progress = True,
) -> Path:
    """:func:`analyze` of a dataset already loaded and checked from its directory (``dataset.path``).

    Its task is the one the caller resolved (``dataset.task``); see :func:`analyze` for the rest.

    Raises:
        InvalidParameterError: a dataset loaded from no directory.

    """
    if dataset.path is None:
        raise InvalidParameterError("dataset", "was not loaded from a directory; analyze writes scores.csv beside it")
    path = dataset.path
    config = config if config is not None else AnalyzerConfig()
    check_seed(seed)
    runner = make_executor(executor, workers=workers, address=address)
    check_engine(dataset.task, config.engine)
    with_contacts(dataset.task, config.contacts)  # InvalidParameterError naming contacts
    problem = dataset.task.analysis_problem(batch=config.batch)
    if problem is not None:
        raise EnergyMarginError(problem)
    directory = Path(path)
    config = _earlier_continuation(directory, dataset, config, seed)
    description = run_description(dataset, config, seed)
    scores_path = directory / SCORES_FILE
    run, done = open_analysis(directory, description, dataset, overwrite=overwrite)
    with run:
        if done is None:
            return scores_path
        total = dataset.n_trajectories * dataset.n_frames
        if done and progress is True:
            print(f"resuming: {len(done)} of {total} frames already scored", file=sys.stderr, flush=True)
        bar = progress_bar(total, desc="analyze", initial=len(done), enabled=progress)
        try:
            with scores_journal(directory) as journal:
                config = _resolve_continuation(config, directory / CONFIG_FILE)
                pending = [i for i in range(total) if divmod(i, dataset.n_frames) not in done]
                for row in runner.run(dataset, config, seed, pending):
                    journal.append(row)
                    done[(row["trajectory"], row["frame"])] = row
                    bar.update(1)
        finally:
            bar.close()
        return write_scores(directory, done)


def _earlier_continuation(directory: Path, dataset: Dataset, config: AnalyzerConfig, seed: int) -> AnalyzerConfig:
    """``config``, its rule deferring to an analysis in ``directory`` of the same settings with a continuation given.

    An analysis recorded with its continuation given (by name, or by a release before the rule,
    whose files read as 0) is the one the rule resumes or finds finished, not another run to refuse.
    """
    if config.continuation is not None or not (directory / CONFIG_FILE).is_file():
        return config
    try:
        previous = read_json(directory / CONFIG_FILE, what="analysis settings")
    except EnergyMarginError:
        return config  # open_run says why it cannot be read
    analyzer = previous.get("analyzer") if isinstance(previous, dict) else None
    given = _comparable(analyzer, earlier=True).get("continuation") if isinstance(analyzer, dict) else None
    if not isinstance(given, int) or isinstance(given, bool):
        return config
    candidate = dataclasses.replace(config, continuation=given)
    same = difference(ANALYSIS_RUN, previous, run_description(dataset, candidate, seed)) is None
    return candidate if same else config


def _resolve_continuation(config: AnalyzerConfig, record: Path) -> AnalyzerConfig:
    """``config`` with its continuation decided.

    ``continuation=None`` (recorded as ``null`` in ``analysis.json``) takes the decision already in
    ``record`` (a resumed run, an earlier release's pilot rule included), or else the engine's
    default (:func:`~energy_margin.analysis.continuation_rule.default_continuation`), then written
    to ``record`` as ``continuation_choice``.
    """
    if config.continuation is not None:
        return config
    description = read_json(record, what="analysis settings")
    decided = recorded_choice(description)
    if decided is None:
        decided = default_continuation(config.engine)
        write_json(record, {**description, "continuation_choice": {"continuation": decided}})
    return dataclasses.replace(config, continuation=decided)


def resolved_continuation(description: dict[str, Any]) -> int:
    """The continuations drawn per frame by the analysis ``analysis.json`` describes (0: the tree's own).

    Given by name, recorded as decided by default, or (a record of neither) an earlier release's: 0.
    """
    analyzer = description.get("analyzer") or {}
    if analyzer.get("continuation") is not None:
        return int(analyzer["continuation"])
    decided = recorded_choice(description)
    return decided if decided is not None else 0


def unchosen_lambda(dataset: Dataset, config: AnalyzerConfig) -> str | None:
    """Where the analysis's lambda comes from when nobody chose it (the task's ``lambda_origin``), else ``None``.

    A scene file without ``perturbation.lambda`` takes the default or, with ``derive = true``, a
    derived one (:attr:`~energy_margin.tasks.base.Task.lambda_origin`); no rule from the scene or
    its trees holds the calibrated AP on every example (docs/howto/scenes.md), so such an analysis
    is uncalibrated. ``None`` when ``config`` or the dataset's task sets lambda.
    """
    if config.likelihood_lambda is not None or dataset.task.lambda_origin == "set":
        return None
    return dataset.task.lambda_origin


def open_analysis(
    directory: Path, description: dict[str, Any], dataset: Dataset, *, overwrite: bool
) -> tuple[RunDirectory, dict[tuple[int, int], dict[str, Any]] | None]:
    """Start or resume the analysis ``description`` in ``directory``, locked: the run and its finished rows.

    Another analysis's scores are refused unless ``overwrite`` (which discards them), by the rule
    of :func:`energy_margin.runs.open_run`. The journal is rewritten without torn or duplicate
    lines, ready for appending; close the run to release its lock.

    Returns:
        The open run, and the journal rows by (trajectory, frame), ``None`` when ``scores.csv``
        of this very run exists.

    """
    engine = str(description.get("analyzer", {}).get("engine", "mujoco"))
    run = open_run(directory, ANALYSIS_RUN, description, overwrite=overwrite, engine=engine)
    try:
        if run.resumed and (directory / SCORES_FILE).exists():
            return run, None
        journal = scores_journal(directory)
        done = {key: row for key, row in journal.read().items() if _valid_key(key, dataset)}
        journal.rewrite(done)
    except BaseException:
        run.close()
        raise
    return run, done


def write_scores(directory: Path, done: dict[tuple[int, int], dict[str, Any]]) -> Path:
    """Write ``scores.csv`` of ``directory`` atomically from rows by (trajectory, frame), sorted; its path."""
    scores_path = directory / SCORES_FILE
    lines = [format_row(done[key]) + "\n" for key in sorted(done)]
    atomic_write_text(scores_path, header() + "".join(lines))
    return scores_path


def _valid_key(key: tuple[int, int], dataset: Dataset) -> bool:
    return 0 <= key[0] < dataset.n_trajectories and 0 <= key[1] < dataset.n_frames
