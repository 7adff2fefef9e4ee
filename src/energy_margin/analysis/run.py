"""Score every frame of a dataset directory and write ``scores.csv`` beside it.

``analyze`` runs :class:`~energy_margin.analysis.frame.FrameAnalyzer` over the pending frames on an
executor (a local process pool or Ray), with a progress bar and an append-only journal, so an
interrupted run resumes where it stopped. Frame ``i`` (trajectory-major order) uses the seed
``SeedSequence(seed).spawn(n_frames_total)[i].generate_state(1, uint64)[0]``.
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from energy_margin._version import __version__
from energy_margin.analysis.executors import make_executor
from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.data.dataset import Dataset
from energy_margin.data.generate import check_engine
from energy_margin.data.io import atomic_write_text, read_json, write_json
from energy_margin.data.scores_file import (
    CONFIG_FILE,
    JOURNAL_FILE,
    SCORES_FILE,
    format_row,
    header,
    read_journal,
)
from energy_margin.data.validation import require_valid
from energy_margin.errors import EnergyMarginError
from energy_margin.tasks import with_contacts


def run_description(dataset: Dataset, config: AnalyzerConfig, seed: int) -> dict[str, Any]:
    """What ``analysis.json`` records of a run: settings, seed, dataset, task and versions."""
    import mujoco

    description: dict[str, Any] = {
        "analyzer": config.to_dict(),
        "seed": int(seed),
        "dataset": {
            "task": dataset.metadata["task"],
            "seed": dataset.metadata.get("seed"),
            "n_trajectories": dataset.n_trajectories,
            "n_frames": dataset.n_frames,
            "n_objects": dataset.n_objects,
        },
        "task_config": dataset.task.config.to_dict(),
        "likelihood_lambda": config.likelihood_lambda
        if config.likelihood_lambda is not None
        else dataset.task.config.likelihood_lambda,
        "versions": {"energy_margin": __version__, "mujoco": mujoco.__version__, "numpy": np.__version__},
    }
    if config.contacts != "recorded":
        # The settings the physics of the analysis used (the dataset's, with the contact model's).
        description["analysis_task_config"] = with_contacts(dataset.task, config.contacts).config.to_dict()
    if config.engine == "pybullet":
        from importlib.metadata import version

        description["versions"]["pybullet"] = version("pybullet")
    return description


# Analyzer settings added after the first release take their defaults in an analysis.json without
# them (:func:`_comparable`), except these, whose behaviour before is not the new default.
_EARLIER_BEHAVIOUR = {"converge_rule": "window"}


def _comparable(analyzer: dict[str, Any], *, earlier: bool) -> dict[str, Any]:
    """Analyzer settings with every field present, as they decide the scores.

    ``earlier``: the settings of a file that may predate later fields (they take the defaults, or
    the behaviour of :data:`_EARLIER_BEHAVIOUR`). The convergence rule only matters with a
    tolerance: without one it takes the default, so a full-budget run resumes whatever file wrote it.
    """
    defaults = AnalyzerConfig().to_dict()
    filled = {**defaults, **(_EARLIER_BEHAVIOUR if earlier else {}), **analyzer}
    if filled.get("converge") is None:
        filled["converge_rule"] = defaults["converge_rule"]
    return filled


def _same_run(previous: dict[str, Any], current: dict[str, Any]) -> bool:
    previous, current = dict(previous), dict(current)
    if isinstance(previous.get("analyzer"), dict):
        previous["analyzer"] = _comparable(previous["analyzer"], earlier=True)
    if isinstance(current.get("analyzer"), dict):
        current["analyzer"] = _comparable(current["analyzer"], earlier=False)
    keys = ("analyzer", "seed", "dataset", "task_config")
    return all(json.dumps(previous.get(k), sort_keys=True) == json.dumps(current.get(k), sort_keys=True) for k in keys)


def analyze(
    path: Path | str,
    config: AnalyzerConfig | None = None,
    *,
    seed: int = 0,
    workers: int = 1,
    executor: str = "local",
    address: str | None = None,
    overwrite: bool = False,
    progress: bool = True,
) -> Path:
    """Score every frame of the dataset at ``path`` and write ``scores.csv`` beside it.

    The resolved configuration goes to ``analysis.json``. Rows are appended to
    ``scores.journal.csv`` as frames finish; ``scores.csv`` (sorted by trajectory and frame) is
    written atomically at the end. Running again after an interruption skips finished frames.

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
    config = config if config is not None else AnalyzerConfig()
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise EnergyMarginError(f"seed must be a non-negative integer, got {seed!r}")
    runner = make_executor(executor, workers=workers, address=address)
    dataset = require_valid(path, overlaps=True, scores=False)
    check_engine(dataset.task, config.engine)
    try:
        with_contacts(dataset.task, config.contacts)
    except ValueError as error:
        raise EnergyMarginError(str(error)) from None
    directory = Path(path)
    description = run_description(dataset, config, seed)
    scores_path = directory / SCORES_FILE
    done = open_run(directory, description, dataset, overwrite=overwrite)
    if done is None:
        return scores_path
    total = dataset.n_trajectories * dataset.n_frames
    pending = [i for i in range(total) if divmod(i, dataset.n_frames) not in done]
    if done and progress:
        print(f"resuming: {len(done)} of {total} frames already scored", file=sys.stderr, flush=True)

    bar = progress_bar(total, desc="analyze", initial=len(done), enabled=progress)
    try:
        with (directory / JOURNAL_FILE).open("a", encoding="utf-8") as journal:
            for row in runner.run(dataset, config, seed, pending):
                append_row(journal, row)
                done[(row["trajectory"], row["frame"])] = row
                bar.update(1)
    finally:
        bar.close()
    return write_scores(directory, done)


