"""Executors: validation, identical scores for every executor and worker count, clean Ray errors."""

from __future__ import annotations

import builtins
import multiprocessing
import os
import shutil
import sys
import threading
import time
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from energy_margin.analysis import executors
from energy_margin.analysis.executors import EXECUTORS, LocalExecutor, RayExecutor, make_executor
from energy_margin.analysis.frame import AnalyzerConfig, FrameAnalyzer
from energy_margin.analysis.run import analyze
from energy_margin.cli import main
from energy_margin.data.dataset import load_dataset
from energy_margin.data.scores_file import COLUMNS, CONFIG_FILE, JOURNAL_FILE, SCORES_FILE, load_scores, read_journal
from energy_margin.errors import EnergyMarginError

SMALL = AnalyzerConfig(expansions=30)
SEED = 3
#: Every column that does not depend on timing.
DETERMINISTIC = tuple(c for c in COLUMNS if c not in ("runtime_s", "physics_s"))


def _deterministic(row: dict[str, Any]) -> dict[str, Any]:
    return {name: row[name] for name in DETERMINISTIC}


def _table(directory: Path) -> dict[tuple[int, int], dict[str, Any]]:
    """Deterministic columns of scores.csv keyed by (trajectory, frame); every key exactly once."""
    scores = load_scores(directory)
    keys = list(zip(scores["trajectory"].tolist(), scores["frame"].tolist(), strict=True))
    assert len(keys) == len(set(keys)), "duplicated rows"
    return {key: {name: scores[name][i].item() for name in DETERMINISTIC} for i, key in enumerate(keys)}


@pytest.fixture(scope="module")
def local_one_reference(tmp_path_factory: pytest.TempPathFactory, tiny_dataset_source: Path) -> Path:
    """The tiny dataset analysed in this process (one worker): the reference of every executor."""
    target = tmp_path_factory.mktemp("executors") / "local-1"
    shutil.copytree(tiny_dataset_source, target)
    analyze(target, SMALL, seed=SEED, workers=1, progress=False)
    return target


# ---------------------------------------------------------------- make_executor


@pytest.mark.parametrize(
    ("kind", "kwargs", "message"),
    [
        ("dask", {}, r"unknown executor 'dask'; choose one of local, ray"),
        ("", {}, "unknown executor ''"),
        ("LOCAL", {}, "unknown executor 'LOCAL'"),
        ("local", {"workers": 0}, r"workers must be a positive integer, got 0"),
        ("local", {"workers": -2}, r"workers must be a positive integer, got -2"),
        ("local", {"workers": True}, r"workers must be a positive integer, got True"),
        ("local", {"workers": False}, r"workers must be a positive integer, got False"),
        ("local", {"workers": 2.0}, r"workers must be a positive integer, got 2.0"),
        ("local", {"workers": "2"}, r"workers must be a positive integer, got '2'"),
        ("ray", {"workers": 0}, r"workers must be a positive integer, got 0"),
        ("local", {"address": "auto"}, r"^address is only for `executor=ray`$"),
        ("local", {"address": ""}, r"^address is only for `executor=ray`$"),
    ],
)
def test_make_executor_rejects_bad_arguments(kind: str, kwargs: dict[str, Any], message: str) -> None:
    with pytest.raises(EnergyMarginError, match=message):
        make_executor(kind, **kwargs)


def test_make_executor_builds_each_kind_without_importing_ray(monkeypatch: pytest.MonkeyPatch) -> None:
    # Building a Ray executor must not need Ray: only running it does.
    monkeypatch.setitem(sys.modules, "ray", None)
    local = make_executor()
    assert isinstance(local, LocalExecutor)
    assert (local.name, local.workers) == ("local", 1)
    pool = make_executor("local", workers=3)
    assert isinstance(pool, LocalExecutor)
    assert pool.workers == 3
    ray = make_executor("ray", workers=2, address="auto")
    assert isinstance(ray, RayExecutor)
    assert (ray.name, ray.workers, ray.address) == ("ray", 2, "auto")
    assert make_executor("ray", workers=2).address is None
    assert EXECUTORS == ("local", "ray")


def test_bad_executor_arguments_write_nothing(tiny_dataset: Path, capsys: pytest.CaptureFixture[str]) -> None:
    before = sorted(p.name for p in tiny_dataset.iterdir())
    with pytest.raises(EnergyMarginError, match="unknown executor"):
        analyze(tiny_dataset, SMALL, executor="spark", progress=False)
    with pytest.raises(EnergyMarginError, match=r"^address is only for `executor=ray`$"):
        analyze(tiny_dataset, SMALL, address="auto", progress=False)
    code = main(["analyze", str(tiny_dataset), "--expansions", "5", "--address", "auto", "--no-progress"])
    err = capsys.readouterr().err
    assert code == 2
    assert err.splitlines() == ["energy-margin: error: --address is only for --executor ray"]
    assert sorted(p.name for p in tiny_dataset.iterdir()) == before


