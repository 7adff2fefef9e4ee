"""Where frames are analysed: this process, a local process pool (the default) or a Ray cluster.

Every executor runs the same :class:`~energy_margin.analysis.frame.FrameAnalyzer` on frame indices and
streams back one scores row per frame, in completion order. A frame's result depends only on its
index, the dataset, the configuration and the seed, so every executor and every number of workers
gives identical scores.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import signal
import sys
import threading
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, as_completed, wait
from typing import Any, Protocol, TypeVar

from energy_margin.analysis.frame import AnalyzerConfig, FrameAnalyzer
from energy_margin.data.dataset import Dataset
from energy_margin.errors import EnergyMarginError, InvalidParameterError, check_positive_int

__all__ = [
    "EXECUTORS",
    "AnalyzerFactory",
    "Executor",
    "LocalExecutor",
    "RayExecutor",
    "make_executor",
    "pool_results",
    "sigint_deferred",
    "stop_pool",
]

EXECUTORS = ("local", "ray")


class Executor(Protocol):
    """Runs frame analyses and streams their rows back."""

    name: str
    workers: int

    def run(
        self, dataset: Dataset, config: AnalyzerConfig, seed: int, indices: Sequence[int]
    ) -> Iterator[dict[str, Any]]:
        """Analyse the frames ``indices`` (trajectory-major) and yield their rows as they finish."""
        ...


def make_executor(kind: str = "local", *, workers: int = 1, address: str | None = None) -> Executor:
    """The executor ``kind`` (``"local"`` or ``"ray"``) with ``workers`` workers.

    Args:
        kind: ``"local"`` (this process when ``workers`` is 1, else a process pool) or ``"ray"``.
        workers: parallel workers, >= 1 (Ray: actors).
        address: Ray cluster address (``"auto"`` or ``"host:port"``); ``None`` starts a local
            Ray instance. Only for ``"ray"``.
    """
    check_positive_int("workers", workers)
    if kind == "local":
        if address is not None:
            raise InvalidParameterError("address", "is only for `executor=ray`")
        return LocalExecutor(workers)
    if kind == "ray":
        return RayExecutor(workers, address)
    raise EnergyMarginError(f"unknown executor {kind!r}; choose one of {', '.join(EXECUTORS)}")


def _chunks(indices: Sequence[int], workers: int) -> list[list[int]]:
    # Small chunks keep the load balanced and the journal fresh; a few frames per task amortise the
    # per-task cost (about 0.1 ms locally, 0.7 ms with Ray).
    size = max(1, min(8, len(indices) // (4 * workers)))
    return [list(indices[i : i + size]) for i in range(0, len(indices), size)]


# --- local -------------------------------------------------------------------------------------

_WORKER: Any = None


def _die_with_parent() -> None:
    """Ask Linux to kill this worker when its parent dies (e.g. by SIGKILL), so none is orphaned."""
    if not sys.platform.startswith("linux"):
        return
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)
    except (OSError, AttributeError):
        return
    # The parent may have died between the fork and the prctl call.
    if os.getppid() == 1:
        os._exit(1)


_PR_SET_PDEATHSIG = 1


#: Builds a frame analyser from (dataset, config, seed): a callable from a frame index to its result.
AnalyzerFactory = Callable[[Dataset, AnalyzerConfig, int], Callable[[int], dict[str, Any]]]


def _init_local_worker(
    dataset: Dataset, config: dict[str, Any], seed: int, factory: AnalyzerFactory = FrameAnalyzer
) -> None:

    # Ctrl-C goes to the parent, which stops the pool; workers must not die half-way on their own.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _die_with_parent()
    global _WORKER
    _WORKER = factory(dataset, AnalyzerConfig(**config), seed)


def _rows(analyzer: Callable[[int], dict[str, Any]], indices: Sequence[int]) -> Iterator[dict[str, Any]]:
    """The analyser's rows of ``indices``: through its ``rows`` when it has one (frames grown together)."""
    rows = getattr(analyzer, "rows", None)
    if rows is not None:
        yield from rows(indices)
    else:
        for index in indices:
            yield analyzer(index)


def _run_local_chunk(indices: list[int]) -> list[dict[str, Any]]:
    assert _WORKER is not None
    return list(_rows(_WORKER, indices))


