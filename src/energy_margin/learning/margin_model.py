"""A learned margin: a small regressor from frame features to the analysed capture and success scores.

:func:`fit_margin_model` fits one (an MLP or gradient-boosted trees, scikit-learn) to the scores of
analysed datasets of one task, holding out whole trajectories, and reports how close it comes on
them: R² of both scores, and the Average Precision of the learned scores against the labels beside
that of the tree's scores on the same frames. :class:`MarginModel` predicts both scores of many
frames in one vectorised call; :meth:`MarginModel.score_state` is the learned path of live scoring
(:mod:`energy_margin.analysis.live`).

A saved model is one ``.npz`` archive read with ``allow_pickle=False``: the regressor's parameters
as arrays and a JSON header (format, schema version, package version, task name and configuration,
feature definition and names, regressor kind, the fit's report). Loading checks the header before
any array is used, and refuses a model of another task, another package version or another
feature definition with one line.
"""

from __future__ import annotations

import json
import time
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin._version import __version__
from energy_margin.analysis.live import LiveScore
from energy_margin.analysis.scores import trajectory_success_score
from energy_margin.compat import save_npz
from energy_margin.data.dataset import Dataset
from energy_margin.data.scores_file import load_scores
from energy_margin.errors import EnergyMarginError, check_choice, check_float, check_positive_int
from energy_margin.evaluation.metrics import average_precision, score_grid
from energy_margin.learning.features import FrameFeatures, ObjectSetFeatures, SetInputs
from energy_margin.learning.regressors import KINDS, Regressor, fit_regressor, regressor_from_arrays
from energy_margin.runs.files import atomic_path
from energy_margin.runs.npz import NpzError, read_npz
from energy_margin.tasks import Task, get_recorded_task
from energy_margin.world.state import FrameState

#: ``format`` of a saved model's header.
FORMAT = "energy-margin-margin-model"
#: Version of the saved layout.
SCHEMA_VERSION = 2
#: The feature definition of each regressor kind (:data:`KINDS`).
FEATURES_OF_KIND: dict[str, type[FrameFeatures]] = {
    "mlp": FrameFeatures,
    "boosting": FrameFeatures,
    "set": ObjectSetFeatures,
}
_HEADER = "header"
_PREFIX = "regressor."


