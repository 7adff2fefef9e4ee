"""Fuzzing the scene-file reader: mutated documents, garbage text, corrupt models and control files.

Every input to :func:`load_scene` (the scene file's own checks and those against its compiled
model) is either accepted or refused with one :class:`EnergyMarginError` of one line, never
another exception. ``ENERGY_MARGIN_FUZZ_TALLY=FILE`` appends the cases, acceptances and refusals
of this module to ``FILE`` as one JSON line.
"""

from __future__ import annotations

import datetime
import io
import json
import math
import re
import shutil
import tempfile
import tomllib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import example, given
from hypothesis import strategies as st

from energy_margin.errors import EnergyMarginError
from energy_margin.tasks.scene_model import load_scene
from fuzzing import Tally, fuzz, scratch_folder
from tiny_scene import TINY_MODEL, TINY_SCENE

EXAMPLES = Path(__file__).parents[2] / "examples"
TALLY = Tally("scene file")


@pytest.fixture(scope="module", autouse=True)
def _scratch_folder(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    with scratch_folder(tmp_path_factory):
        yield


@pytest.fixture(scope="module", autouse=True)
def _tally() -> Iterator[None]:
    yield
    TALLY.report()


def attempt(path: Path) -> EnergyMarginError | None:
    """Load the scene file at ``path``: ``None`` when accepted, else its one-line EnergyMarginError."""
    TALLY["cases"] += 1
    try:
        load_scene(path)
    except EnergyMarginError as error:
        return TALLY.refused(error)
    TALLY["accepted"] += 1
    return None


# ---------------------------------------------------------------- TOML written back from Python values


def _string(text: str) -> str:
    escaped = []
    for char in text:
        if char in '"\\':
            escaped.append("\\" + char)
        elif ord(char) < 0x20 or ord(char) == 0x7F:
            escaped.append(f"\\u{ord(char):04x}")
        else:
            escaped.append(char)
    return '"' + "".join(escaped) + '"'


def _key(name: str) -> str:
    return name if re.fullmatch(r"[A-Za-z0-9_-]+", name) else _string(name)


def _value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return _string(value)
    if isinstance(value, datetime.date | datetime.time):
        return value.isoformat()
    if isinstance(value, list):
        return "[" + ", ".join(_value(item) for item in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{_key(k)} = {_value(v)}" for k, v in value.items()) + "}"
    raise TypeError(type(value))


def to_toml(document: dict[str, Any]) -> str:
    """TOML text of ``document``: top-level tables as ``[name]`` sections, arrays of tables as ``[[name]]``."""
    lines = [f"{_key(k)} = {_value(v)}" for k, v in document.items() if not isinstance(v, dict)]
    for name, table in document.items():
        if not isinstance(table, dict):
            continue
        lines.append(f"[{_key(name)}]")
        arrays = {}
        for key, value in table.items():
            if isinstance(value, list) and value and all(isinstance(item, dict) for item in value):
                arrays[key] = value
            else:
                lines.append(f"{_key(key)} = {_value(value)}")
        for key, items in arrays.items():
            for item in items:
                lines.append(f"[[{_key(name)}.{_key(key)}]]")
                lines.extend(f"{_key(k)} = {_value(v)}" for k, v in item.items())
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------- the valid base files

PUSHING = EXAMPLES / "pushing"
# A robot model for the control file: the tiny scene with a slider and one motor.
ROBOT_MODEL = TINY_MODEL.replace(
    "  </worldbody>",
    '    <body name="slider" pos="0 0.8 0.03"><joint name="slide" type="slide" axis="1 0 0"/>'
    '<geom type="box" size="0.02 0.02 0.02" mass="0.5"/></body>\n  </worldbody>\n'
    '  <actuator><motor name="push" joint="slide"/></actuator>\n'
    '  <keyframe><key name="start" qpos="0 0 0.03 1 0 0 0 0.06 0 0.03 1 0 0 0 0.1"/></keyframe>',
)
CTRL_SCENE = (
    TINY_SCENE.replace("[[motion.keyframes]]\ntime = 0.0\nmocap.pusher.pos = [0.0, -0.15, 0.03]\n\n", "")
    .replace("[[motion.keyframes]]\ntime = 1.5\nmocap.pusher.pos = [0.0, 0.3, 0.03]\n", "")
    .replace(
        "duration = 1.5\n", 'duration = 1.5\nctrl_file = "ctrl.npz"\nactuators = ["push"]\ninitial_keyframe = "start"\n'
    )
)


class Bases:
    """Valid scene folders written once; ``copy(name)`` gives a private copy to mutate."""

    def __init__(self, root: Path) -> None:
        self.root = root
        self.folders: dict[str, Path] = {}
        tiny = root / "tiny"
        tiny.mkdir()
        (tiny / "model.xml").write_text(TINY_MODEL)
        # The tiny scene with a mocap orientation and a second set kind, so more keys are present.
        scene = TINY_SCENE.replace(
            "mocap.pusher.pos = [0.0, 0.3, 0.03]\n",
            "mocap.pusher.pos = [0.0, 0.3, 0.03]\nmocap.pusher.quat = [1, 0, 0, 0.1]\n",
        ).replace("[capture]\n", "[capture]\nat_least = 1\n")
        (tiny / "scene.toml").write_text(scene)
        self.folders["tiny"] = tiny
        pushing = root / "pushing"
        pushing.mkdir()
        for name in ("pushing.toml", "pushing.xml"):
            shutil.copy(PUSHING / name, pushing / name)
        (pushing / "scene.toml").write_text((pushing / "pushing.toml").read_text().replace("count = 10", "count = 2"))
        (pushing / "pushing.toml").unlink()
        self.folders["pushing"] = pushing
        robot = root / "ctrl"
        robot.mkdir()
        (robot / "model.xml").write_text(ROBOT_MODEL)
        (robot / "scene.toml").write_text(CTRL_SCENE)
        np.savez(robot / "ctrl.npz", time=np.array([0.0, 0.5, 1.0]), ctrl=np.array([[0.0], [0.1], [0.2]]))
        self.folders["ctrl"] = robot
        self.documents = {
            name: tomllib.loads((folder / "scene.toml").read_text()) for name, folder in self.folders.items()
        }

    def copy(self, name: str) -> Path:
        """A private copy of base ``name``'s folder; returns its scene file."""
        target = Path(tempfile.mkdtemp(dir=self.root)) / name
        shutil.copytree(self.folders[name], target)
        return target / "scene.toml"


@pytest.fixture(scope="module")
def bases(tmp_path_factory: pytest.TempPathFactory) -> Bases:
    return Bases(tmp_path_factory.mktemp("scene-fuzz"))


def _discard(scene: Path) -> None:
    shutil.rmtree(scene.parent.parent)


@pytest.mark.parametrize("name", ["tiny", "pushing", "ctrl"])
def test_the_bases_are_valid_and_written_back_unchanged(bases: Bases, name: str) -> None:
    assert attempt(bases.folders[name] / "scene.toml") is None
    document = bases.documents[name]
    assert tomllib.loads(to_toml(document)) == document
    scene = bases.copy(name)
    scene.write_text(to_toml(document))
    assert attempt(scene) is None
    _discard(scene)


# ---------------------------------------------------------------- mutated documents

NAMES = ["box_a", "box_b", "box_*", "pusher", "goal", "ground", "world", "cylinder", "wall", "slide", "push", "start"]
WORDS = ["free", "upright", "linear", "hold", "ranges", "pile", "box", "cylinder", "height", "distance", "speed"]
WORDS += ["contact", "all", "any", "not", "model.xml", "pushing.xml", "ctrl.npz", "scene.toml", "", ".", "/"]
KEYS = ["type", "body", "site", "geom", "center", "half_size", "radius", "half_height", "min", "max", "plane"]
KEYS += ["margin", "of", "region", "at_least", "pos", "quat", "time", "ctrl", "mocap", "x", "y", "z", "yaw", "low"]
KEYS += ["high", "mode", "count", "template", "bodies", "joints", "keyframes", "ctrl_file", "extra", "duration"]

_SCALAR = st.one_of(
    st.booleans(),
    st.integers(-(2**63), 2**63 - 1),
    st.sampled_from([0, 1, 2, 3, -1, 10**6]),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -0.0, 0.5, 1.0, 1e-300, 1e300, -1.0]),
    st.sampled_from(NAMES + WORDS),
    st.text(max_size=12),
    st.dates(),
    st.datetimes(),
    st.times(),
)
_TOML = st.recursive(
    _SCALAR,
    lambda children: (
        st.lists(children, max_size=5)
        | st.dictionaries(st.sampled_from(KEYS) | st.text(min_size=1, max_size=6), children, max_size=4)
    ),
    max_leaves=10,
)
_NUMBERS = st.lists(st.floats(-2.0, 2.0) | st.sampled_from([0.0, -1.0, 1e300, math.nan, math.inf]), max_size=5)


