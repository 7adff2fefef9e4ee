"""Fuzzing the saved margin-model reader: random bytes, damaged archives, mutated members and headers.

Every file given to :func:`load_margin_model` is either accepted or refused with one
:class:`EnergyMarginError` of one line, never another exception; an accepted model rebuilds its
task and predicts one frame, or refuses that with one line too. ``ENERGY_MARGIN_FUZZ_TALLY=FILE``
appends the cases, acceptances and refusals of this module to ``FILE`` as one JSON line.
"""

from __future__ import annotations

import contextlib
import io
import json
import shutil
import tempfile
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import example, given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from energy_margin import __version__
from energy_margin.data.dataset import load_dataset
from energy_margin.errors import EnergyMarginError
from energy_margin.learning.features import FrameFeatures
from energy_margin.learning.margin_model import MarginModel, load_margin_model
from energy_margin.learning.regressors import N_OUTPUTS, BoostingRegressor, MlpRegressor
from energy_margin.tasks import Task, get_task
from energy_margin.world.state import FrameState
from fuzzing import Tally, damaged, fuzz

TALLY = Tally("margin model")
KINDS = ("mlp", "boosting")


@pytest.fixture(scope="module", autouse=True)
def _tally() -> Iterator[None]:
    yield
    TALLY.report()


def _model(task: Task, kind: str) -> MarginModel:
    """A small hand-made model of ``task`` (no fit needed: the reader is under test, not the fit)."""
    features = FrameFeatures(task)
    width = features.dimension
    rng = np.random.default_rng(0)
    if kind == "mlp":
        regressor: Any = MlpRegressor(
            rng.normal(size=width),
            rng.uniform(0.5, 2.0, size=width),
            [rng.normal(size=(width, 3)), rng.normal(size=(3, N_OUTPUTS))],
            [rng.normal(size=3), rng.normal(size=N_OUTPUTS)],
        )
    else:
        # Two trees per score of three nodes: a split on feature 0 and 1, and two leaves.
        shape = (N_OUTPUTS, 2, 3)
        feature = np.zeros(shape, dtype=np.int64)
        feature[:, 1, 0] = 1
        left = np.broadcast_to(np.arange(3), shape).copy()
        right = left.copy()
        left[:, :, 0], right[:, :, 0] = 1, 2
        value = np.zeros(shape)
        value[:, :, 1], value[:, :, 2] = 0.1, 0.3
        regressor = BoostingRegressor(np.full(N_OUTPUTS, 0.2), feature, np.zeros(shape), left, right, value, 1, width)
    return MarginModel(
        task_name=task.name,
        task_config=task.config.to_dict(),
        feature_set=features.identifier,
        package_version=__version__,
        kind=kind,
        feature_names=features.names,
        regressor=regressor,
        report={"r2": {"capture": 0.5, "success": None}},
    )


class Base:
    """The saved base models (one per kind), their members, and a frame of their task."""

    def __init__(self, root: Path, frame: FrameState) -> None:
        self.root = root
        self.task = get_task("pushing")
        self.frame = frame
        self.files: dict[str, bytes] = {}
        self.members: dict[str, dict[str, np.ndarray]] = {}
        for kind in KINDS:
            path = root / f"{kind}.npz"
            _model(self.task, kind).save(path)
            self.files[kind] = path.read_bytes()
            with np.load(path) as archive:
                self.members[kind] = {name: archive[name] for name in archive.files}

    def header(self, kind: str) -> dict[str, Any]:
        header: dict[str, Any] = json.loads(self.members[kind]["header"].tobytes())
        return header

    def load(self, content: bytes, *, task_name: str | None = None) -> EnergyMarginError | None:
        """``load_margin_model`` of ``content`` (then its task and one prediction): ``None`` or the error."""
        TALLY["cases"] += 1
        folder = Path(tempfile.mkdtemp(dir=self.root))
        path = folder / "model.npz"
        path.write_bytes(content)
        try:
            model = load_margin_model(path, task_name=task_name)
            assert model.task.name == model.task_name
            capture, success = model.predict(self.task, [self.frame])
            assert capture.shape == success.shape == (1,)
        except EnergyMarginError as error:
            return TALLY.refused(error)
        finally:
            shutil.rmtree(folder)
        TALLY["accepted"] += 1
        return None


@pytest.fixture(scope="module")
def base(tiny_dataset_source: Path, tmp_path_factory: pytest.TempPathFactory) -> Base:
    return Base(tmp_path_factory.mktemp("model-fuzz"), load_dataset(tiny_dataset_source).frame(0, 1))