@dataclass
class MarginModel:
    """A fitted learned margin of one task.

    Attributes:
        task_name: the task it was fitted on, e.g. ``"pushing"``.
        task_config: that task's resolved configuration (as in ``dataset.json``).
        feature_set: the feature definition, ``name/version`` (e.g. ``"frame-statistics/1"``).
        package_version: the energy-margin version that fitted it.
        kind: regressor kind, ``"mlp"``, ``"boosting"`` or ``"set"``.
        feature_names: name of every feature column, shape (D,).
        regressor: the fitted parameters and their prediction.
        report: what :func:`fit_margin_model` measured (JSON-compatible).
        n_objects_range: the fewest and the most objects of any training frame; frames outside
            this range are refused by :meth:`check_dataset`.

    """

    task_name: str
    task_config: dict[str, Any]
    feature_set: str
    package_version: str
    kind: str
    feature_names: tuple[str, ...]
    regressor: Regressor
    report: dict[str, Any] = field(default_factory=dict)
    n_objects_range: tuple[int, int] = (1, 1_000_000)
    _features: dict[int, tuple[Task, FrameFeatures]] = field(default_factory=dict, init=False, repr=False)

    @property
    def task(self) -> Task:
        """The task it was fitted on, with its configuration."""
        return get_recorded_task(self.task_name, self.task_config)

    def features(self, task: Task) -> FrameFeatures:
        """The feature definition bound to ``task`` (built once per task object).

        Raises:
            EnergyMarginError: ``task`` is another task than the model's, or its features differ.
        """
        cached = self._features.get(id(task))
        if cached is not None and cached[0] is task:
            return cached[1]
        if task.name != self.task_name:
            raise EnergyMarginError(f"this margin model was fitted on task {self.task_name!r}, not {task.name!r}")
        features = FEATURES_OF_KIND[self.kind](task)
        if features.identifier != self.feature_set or features.names != self.feature_names:
            raise EnergyMarginError(
                f"this margin model uses features {self.feature_set!r} of {len(self.feature_names)} columns; "
                f"{task.label} gives {features.identifier!r} of {features.dimension}"
            )
        if len(self._features) >= 8:
            self._features.clear()
        self._features[id(task)] = (task, features)
        return features

    def predict(self, task: Task, frames: Sequence[FrameState]) -> tuple[np.ndarray, np.ndarray]:
        """Learned capture and success scores of ``frames``, each shape (F,), in [0, 1].

        One call computes the features of every frame and runs the regressor once on all of
        them; frames may hold any number of objects.

        Raises:
            EnergyMarginError: ``task`` is not the model's task.
            InvalidParameterError: no frames, or a frame whose end-effector size is not the task's.
        """
        raw = self.regressor.predict(self.features(task)(frames))
        scores = np.clip(raw, 0.0, 1.0)
        return scores[:, 0].copy(), scores[:, 1].copy()

    def score_state(self, task: Task, state: FrameState) -> LiveScore:
        """The learned path of live scoring: both scores of one state, with the seconds it took.

        The counterpart of :func:`energy_margin.analysis.live.score_state` (which grows a tree);
        the result has ``expansions`` 0 and ``stopped_by`` ``"learned"``.
        """
        started = time.perf_counter()
        capture, success = self.predict(task, [state])
        return LiveScore(
            capture=float(capture[0]),
            success=float(success[0]),
            expansions=0,
            nodes=0,
            seconds=time.perf_counter() - started,
            stopped_by="learned",
        )

    def check_dataset(self, dataset: Dataset) -> None:
        """Refuse, in one line, a dataset this model cannot score.

        Raises:
            EnergyMarginError: the dataset is of another task, holds a number of objects outside
                the model's training range, or (a scene file's task) was made with another
                compiled model than the model's training data.
        """
        name = dataset.metadata["task"]
        where = f"the margin model (task {self.task_name!r}) cannot score {dataset.path or 'this dataset'}"
        if name != self.task_name:
            raise EnergyMarginError(f"{where}: it is a dataset of task {name!r}")
        fewest, most = self.n_objects_range
        if not fewest <= dataset.n_objects <= most:
            raise EnergyMarginError(
                f"{where}: it holds {dataset.n_objects} objects and the model was fitted on "
                f"{fewest if fewest == most else f'{fewest} to {most}'}"
            )
        fitted_on = str(self.task_config.get("model_sha256") or "")
        scored = str(dataset.task.config.to_dict().get("model_sha256") or "")
        if fitted_on and scored and fitted_on != scored:
            raise EnergyMarginError(
                f"{where}: it was made with another compiled model (sha256 {scored[:12]}…, the model's "
                f"training data {fitted_on[:12]}…)"
            )

    def header(self) -> dict[str, Any]:
        """The JSON header of the saved file."""
        return {
            "format": FORMAT,
            "schema_version": SCHEMA_VERSION,
            "package_version": self.package_version,
            "task": self.task_name,
            "task_config": self.task_config,
            "feature_set": self.feature_set,
            "feature_names": list(self.feature_names),
            "kind": self.kind,
            "n_objects": list(self.n_objects_range),
            "report": self.report,
        }

    def save(self, path: Path | str) -> None:
        """Write the model to ``path`` (an ``.npz`` archive, whatever its name), atomically."""
        path = Path(path)
        if path.is_dir():
            raise EnergyMarginError(f"{path} is a directory; give a model file name, e.g. model.npz")
        path.parent.mkdir(parents=True, exist_ok=True)
        header = np.frombuffer(json.dumps(self.header(), sort_keys=True).encode("utf-8"), dtype=np.uint8)
        arrays = {f"{_PREFIX}{name}": value for name, value in self.regressor.arrays().items()}
        with atomic_path(path) as temporary, temporary.open("wb") as stream:
            save_npz(stream, {_HEADER: header, **arrays}, compressed=True)