def _paths(value: Any, prefix: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    """Every path to a value inside ``value`` (dict keys and list indices), the root excluded."""
    found = []
    if isinstance(value, dict):
        for key, item in value.items():
            found.append((*prefix, key))
            found.extend(_paths(item, (*prefix, key)))
    elif isinstance(value, list):
        for index, item in enumerate(value):
            found.append((*prefix, index))
            found.extend(_paths(item, (*prefix, index)))
    return found


def _at(document: Any, path: tuple[Any, ...]) -> Any:
    for part in path:
        document = document[part]
    return document


def mutate(document: dict[str, Any], data: st.DataObject) -> dict[str, Any]:
    """``document`` after one to four random edits: values replaced, keys removed or added, kinds swapped."""
    document = json.loads(json.dumps(document))  # a deep copy (the bases hold only JSON types)
    for _ in range(data.draw(st.integers(1, 4), label="edits")):
        paths = _paths(document)
        if not paths:
            break
        path = data.draw(st.sampled_from(paths), label="path")
        parent, last = _at(document, path[:-1]), path[-1]
        current = parent[last]
        edit = data.draw(st.sampled_from(["value", "remove", "add", "kind", "numbers", "name"]), label="edit")
        if edit == "value":
            parent[last] = data.draw(_TOML)
        elif edit == "remove":
            del parent[last]
        elif edit == "add":
            target = current if isinstance(current, dict) else parent if isinstance(parent, dict) else document
            target[data.draw(st.sampled_from(KEYS) | st.text(min_size=1, max_size=6))] = data.draw(_TOML)
        elif edit == "kind":  # a table or list becomes a scalar, a scalar becomes a table or a list
            if isinstance(current, dict | list):
                parent[last] = data.draw(_SCALAR)
            else:
                parent[last] = data.draw(st.sampled_from([{}, [], [current], {"type": current}, {"value": current}]))
        elif edit == "numbers":
            parent[last] = data.draw(_NUMBERS)
        else:
            parent[last] = data.draw(st.sampled_from(NAMES + WORDS))
    return document


@pytest.mark.slow
@fuzz(400)
@given(name=st.sampled_from(["tiny", "pushing", "ctrl"]), data=st.data())
def test_mutated_scene_documents(bases: Bases, name: str, data: st.DataObject) -> None:
    scene = bases.copy(name)
    scene.write_text(to_toml(mutate(bases.documents[name], data)), encoding="utf-8")
    attempt(scene)
    _discard(scene)


@fuzz(150)
@given(
    name=st.sampled_from(["tiny", "pushing", "ctrl"]),
    top=st.sampled_from(["schema_version", "mjcf", "objects", "motion", "randomize", "perturbation", "capture"]),
    value=_TOML,
)
@example(name="tiny", top="schema_version", value=True)
@example(name="tiny", top="schema_version", value=1.0)
@example(name="tiny", top="mjcf", value="model\x00.xml")
@example(name="tiny", top="mjcf", value="")
@example(name="tiny", top="mjcf", value=".")
@example(name="tiny", top="mjcf", value="x" * 5000)
@example(name="pushing", top="objects", value={"template": "world", "count": 1})
@example(name="pushing", top="objects", value={"template": "cylinder", "count": 2**62})
@example(name="tiny", top="capture", value={"region": {"type": ["box"]}})
@example(name="tiny", top="capture", value={"region": {"type": {"a": 1}}})
@example(name="ctrl", top="motion", value={"duration": 1.0, "ctrl_file": "ctrl\x00.npz"})
def test_any_value_of_a_top_level_key(bases: Bases, name: str, top: str, value: Any) -> None:
    document = json.loads(json.dumps(bases.documents[name]))
    document[top] = value
    scene = bases.copy(name)
    scene.write_text(to_toml(document), encoding="utf-8")
    attempt(scene)
    _discard(scene)


# ---------------------------------------------------------------- mutated text and random bytes


@fuzz(200)
@given(name=st.sampled_from(["tiny", "pushing", "ctrl"]), data=st.data())
def test_mutated_scene_text(bases: Bases, name: str, data: st.DataObject) -> None:
    """Lines removed, repeated or swapped, the text cut short, bytes overwritten or inserted."""
    scene = bases.copy(name)
    content = bytearray(scene.read_bytes())
    lines = content.splitlines(keepends=True)
    edit = data.draw(st.sampled_from(["drop", "repeat", "swap", "truncate", "byte", "insert"]), label="edit")
    if edit == "drop":
        del lines[data.draw(st.integers(0, len(lines) - 1))]
        content = bytearray(b"".join(lines))
    elif edit == "repeat":
        index = data.draw(st.integers(0, len(lines) - 1))
        lines.insert(index, lines[index])
        content = bytearray(b"".join(lines))
    elif edit == "swap":
        a, b = data.draw(st.integers(0, len(lines) - 1)), data.draw(st.integers(0, len(lines) - 1))
        lines[a], lines[b] = lines[b], lines[a]
        content = bytearray(b"".join(lines))
    elif edit == "truncate":
        content = content[: data.draw(st.integers(0, len(content) - 1))]
    elif edit == "byte":
        content[data.draw(st.integers(0, len(content) - 1))] = data.draw(st.integers(0, 255))
    else:
        index = data.draw(st.integers(0, len(content)))
        content[index:index] = data.draw(st.binary(min_size=1, max_size=8))
    scene.write_bytes(bytes(content))
    attempt(scene)
    _discard(scene)


@fuzz(100)
@given(content=st.binary(max_size=400) | st.text(max_size=200).map(lambda text: text.encode("utf-8")))
@example(content=b"")
@example(content=b"\xff\xfe\x00\x00")
@example(content=b'schema_version = 1\nmjcf = "model.xml"\n\xc3\x28')  # invalid UTF-8
@example(content="schema_version = 1\n".encode("utf-16"))
@example(content=b"[" * 5000)
@example(content=b"a = " + b"[" * 5000 + b"]" * 5000)
@example(content=b"a = " + b"{b = " * 2000 + b"1" + b"}" * 2000)
def test_random_bytes_as_scene_file(bases: Bases, content: bytes) -> None:
    scene = bases.copy("tiny")
    scene.write_bytes(content)
    assert attempt(scene) is not None
    _discard(scene)


# ---------------------------------------------------------------- referenced files missing or corrupt


def _xml_edits(model: str, data: st.DataObject) -> bytes:
    edit = data.draw(st.sampled_from(["truncate", "attribute", "bytes", "drop"]), label="model edit")
    if edit == "truncate":
        return model.encode()[: data.draw(st.integers(0, len(model) - 1))]
    if edit == "attribute":
        attributes = list(re.finditer(r'="([^"]*)"', model))
        match = data.draw(st.sampled_from(attributes))
        value = data.draw(st.sampled_from(["", "-1", "nan", "inf", "1e400", "0 0", "x", "true", "1 2 3 4 5 6 7"]))
        return (model[: match.start(1)] + value + model[match.end(1) :]).encode()
    if edit == "bytes":
        content = bytearray(model.encode())
        index = data.draw(st.integers(0, len(content) - 1))
        content[index : index + 1] = data.draw(st.binary(min_size=0, max_size=4))
        return bytes(content)
    lines = model.splitlines(keepends=True)
    del lines[data.draw(st.integers(0, len(lines) - 1))]
    return "".join(lines).encode()


@fuzz(150)
@given(name=st.sampled_from(["tiny", "pushing", "ctrl"]), data=st.data())
@example(name="tiny", data=None)
def test_corrupt_or_missing_model_file(bases: Bases, name: str, data: st.DataObject | None) -> None:
    scene = bases.copy(name)
    model = scene.parent / str(bases.documents[name]["mjcf"])
    if data is None:
        model.unlink()
    else:
        kind = data.draw(st.sampled_from(["edit", "edit", "bytes", "missing", "directory", "itself"]), label="kind")
        if kind == "edit":
            model.write_bytes(_xml_edits(model.read_text(), data))
        elif kind == "bytes":
            model.write_bytes(data.draw(st.binary(max_size=300)))
        elif kind == "missing":
            model.unlink()
        elif kind == "directory":
            model.unlink()
            model.mkdir()
        else:
            shutil.copy(scene, model)
    attempt(scene)
    _discard(scene)


def _npz(**arrays: Any) -> bytes:
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    return buffer.getvalue()


_ARRAYS = st.one_of(
    st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=4).map(np.array),
    st.sampled_from(
        [
            np.zeros(0),
            np.float64(1.0),
            np.zeros((3, 1)),
            np.zeros((3, 2)),
            np.array([0.0, 0.0, 1.0]),
            np.array([[0.0], [np.nan], [0.2]]),
            np.array(["a", "b", "c"]),
            np.array([b"a", b"b", b"c"]),
            np.array([1 + 2j, 3j, 0j]),
            np.array([True, False, True]),
            np.zeros(3, dtype=[("a", "<f8")]),
            np.array([None, 1, "x"], dtype=object),
            np.zeros((3, 1), dtype=np.float16),
            np.arange(3, dtype=np.uint64),
        ]
    ),
)