# ---------------------------------------------------------------- chunks


@settings(max_examples=100, deadline=None)
@given(
    indices=st.lists(st.integers(0, 10_000), max_size=300, unique=True),
    workers=st.integers(1, 16),
)
def test_chunks_cover_every_index_once_in_order(indices: list[int], workers: int) -> None:
    chunks = executors._chunks(indices, workers)
    assert [i for chunk in chunks for i in chunk] == indices
    assert all(1 <= len(chunk) <= 8 for chunk in chunks)


# ---------------------------------------------------------------- local executor


@pytest.mark.parametrize("workers", [1, 2])
def test_local_executor_returns_each_requested_index_once(tiny_dataset: Path, workers: int) -> None:
    dataset = load_dataset(tiny_dataset)
    reference = FrameAnalyzer(dataset, SMALL, SEED)
    requested = [5, 0, 3, 1]  # a subset, out of order, not contiguous
    rows = list(LocalExecutor(workers).run(dataset, SMALL, SEED, requested))
    got = [_index(row, dataset.n_frames) for row in rows]
    assert sorted(got) == sorted(requested)
    assert len(got) == len(set(got))
    for row in rows:
        index = _index(row, dataset.n_frames)
        assert _deterministic(row) == _deterministic(reference(index))
        assert row["runtime_s"] >= 0
        assert row["physics_s"] >= 0
        assert set(row) == set(COLUMNS)


def _index(row: dict[str, Any], n_frames: int) -> int:
    return int(row["trajectory"]) * n_frames + int(row["frame"])