def archive(members: dict[str, Any]) -> bytes:
    """An uncompressed ``.npz`` of ``members`` (Python objects pickled, as ``np.savez`` does)."""
    buffer = io.BytesIO()
    np.savez(buffer, **members)
    return buffer.getvalue()


def header_bytes(header: Any) -> np.ndarray:
    return np.frombuffer(json.dumps(header).encode(), dtype=np.uint8)


@pytest.mark.parametrize("kind", KINDS)
def test_the_base_models_are_accepted(base: Base, kind: str) -> None:
    assert base.load(base.files[kind], task_name="pushing") is None
    assert base.load(archive(base.members[kind])) is None


# ---------------------------------------------------------------- random bytes, truncated and damaged files


@fuzz(100)
@given(content=st.binary(max_size=800))
@example(content=b"")
@example(content=b"PK\x05\x06" + b"\0" * 18)  # an empty zip archive
@example(content=b"\x93NUMPY\x01\x00v\x00{'descr': '|u1', 'fortran_order': False, 'shape': (3,), }   abc")
def test_random_bytes_as_model(base: Base, content: bytes) -> None:
    assert base.load(content) is not None


@pytest.mark.slow
@fuzz(200)
@given(
    kind=st.sampled_from(KINDS),
    stored=st.booleans(),
    edit=st.sampled_from(["truncate", "byte", "block"]),
    position=st.floats(0.0, 1.0, exclude_max=True),
    value=st.integers(0, 255),
)
def test_truncated_or_damaged_model(
    base: Base, kind: str, stored: bool, edit: str, position: float, value: int
) -> None:
    content = archive(base.members[kind]) if stored else base.files[kind]
    base.load(damaged(content, edit, position, value, width=32))


# ---------------------------------------------------------------- mutated members

_DTYPES = st.sampled_from(["<f8", "<f4", "<i8", "<i4", "|u1", "|b1", "<c16", "<U4", "|S4", ">f8", "<m8[s]"])
_ARRAY = st.one_of(
    hnp.arrays(_DTYPES, hnp.array_shapes(min_dims=0, max_dims=3, min_side=0, max_side=5)),
    st.sampled_from(
        [
            np.zeros(0),
            np.float64(np.nan),
            np.float64(np.inf),
            np.int64(2**62),
            np.int64(-1),
            np.array([None, 1], dtype=object),
            np.zeros(2, dtype=[("a", "<f8")]),
            np.full((2, 2, 3), 10**6, dtype=np.int64),
            np.full((2, 2, 3), -1, dtype=np.int64),
            np.full(3, np.nan),
        ]
    ),
)


@np.errstate(all="ignore")
def mutate_members(members: dict[str, np.ndarray], data: st.DataObject) -> dict[str, Any]:
    """``members`` after one to three edits: removed, replaced, added, reshaped, retyped or poisoned."""
    members = {name: value.copy() for name, value in members.items()}
    for _ in range(data.draw(st.integers(1, 3), label="edits")):
        name = data.draw(st.sampled_from([*sorted(members), "regressor.weight_7", "regressor.extra"]), label="member")
        edit = data.draw(st.sampled_from(["remove", "replace", "reshape", "dtype", "special"]), label="edit")
        value = members.get(name, np.zeros(3))
        if edit == "remove":
            members.pop(name, None)
        elif edit == "replace":
            members[name] = data.draw(_ARRAY)
        elif edit == "reshape":
            members[name] = value.reshape(-1) if value.ndim != 1 else value[: data.draw(st.integers(0, value.size))]
        elif edit == "dtype":
            dtype = data.draw(_DTYPES)
            with warnings.catch_warnings(), contextlib.suppress(TypeError, ValueError):  # not convertible: kept
                warnings.simplefilter("ignore")
                members[name] = value.astype(dtype)
        elif value.size and value.dtype.kind in "fi":
            flat = value.reshape(-1)
            if value.dtype.kind == "f":
                special = [np.nan, np.inf, -1, 10**6]
            else:  # the largest values the member's integer type holds (a retyped int8 holds no 10**6)
                largest = int(np.iinfo(value.dtype).max)
                special = [-1, min(10**6, largest), largest]
            flat[data.draw(st.integers(0, flat.size - 1))] = data.draw(st.sampled_from(special))
    return members