@fuzz(150)
@given(data=st.data())
@example(data=None)
def test_corrupt_or_missing_control_file(bases: Bases, data: st.DataObject | None) -> None:
    scene = bases.copy("ctrl")
    target = scene.parent / "ctrl.npz"
    if data is None:
        target.unlink()
    else:
        original = target.read_bytes()
        kind = data.draw(st.sampled_from(["arrays", "arrays", "bytes", "truncate", "byte", "directory"]), label="kind")
        if kind == "arrays":
            arrays = {"time": np.array([0.0, 0.5, 1.0]), "ctrl": np.array([[0.0], [0.1], [0.2]])}
            for name in data.draw(st.lists(st.sampled_from(["time", "ctrl", "other"]), max_size=2, unique=True)):
                if data.draw(st.booleans()):
                    arrays.pop(name, None)
                else:
                    arrays[name] = data.draw(_ARRAYS)
            target.write_bytes(_npz(**arrays))
        elif kind == "bytes":
            target.write_bytes(data.draw(st.binary(max_size=300)))
        elif kind == "truncate":
            target.write_bytes(original[: data.draw(st.integers(0, len(original) - 1))])
        elif kind == "byte":
            content = bytearray(original)
            content[data.draw(st.integers(0, len(content) - 1))] ^= data.draw(st.integers(1, 255))
            target.write_bytes(bytes(content))
        else:
            target.unlink()
            target.mkdir()
    attempt(scene)
    _discard(scene)