@contextlib.contextmanager
def sigint_deferred() -> Iterator[None]:
    """Hold a Ctrl-C that arrives inside the block and raise it as ``KeyboardInterrupt`` after it.

    Starting a process pool forks; CPython prints and swallows an exception raised in its
    at-fork callbacks, so an interrupt landing there would be lost. Main thread only.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    received: list[int] = []
    previous = signal.signal(signal.SIGINT, lambda number, frame: received.append(number))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
    if received and previous is signal.default_int_handler:
        raise KeyboardInterrupt


@contextlib.contextmanager
def _sigint_ignored() -> Iterator[None]:
    """Ignore SIGINT inside the block (main thread only; elsewhere a no-op)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def stop_pool(pool: ProcessPoolExecutor, *, finished: bool) -> None:
    """Shut a process pool down: drain it when ``finished``, else stop its workers at once.

    Interrupted (Ctrl-C, an error, or the consumer stopped), the workers are terminated rather
    than drained. A second SIGINT (`timeout -s INT` signals the process and then its group) must
    not cut this short, or the workers outlive the pool and exit waits for them. The pool's manager
    thread is joined here (the workers are gone, so this is quick): left running, it races the
    interpreter's exit handler over its wake-up pipe ("Exception ignored in: <module 'threading'>
    ... Bad file descriptor").
    """
    if finished:
        pool.shutdown(wait=True)
        return
    with _sigint_ignored():
        processes = list(getattr(pool, "_processes", {}).values())
        for process in processes:
            process.terminate()
        for process in processes:
            process.join()
        # A worker stopped half-way through sending its result leaves a partial message in the
        # result pipe, and the pool's manager thread would wait for the rest of it forever. With
        # every worker gone, closing this process's end of the pipe (the last writer) turns that
        # wait into end-of-file, which the manager reads as a broken pool and shuts down.
        writer = getattr(getattr(pool, "_result_queue", None), "_writer", None)
        if writer is not None:
            writer.close()
        pool.shutdown(wait=True, cancel_futures=True)


_Result = TypeVar("_Result")


def pool_results(
    worker: Callable[[Any], _Result],
    jobs: Sequence[Any],
    *,
    workers: int,
    initializer: Callable[..., None],
    initargs: tuple[Any, ...],
) -> Iterator[_Result]:
    """``worker(job)`` of every job on a pool of up to ``workers`` processes, in completion order.

    Each process starts with ``initializer(*initargs)``. Submitting forks the workers: an
    interrupt meanwhile is held until they exist, and the pool is stopped on the way out.
    """
    pool = ProcessPoolExecutor(max_workers=min(workers, len(jobs)), initializer=initializer, initargs=initargs)
    finished = False
    try:
        with sigint_deferred():
            futures = [pool.submit(worker, job) for job in jobs]
        for future in as_completed(futures):
            yield future.result()
        finished = True
    finally:
        stop_pool(pool, finished=finished)


class LocalExecutor:
    """This process (one worker) or a ``ProcessPoolExecutor`` (several).

    Args:
        workers: worker processes (1: this process).
        analyzer: what runs on each frame index: :class:`FrameAnalyzer` (a scores row) by default,
            or another picklable factory of the same signature whose results are yielded as they are.

    """

    name = "local"

    def __init__(self, workers: int = 1, *, analyzer: AnalyzerFactory = FrameAnalyzer) -> None:
        self.workers = workers
        self.analyzer = analyzer

    def run(
        self, dataset: Dataset, config: AnalyzerConfig, seed: int, indices: Sequence[int]
    ) -> Iterator[dict[str, Any]]:
        """Analyse ``indices`` and yield rows in completion order."""
        if not indices:
            return
        if self.workers == 1:
            yield from _rows(self.analyzer(dataset, config, seed), indices)
            return
        pool = ProcessPoolExecutor(
            max_workers=self.workers,
            initializer=_init_local_worker,
            initargs=(dataset, config.to_dict(), seed, self.analyzer),
        )
        pending: set[Future[list[dict[str, Any]]]] = set()
        chunks = iter(_chunks(indices, self.workers))
        finished = False
        try:
            # Keep two chunks in flight per worker so none idles while results are written. The
            # first submissions fork the workers: an interrupt meanwhile is held until they exist.
            with sigint_deferred():
                for first in chunks:
                    pending.add(pool.submit(_run_local_chunk, first))
                    if len(pending) >= 2 * self.workers:
                        break
            while pending:
                done, pending = wait(pending, return_when=FIRST_COMPLETED)
                for future in done:
                    yield from future.result()
                    following = next(chunks, None)
                    if following is not None:
                        pending.add(pool.submit(_run_local_chunk, following))
            finished = True
        finally:
            stop_pool(pool, finished=finished)


# --- Ray ---------------------------------------------------------------------------------------


class _RayFrameAnalyzer:
    """Ray actor body: one FrameAnalyzer per worker, fed chunks of frame indices."""

    def __init__(self, dataset: Dataset, config: dict[str, Any], seed: int) -> None:

        self._analyzer = FrameAnalyzer(dataset, AnalyzerConfig(**config), seed)

    def run(self, indices: list[int]) -> list[dict[str, Any]]:
        return [self._analyzer(index) for index in indices]