def open_run(
    directory: Path, description: dict[str, Any], dataset: Dataset, *, overwrite: bool
) -> dict[tuple[int, int], dict[str, Any]] | None:
    """Start or resume the run ``description`` in ``directory``: its finished rows, or ``None`` when complete.

    A directory holding another run's scores is refused unless ``overwrite`` (which discards them).
    ``analysis.json`` is written and the journal rewritten without torn or duplicate lines, ready
    for appending.

    Returns:
        Journal rows by (trajectory, frame); ``None`` when ``scores.csv`` of this very run exists.

    """
    config_path, journal_path, scores_path = (directory / name for name in (CONFIG_FILE, JOURNAL_FILE, SCORES_FILE))
    if config_path.exists():
        try:
            previous = read_json(config_path, what="analysis configuration")
        except EnergyMarginError:
            previous = None
        if not isinstance(previous, dict) or not _same_run(previous, description):
            if not overwrite:
                raise EnergyMarginError(
                    f"{directory} holds scores of a different analysis ({config_path.name}); "
                    "pass --overwrite to replace them"
                )
            for stale in (journal_path, scores_path):
                stale.unlink(missing_ok=True)
        elif scores_path.exists():
            return None
    done = {key: row for key, row in read_journal(journal_path).items() if _valid_key(key, dataset)}
    write_json(config_path, description)
    atomic_write_text(journal_path, header() + "".join(format_row(done[k]) + "\n" for k in sorted(done)))
    return done


def append_row(journal: TextIO, row: dict[str, Any]) -> None:
    """Append one scores row to an open journal and make it durable (flushed and synced)."""
    journal.write(format_row(row) + "\n")
    journal.flush()
    os.fsync(journal.fileno())


def write_scores(directory: Path, done: dict[tuple[int, int], dict[str, Any]]) -> Path:
    """Write ``scores.csv`` of ``directory`` atomically from rows by (trajectory, frame), sorted; its path."""
    scores_path = directory / SCORES_FILE
    lines = [format_row(done[key]) + "\n" for key in sorted(done)]
    atomic_write_text(scores_path, header() + "".join(lines))
    return scores_path


def _valid_key(key: tuple[int, int], dataset: Dataset) -> bool:
    return 0 <= key[0] < dataset.n_trajectories and 0 <= key[1] < dataset.n_frames


class _NoBar:
    def update(self, count: int) -> None:
        del count

    def close(self) -> None:
        pass


def progress_bar(total: int, *, desc: str, initial: int = 0, enabled: bool) -> Any:
    """A per-frame tqdm bar on standard error (``update``, ``close``), or one that shows nothing."""
    if not enabled:
        return _NoBar()
    from tqdm import tqdm

    return tqdm(total=total, initial=initial, unit="frame", desc=desc, dynamic_ncols=True)