@pytest.mark.slow
@fuzz(350)
@given(kind=st.sampled_from(KINDS), data=st.data())
def test_mutated_members(base: Base, kind: str, data: st.DataObject) -> None:
    base.load(archive(mutate_members(base.members[kind], data)))


# ---------------------------------------------------------------- mutated headers

_JSON = st.recursive(
    st.none()
    | st.booleans()
    | st.integers()
    | st.floats()
    | st.text(max_size=8)
    | st.sampled_from(["mlp", "boosting", "pushing", "scooping", "scene", "frame-statistics/1", __version__]),
    lambda children: st.lists(children, max_size=3) | st.dictionaries(st.text(max_size=6), children, max_size=3),
    max_leaves=8,
)
FIELDS = ["format", "schema_version", "package_version", "task", "task_config", "feature_set", "feature_names"]
FIELDS += ["kind", "report"]


def mutate_header(header: dict[str, Any], data: st.DataObject) -> dict[str, Any]:
    """``header`` after one to three edits of its fields and of the task settings."""
    header = json.loads(json.dumps(header))
    for _ in range(data.draw(st.integers(1, 3), label="edits")):
        edit = data.draw(st.sampled_from(["value", "remove", "add", "config", "names", "kind"]), label="edit")
        field = data.draw(st.sampled_from(FIELDS), label="field")
        if edit == "value":
            header[field] = data.draw(_JSON)
        elif edit == "remove":
            header.pop(field, None)
        elif edit == "add":
            header[data.draw(st.text(max_size=8))] = data.draw(_JSON)
        elif edit == "config" and isinstance(header.get("task_config"), dict):
            config = header["task_config"]
            key = data.draw(st.sampled_from([*sorted(config), "unknown"]))
            if data.draw(st.booleans()):
                config.pop(key, None)
            else:
                config[key] = data.draw(_JSON)
        elif edit == "names" and isinstance(header.get("feature_names"), list):
            names = header["feature_names"]
            if names and data.draw(st.booleans()):
                names[data.draw(st.integers(0, len(names) - 1))] = data.draw(_JSON)
            else:
                header["feature_names"] = names[: data.draw(st.integers(0, len(names)))]
        else:
            header["kind"] = "boosting" if header.get("kind") == "mlp" else "mlp"
    return header


@fuzz(250)
@given(kind=st.sampled_from(KINDS), data=st.data(), task_name=st.sampled_from([None, "pushing", "scooping"]))
def test_mutated_header(base: Base, kind: str, data: st.DataObject, task_name: str | None) -> None:
    members = dict(base.members[kind])
    members["header"] = header_bytes(mutate_header(base.header(kind), data))
    base.load(archive(members), task_name=task_name)


@fuzz(100)
@given(
    kind=st.sampled_from(KINDS),
    raw=st.one_of(
        st.binary(max_size=200),
        st.text(max_size=100).map(str.encode),
        _JSON.map(lambda value: json.dumps(value).encode()),
    ),
)
@example(kind="mlp", raw=b"[" * 100_000 + b"]" * 100_000)
@example(kind="mlp", raw=b"\xff\xfe")
@example(kind="mlp", raw=b"1" * 5000)
@example(kind="mlp", raw=b"NaN")
@example(kind="boosting", raw=b'{"format": "energy-margin-margin-model"}')
def test_header_that_is_not_a_header(base: Base, kind: str, raw: bytes) -> None:
    members = dict(base.members[kind])
    members["header"] = np.frombuffer(raw, dtype=np.uint8)
    assert base.load(archive(members)) is not None


@pytest.mark.parametrize(
    "header",
    [
        np.array("{}"),
        np.array([1.5, 2.5]),
        np.zeros((2, 3), dtype=np.uint8),
        np.zeros(2, dtype=[("a", "u1")]),
        np.array([b"{}"]),
    ],
    ids=["str", "floats", "2-d", "structured", "bytes"],
)
def test_header_of_another_type(base: Base, header: np.ndarray) -> None:
    members = dict(base.members["mlp"])
    members["header"] = header
    error = base.load(archive(members))
    assert error is not None and "header" in str(error)


def test_boosting_depth_beyond_its_trees(base: Base) -> None:
    # A depth larger than any tree of its node arrays would loop over nothing for a long time.
    members = dict(base.members["boosting"])
    members["regressor.depth"] = np.array(10**12)
    error = base.load(archive(members))
    assert error is not None and "depth must be in [0, 2]" in str(error)
    members["regressor.left"] = members["regressor.left"].astype(float)
    error = base.load(archive(members))
    assert error is not None and "left must hold integers" in str(error)