def load_margin_model(path: Path | str, *, task_name: str | None = None) -> MarginModel:
    """Read a model saved by :meth:`MarginModel.save`.

    Args:
        path: the model file.
        task_name: the task the caller scores; a model of another task is refused.

    Raises:
        EnergyMarginError: a missing, corrupt or foreign file, a model of another task, of another
            package version or of another feature definition (one line each).
    """
    path = Path(path)
    try:
        if not path.is_file():
            raise EnergyMarginError(f"margin model {path} {'is not a file' if path.exists() else 'does not exist'}")
    except OSError as error:
        raise EnergyMarginError(f"margin model {path} cannot be read ({error.strerror})") from None
    try:
        contents = read_npz(path)
    except NpzError as error:
        raise EnergyMarginError(f"margin model {path}: not a margin model file ({error})") from None
    if _HEADER not in contents:
        raise EnergyMarginError(f"margin model {path}: not a margin model file (no header)")
    raw = contents[_HEADER]
    if raw.dtype != np.uint8 or raw.ndim != 1:
        raise EnergyMarginError(
            f"margin model {path}: the header is not a 1-d array of bytes ({raw.dtype} {raw.shape})"
        )
    try:
        header = json.loads(raw.tobytes().decode("utf-8"))
    except (ValueError, RecursionError):
        raise EnergyMarginError(f"margin model {path}: the header is not valid JSON") from None
    _check_header(path, header, task_name)
    arrays = {name[len(_PREFIX) :]: value for name, value in contents.items() if name.startswith(_PREFIX)}
    bad = next((name for name, value in arrays.items() if value.dtype.kind not in "biuf"), None)
    if bad is not None:
        raise EnergyMarginError(
            f"margin model {path}: corrupt parameters ({bad} holds {arrays[bad].dtype}, not numbers)"
        )
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)  # int() of a 1-element array
            regressor = regressor_from_arrays(header["kind"], arrays)
    except (ValueError, TypeError, OverflowError) as error:
        raise EnergyMarginError(
            f"margin model {path}: corrupt {header['kind']} parameters ({_one_line(error)})"
        ) from None
    width = len(header["feature_names"])
    if regressor.n_features != width:
        raise EnergyMarginError(f"margin model {path}: corrupt parameters (they do not fit {width} features)")
    return MarginModel(
        task_name=header["task"],
        task_config=header["task_config"],
        feature_set=header["feature_set"],
        package_version=header["package_version"],
        kind=header["kind"],
        feature_names=tuple(header["feature_names"]),
        regressor=regressor,
        report=header.get("report", {}),
        n_objects_range=(int(header["n_objects"][0]), int(header["n_objects"][1])),
    )


def _check_header(path: Path, header: Any, task_name: str | None) -> None:
    """Refuse a header of another format, version, task or feature definition."""
    where = f"margin model {path}"
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        raise EnergyMarginError(f"{where}: not a margin model file")
    if header.get("schema_version") != SCHEMA_VERSION:
        raise EnergyMarginError(
            f"{where}: schema version {header.get('schema_version')!r} is not supported (this version reads "
            f"{SCHEMA_VERSION})"
        )
    if header.get("package_version") != __version__:
        raise EnergyMarginError(
            f"{where} was fitted by energy-margin {header.get('package_version')!r}, this is {__version__}: "
            "fit it again with `energy-margin learn`"
        )
    required = {"task": str, "task_config": dict, "feature_set": str, "feature_names": list, "kind": str}
    for key, kind in required.items():
        if not isinstance(header.get(key), kind):
            raise EnergyMarginError(f"{where}: header field {key!r} is missing or not a {kind.__name__}")
    objects = header.get("n_objects")
    if (
        not isinstance(objects, list)
        or len(objects) != 2
        or not all(isinstance(value, int) and not isinstance(value, bool) and value >= 1 for value in objects)
        or objects[0] > objects[1]
    ):
        raise EnergyMarginError(f"{where}: header field 'n_objects' is not a [fewest, most] pair of counts >= 1")
    if "report" in header and not isinstance(header["report"], dict):
        raise EnergyMarginError(f"{where}: header field 'report' is not a dict")
    if not all(isinstance(name, str) for name in header["feature_names"]):
        raise EnergyMarginError(f"{where}: header field 'feature_names' holds a value that is not a str")
    if task_name is not None and header["task"] != task_name:
        raise EnergyMarginError(f"{where} is a model of task {header['task']!r}, not {task_name!r}")
    if header["kind"] not in KINDS:
        raise EnergyMarginError(f"{where}: unknown regressor kind {header['kind']!r} (known: {', '.join(KINDS)})")
    definition = FEATURES_OF_KIND[header["kind"]]
    if header["feature_set"] != f"{definition.name}/{definition.version}":
        raise EnergyMarginError(
            f"{where} uses features {header['feature_set']!r}; this version computes "
            f"{definition.name}/{definition.version} for a {header['kind']} model"
        )


def _one_line(error: BaseException) -> str:
    return " ".join(str(error).split()) or type(error).__name__


@dataclass(frozen=True)
class _Frames:
    """The frames of one analysed dataset with their features and scores, trajectory-major."""

    dataset: Dataset
    features: np.ndarray | SetInputs  # (T * K, D), or the set inputs of the T * K frames
    capture: np.ndarray  # (T, K) tree capture scores
    success: np.ndarray  # (T, K) tree success scores
    runtime: np.ndarray  # (T, K) tree seconds per frame


