"""A fitted learned margin and its saved file: :class:`MarginModel` and :func:`load_margin_model`.

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
from energy_margin.compat import save_npz
from energy_margin.data.dataset import Dataset
from energy_margin.errors import EnergyMarginError
from energy_margin.learning.features import FrameFeatures, ObjectSetFeatures
from energy_margin.learning.regressors import KINDS, Regressor, regressor_from_arrays
from energy_margin.runs.files import atomic_path
from energy_margin.runs.npz import NpzError, read_npz
from energy_margin.tasks import Task, get_recorded_task
from energy_margin.world.state import FrameState

__all__ = ["FEATURES_OF_KIND", "FORMAT", "SCHEMA_VERSION", "MarginModel", "load_margin_model"]


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