# A chunk is tried on at most this many workers before the run fails.
_RAY_ATTEMPTS = 3


def _ray_lost_worker_errors(ray: Any) -> tuple[type[BaseException], ...]:
    """Ray's exceptions for an actor whose worker process or node is gone."""
    exceptions = ray.exceptions
    names = ("RayActorError", "ActorDiedError", "ActorUnavailableError", "WorkerCrashedError", "NodeDiedError")
    return tuple(getattr(exceptions, name) for name in names if hasattr(exceptions, name))


def _least_loaded(actors: list[Any], in_flight: dict[Any, tuple[Any, list[int], int]]) -> Any:
    """The actor with the fewest chunks in flight (the first of them on a tie)."""
    load = {id(actor): 0 for actor in actors}
    for actor, _, _ in in_flight.values():
        if id(actor) in load:
            load[id(actor)] += 1
    return min(actors, key=lambda actor: load[id(actor)])


def _import_ray() -> Any:
    # Ray would otherwise try to report usage statistics over the network.
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    try:
        import ray
    except ImportError:
        raise EnergyMarginError("the Ray executor needs Ray: pip install 'energy-margin[ray]'") from None
    return ray


class RayExecutor:
    """Ray actors, on a local Ray instance or an existing cluster (``address``)."""

    name = "ray"

    def __init__(self, workers: int = 2, address: str | None = None) -> None:
        self.workers = workers
        self.address = address

    def run(
        self, dataset: Dataset, config: AnalyzerConfig, seed: int, indices: Sequence[int]
    ) -> Iterator[dict[str, Any]]:
        """Analyse ``indices`` on Ray actors and yield rows in completion order."""
        if not indices:
            return
        ray = _import_ray()
        started_here = not ray.is_initialized()
        if started_here:
            options: dict[str, Any] = {
                "include_dashboard": False,
                "log_to_driver": False,
                "configure_logging": False,
            }
            if self.address is None:
                options["num_cpus"] = self.workers
            else:
                options["address"] = self.address
            try:
                ray.init(**options)
            except (ConnectionError, RuntimeError, ValueError) as error:
                raise EnergyMarginError(f"cannot start or reach Ray ({error})") from None
        actor_class = ray.remote(num_cpus=1)(_RayFrameAnalyzer)
        lost = _ray_lost_worker_errors(ray)
        actors: list[Any] = []
        try:
            # The dataset travels through the object store, so cluster nodes need no shared disk.
            dataset_ref = ray.put(dataset)

            def new_actor() -> Any:
                actor = actor_class.remote(dataset_ref, config.to_dict(), seed)
                actors.append(actor)
                return actor

            chunks = iter(_chunks(indices, self.workers))
            # reference -> (actor, chunk, attempt): a chunk's rows are yielded only when the whole
            # chunk came back, so a worker lost mid-chunk loses nothing and duplicates nothing.
            in_flight: dict[Any, tuple[Any, list[int], int]] = {}
            alive: list[Any] = []
            for _ in range(self.workers):
                actor = new_actor()
                alive.append(actor)
                for _ in range(2):
                    chunk = next(chunks, None)
                    if chunk is not None:
                        in_flight[actor.run.remote(chunk)] = (actor, chunk, 1)
            while in_flight:
                ready, _ = ray.wait(list(in_flight), num_returns=1)
                for reference in ready:
                    actor, chunk, attempt = in_flight.pop(reference)
                    try:
                        rows = ray.get(reference)
                    except lost as error:
                        # Its node left the cluster (or the worker died): run the chunk again on a
                        # surviving actor (a new one would wait for the CPU the survivors hold),
                        # or on a new actor, which Ray places on a node still there, if none is left.
                        if attempt >= _RAY_ATTEMPTS:
                            raise EnergyMarginError(
                                f"frames {chunk[0]}..{chunk[-1]} failed on {attempt} Ray workers ({error})"
                            ) from None
                        if actor in alive:
                            alive.remove(actor)
                        if not alive:
                            alive.append(new_actor())
                        target = _least_loaded(alive, in_flight)
                        in_flight[target.run.remote(chunk)] = (target, chunk, attempt + 1)
                        continue
                    yield from rows
                    following = next(chunks, None)
                    if following is not None:
                        target = actor if actor in alive else _least_loaded(alive, in_flight)
                        in_flight[target.run.remote(following)] = (target, following, 1)
        finally:
            for actor in actors:
                with contextlib.suppress(Exception):
                    ray.kill(actor)
            if started_here:
                ray.shutdown()