def check_same_task(datasets: Sequence[Dataset]) -> None:
    """Refuse no datasets, or datasets of different tasks or task settings (one line).

    Raises:
        EnergyMarginError: as above.
    """
    if not datasets:
        raise EnergyMarginError("give at least one analysed dataset")
    first = datasets[0]
    for other in datasets[1:]:
        if other.metadata["task"] != first.metadata["task"]:
            raise EnergyMarginError(
                f"datasets {first.path} and {other.path} are of different tasks "
                f"({first.metadata['task']!r} and {other.metadata['task']!r}): a margin model is fitted on one task"
            )
        if other.task.config.to_dict() != first.task.config.to_dict():
            a, b = first.task.config.to_dict(), other.task.config.to_dict()
            key = next(k for k in a if a[k] != b.get(k))
            raise EnergyMarginError(
                f"datasets {first.path} and {other.path} were generated with different {first.metadata['task']} "
                f"settings ({key}: {a[key]!r} and {b.get(key)!r})"
            )


def training_frames(datasets: Sequence[Dataset], *, kind: str = "mlp") -> list[_Frames]:
    """Features and scores of every frame of analysed ``datasets`` (one task, one configuration).

    ``kind`` chooses the feature definition (:data:`FEATURES_OF_KIND`).

    Raises:
        EnergyMarginError: no datasets, datasets of different tasks or settings, or one without
            ``scores.csv``.
    """
    check_same_task(datasets)
    first = datasets[0]
    task = first.task
    features = FEATURES_OF_KIND[kind](task)
    frames = []
    for dataset in datasets:
        if dataset.path is None:
            raise EnergyMarginError("a dataset read from disk is needed (its scores.csv sits beside it)")
        scores = load_scores(dataset.path)
        states = [
            dataset.frame(trajectory, index)
            for trajectory in range(dataset.n_trajectories)
            for index in range(dataset.n_frames)
        ]
        frames.append(
            _Frames(
                dataset=dataset,
                features=features(states),
                capture=score_grid(dataset, scores, "capture_score"),
                success=score_grid(dataset, scores, "success_score"),
                runtime=score_grid(dataset, scores, "runtime_s"),
            )
        )
    return frames