@pytest.mark.parametrize("workers", [1, 2])
def test_local_executor_with_no_indices_starts_nothing(
    tiny_dataset: Path, workers: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    def no_pool(*args: object, **kwargs: object) -> None:
        raise AssertionError("a pool was started for no frames")

    monkeypatch.setattr(executors, "ProcessPoolExecutor", no_pool)
    assert list(LocalExecutor(workers).run(load_dataset(tiny_dataset), SMALL, SEED, [])) == []


def _children_gone(timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if not multiprocessing.active_children():
            return True
        time.sleep(0.05)
    return not multiprocessing.active_children()


def test_stopping_early_terminates_the_pool(tiny_dataset: Path) -> None:
    dataset = load_dataset(tiny_dataset)
    assert not multiprocessing.active_children()
    stream = LocalExecutor(2).run(dataset, AnalyzerConfig(expansions=200), SEED, list(range(6)))
    first = next(stream)
    assert set(first) == set(COLUMNS)
    assert multiprocessing.active_children()  # the pool is still working on the other frames
    stream.close()  # the consumer stops: the pool must not be drained
    assert _children_gone(10.0), multiprocessing.active_children()


def _large_result(size: int) -> bytes:
    return b"x" * size


def _stop_while_results_stream(size: int) -> bool:
    """Stop a pool whose workers are sending ``size``-byte results; True when it stopped within 10 s."""
    pool = ProcessPoolExecutor(2)
    pending = {pool.submit(_large_result, size) for _ in range(4)}
    for _ in range(20):
        done, pending = wait(pending, return_when=FIRST_COMPLETED)
        pending |= {pool.submit(_large_result, size) for _ in done}
    stopper = threading.Thread(target=executors.stop_pool, args=(pool,), kwargs={"finished": False}, daemon=True)
    stopper.start()
    stopper.join(10.0)
    return not stopper.is_alive()


def test_stopping_a_pool_mid_result_does_not_hang() -> None:
    # A worker terminated while writing a 200 kB result leaves half a message in the pipe; the
    # pool's manager thread used to wait for the rest forever (three hangs in three tries).
    for attempt in range(8):
        assert _stop_while_results_stream(200_000), f"stop_pool hung on attempt {attempt}"
    assert _children_gone(10.0), multiprocessing.active_children()


def test_local_one_and_two_workers_give_identical_scores(
    local_one_reference: Path, copy_dataset: Callable[[str], Path]
) -> None:
    two = copy_dataset("local-2")
    analyze(two, SMALL, seed=SEED, workers=2, progress=False)
    reference = _table(local_one_reference)
    assert _table(two) == reference
    assert sorted(reference) == [(t, k) for t in range(2) for k in range(3)]
    assert not multiprocessing.active_children()


# ---------------------------------------------------------------- Ray


@pytest.mark.slow
def test_ray_gives_the_scores_of_the_local_executor(
    local_one_reference: Path, copy_dataset: Callable[[str], Path]
) -> None:
    pytest.importorskip("ray")
    import ray

    assert not ray.is_initialized()
    directory = copy_dataset("ray-2")
    # Resume from a journal holding frames 0 and 2, so the actors get a non-contiguous subset
    # (1, 3, 4, 5) and every requested row must come back exactly once.
    shutil.copy(local_one_reference / CONFIG_FILE, directory / CONFIG_FILE)
    lines = (local_one_reference / JOURNAL_FILE).read_text().splitlines(keepends=True)
    kept = [line for line in lines[1:] if line.split(",")[:2] in (["0", "0"], ["0", "2"])]
    assert len(kept) == 2
    (directory / JOURNAL_FILE).write_text(lines[0] + "".join(kept))

    analyze(directory, SMALL, seed=SEED, workers=2, executor="ray", progress=False)

    assert not ray.is_initialized()  # the instance it started is shut down again
    assert _table(directory) == _table(local_one_reference)
    assert read_journal(directory / JOURNAL_FILE).keys() == {(t, k) for t in range(2) for k in range(3)}
    journal_lines = (directory / JOURNAL_FILE).read_text().splitlines()
    assert len(journal_lines) == 1 + 6  # header + one line per frame, none computed twice
    rows = (directory / SCORES_FILE).read_text().splitlines(keepends=True)
    assert [r for r in rows if r in kept] == kept  # kept rows untouched, runtime included


@pytest.mark.parametrize("how", ["sys.modules", "__import__"])
def test_missing_ray_is_a_clean_error(tiny_dataset: Path, monkeypatch: pytest.MonkeyPatch, how: str) -> None:
    if how == "sys.modules":
        monkeypatch.setitem(sys.modules, "ray", None)
    else:
        real_import = builtins.__import__

        def fake_import(name: str, *args: Any, **kwargs: Any) -> Any:
            if name == "ray" or name.startswith("ray."):
                raise ModuleNotFoundError("No module named 'ray'", name="ray")
            return real_import(name, *args, **kwargs)

        monkeypatch.delitem(sys.modules, "ray", raising=False)
        monkeypatch.setattr(builtins, "__import__", fake_import)
    dataset = load_dataset(tiny_dataset)
    with pytest.raises(EnergyMarginError, match=r"the Ray executor needs Ray: pip install 'energy-margin\[ray\]'"):
        list(RayExecutor(2).run(dataset, SMALL, SEED, [0, 1]))
    with pytest.raises(EnergyMarginError, match="needs Ray") as info:
        analyze(tiny_dataset, SMALL, seed=SEED, workers=2, executor="ray", progress=False)
    assert info.value.__cause__ is None  # `from None`: no chained ImportError in the message
    assert not (tiny_dataset / SCORES_FILE).exists()


def test_missing_ray_on_the_command_line(
    tiny_dataset: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)
    code = main(["analyze", str(tiny_dataset), "--expansions", "5", "--executor", "ray", "--no-progress"])
    captured = capsys.readouterr()
    assert code == 2
    assert captured.err.splitlines() == [
        "energy-margin: error: the Ray executor needs Ray: pip install 'energy-margin[ray]'"
    ]
    assert "Traceback" not in captured.err
    assert not (tiny_dataset / SCORES_FILE).exists()
    # The same analysis then completes locally (the executor is not part of the configuration).
    monkeypatch.delitem(sys.modules, "ray")
    assert main(["analyze", str(tiny_dataset), "--expansions", "5", "--no-progress"]) == 0
    assert len(load_scores(tiny_dataset)["frame"]) == 6


def test_ray_executor_with_no_indices_needs_no_ray(tiny_dataset: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)
    assert list(RayExecutor(2).run(load_dataset(tiny_dataset), SMALL, SEED, [])) == []


def test_import_ray_disables_usage_statistics_unless_set(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)
    environment: dict[str, str] = {}
    monkeypatch.setattr(os, "environ", environment)
    with pytest.raises(EnergyMarginError):
        executors._import_ray()
    assert environment == {"RAY_USAGE_STATS_ENABLED": "0"}
    environment["RAY_USAGE_STATS_ENABLED"] = "1"
    with pytest.raises(EnergyMarginError):
        executors._import_ray()
    assert environment == {"RAY_USAGE_STATS_ENABLED": "1"}  # an explicit choice is kept