def fit_margin_model(
    datasets: Sequence[Dataset],
    *,
    seed: int,
    kind: str = "mlp",
    holdout: float = 0.25,
    success_frames: int = 3,
    **options: Any,
) -> tuple[MarginModel, dict[str, Any]]:
    """Fit a learned margin to analysed datasets of one task and measure it on held-out trajectories.

    Args:
        datasets: analysed datasets (``load_dataset``; each with ``scores.csv`` beside it), one
            task and one task configuration; their numbers of objects may differ.
        seed: seed of the split and of the regressor.
        kind: ``"mlp"`` (a ReLU perceptron), ``"boosting"`` (gradient-boosted trees) or ``"set"``
            (the network over the objects, :mod:`energy_margin.learning.set_network`; needs PyTorch).
        holdout: fraction of the trajectories (whole trajectories, never single frames) held out
            for the report, in (0, 1); at least one trajectory is held out and one kept.
        success_frames: k-bar of the trajectory success AP (as in ``evaluate``), >= 1.
        options: regressor settings (:func:`energy_margin.learning.regressors.fit_regressor`).

    Returns:
        The model (fitted on the kept trajectories) and its report: ``r2`` of ``capture`` and
        ``success`` on the held-out frames; ``ap``: ``capture`` (per frame, labels at k-hat 0),
        ``capture_window2`` (labels at k-hat 2: the objects stay captured two more frames),
        ``success`` (per trajectory, from the last ``success_frames`` frames) and
        ``success_first_half`` (from the first half of the frames only), each ``learned`` beside
        ``tree`` (the analysed scores of the same frames), as ``evaluate`` asks them;
        ``n_trajectories`` and ``n_frames`` (``train``, ``held_out``); ``seconds_per_query`` (one batched predict over
        the held-out frames, per frame, wall time), ``seconds_single_query`` (one frame per call),
        ``cpu_seconds_per_query`` and ``cpu_seconds_single_query`` (the same in CPU time),
        ``tree_seconds_per_frame`` (the analysis' mean wall time of the held-out frames, from
        ``scores.csv``), ``speedup`` and ``speedup_single_query`` (tree over learned wall time);
        ``fit_seconds``.

    Raises:
        EnergyMarginError: datasets of different tasks, without scores, or too few trajectories.
        InvalidParameterError: a bad ``kind``, ``holdout`` or ``success_frames``.
    """
    check_choice("kind", kind, KINDS)
    check_float("holdout", holdout, minimum=0.0, maximum=1.0, exclusive_minimum=True, exclusive_maximum=True)
    check_positive_int("success_frames", success_frames)
    frames = training_frames(datasets, kind=kind)
    groups = [(d, t) for d, item in enumerate(frames) for t in range(item.dataset.n_trajectories)]
    if len(groups) < 2:
        raise EnergyMarginError("a margin model needs at least 2 trajectories (one is held out)")
    order = np.random.default_rng(seed).permutation(len(groups))
    n_held = min(len(groups) - 1, max(1, round(holdout * len(groups))))
    held = {groups[i] for i in order[:n_held]}

    def select(is_held: bool) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray]:
        rows: list[Any] = []
        targets: list[np.ndarray] = []
        trajectory: list[np.ndarray] = []
        labels: list[np.ndarray] = []
        for d, item in enumerate(frames):
            dataset, k = item.dataset, item.dataset.n_frames
            future, success = dataset.capture_labels(min(2, k - 1)), dataset.success_labels()
            for t in range(dataset.n_trajectories):
                if ((d, t) in held) == is_held:
                    rows.append(_take(item.features, slice(t * k, (t + 1) * k)))
                    targets.append(np.stack([item.capture[t], item.success[t]], axis=1))
                    trajectory.append(np.full(k, len(trajectory)))
                    labels.append(np.column_stack([future[t], np.full(k, success[t])]).astype(float))
        return _concatenate(rows), np.concatenate(targets), np.concatenate(trajectory), np.concatenate(labels)

    train_x, train_y, train_groups, train_labels = select(False)
    test_x, test_y, _, _ = select(True)
    started = time.perf_counter()
    if kind == "set":
        # The labels the scores answer (the objects stay captured two more frames; the trajectory
        # succeeds) as auxiliary targets: on held-out pushing trajectories they raised future
        # capture AP by about 0.015 (docs/control.md).
        options = {"groups": train_groups, "auxiliary": train_labels, **options}
    regressor = fit_regressor(kind, train_x, train_y, seed=seed, **options)
    fit_seconds = time.perf_counter() - started
    task = frames[0].dataset.task
    definition = FEATURES_OF_KIND[kind](task)
    model = MarginModel(
        task_name=task.name,
        task_config=task.config.to_dict(),
        feature_set=definition.identifier,
        package_version=__version__,
        kind=kind,
        feature_names=definition.names,
        regressor=regressor,
        n_objects_range=(
            min(item.dataset.n_objects for item in frames),
            max(item.dataset.n_objects for item in frames),
        ),
    )
    report = _held_out_report(model, frames, held, test_x, test_y, success_frames=success_frames)
    report.update(
        {
            "task": task.name,
            "kind": kind,
            "seed": seed,
            "holdout": float(holdout),
            "feature_set": definition.identifier,
            "n_features": definition.dimension,
            "n_trajectories": {"train": len(groups) - n_held, "held_out": n_held},
            "n_frames": {"train": len(train_x), "held_out": len(test_x)},
            "fit_seconds": fit_seconds,
            "fit": {key: value for key, value in getattr(regressor, "fit_info", {}).items() if key != "fit_seconds"},
            "datasets": [str(item.dataset.path) for item in frames],
        }
    )
    model.report = report
    return model, report


def _take(features: np.ndarray | SetInputs, rows: slice) -> np.ndarray | SetInputs:
    """The rows ``rows`` of features (F, D) or of set inputs."""
    return features.take(rows) if isinstance(features, SetInputs) else features[rows]


def _concatenate(parts: list[Any]) -> Any:
    """Features of many frames in order: one array (F, D), or set inputs padded to one width."""
    return SetInputs.concatenate(parts) if isinstance(parts[0], SetInputs) else np.concatenate(parts)


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


def load_training_datasets(paths: Sequence[Path | str]) -> list[Dataset]:
    """Load analysed datasets of one task for :func:`fit_margin_model`.

    Raises:
        EnergyMarginError: a dataset with a problem (its ``scores.csv`` included), datasets of
            different tasks, or one without ``scores.csv`` (one line).
    """
    from energy_margin.data.validation import require_valid

    if not paths:
        raise EnergyMarginError("give at least one analysed dataset")
    datasets = [require_valid(path, overlaps=False, scores=None) for path in paths]
    check_same_task(datasets)
    for path in paths:
        require_valid(path, overlaps=False, scores=True)
    return datasets
