"""Fuzzing the roll-out readers of ``record``: mutated, truncated and garbage ``.npz`` and HDF5 files.

Every file given to :func:`read_rollout_file` (and, for a share of them, to the whole
:func:`record_dataset`) is either accepted or refused with one :class:`EnergyMarginError` of one
line, never another exception. ``ENERGY_MARGIN_FUZZ_TALLY=FILE`` appends the cases, acceptances
and refusals of this module to ``FILE`` as one JSON line.
"""

from __future__ import annotations

import contextlib
import io
import shutil
import tempfile
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pytest
from hypothesis import example, given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from energy_margin.data.record import read_rollout_file, record_dataset
from energy_margin.errors import EnergyMarginError
from energy_margin.tasks.scene_model import load_scene
from fuzzing import Tally, damaged, fuzz, scratch_folder
from tiny_scene import write_tiny_scene

h5py = pytest.importorskip("h5py")

TALLY = Tally("recording")
ROWS = 6
NAMES = ("time", "qpos", "qvel", "ctrl", "mocap_pos", "mocap_quat")


@pytest.fixture(scope="module", autouse=True)
def _scratch_folder(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    with scratch_folder(tmp_path_factory):
        yield


@pytest.fixture(scope="module", autouse=True)
def _tally() -> Iterator[None]:
    yield
    TALLY.report()


class Base:
    """The tiny scene, its compiled model and a valid roll-out of ``ROWS`` rows, made once."""

    def __init__(self, root: Path) -> None:
        self.root = root
        self.scene = write_tiny_scene(root / "scene")
        self.model = load_scene(self.scene).model
        model, data = self.model, mujoco.MjData(self.model)
        log: dict[str, list[np.ndarray]] = {name: [] for name in NAMES}
        for _ in range(ROWS):
            data.mocap_pos[0] = [0.0, -0.15 + 0.3 * data.time, 0.03]
            log["time"].append(np.array(data.time))
            for name in NAMES[1:]:
                log[name].append(getattr(data, name).copy())
            mujoco.mj_step(model, data)
        self.arrays = {name: np.stack(values) for name, values in log.items()}

    def path(self, suffix: str) -> Path:
        """A fresh file name in a private folder."""
        return Path(tempfile.mkdtemp(dir=self.root)) / f"rollout{suffix}"

    def read(self, path: Path) -> EnergyMarginError | None:
        """``read_rollout_file`` on ``path``: ``None`` when accepted, else its one-line error."""
        TALLY["cases"] += 1
        try:
            rollouts = read_rollout_file(path, self.model)
        except EnergyMarginError as error:
            return TALLY.refused(error)
        finally:
            shutil.rmtree(path.parent)
        assert rollouts and all(value.dtype == float for _, arrays in rollouts for value in arrays.values())
        TALLY["accepted"] += 1
        return None

    def record(self, path: Path, frames: int) -> EnergyMarginError | None:
        """The whole ``record_dataset`` on ``path``: ``None`` when accepted, else its one-line error."""
        TALLY["cases"] += 1
        out = path.parent / "dataset"
        try:
            record_dataset(self.scene, [path], n_frames=frames, out=out)
        except EnergyMarginError as error:
            assert not out.exists()
            return TALLY.refused(error)
        finally:
            shutil.rmtree(path.parent)
        TALLY["accepted"] += 1
        return None


@pytest.fixture(scope="module")
def base(tmp_path_factory: pytest.TempPathFactory) -> Base:
    return Base(tmp_path_factory.mktemp("record-fuzz"))


def write_npz(path: Path, arrays: dict[str, Any], *, compressed: bool = False) -> Path:
    (np.savez_compressed if compressed else np.savez)(path, **arrays)
    return path


def write_hdf5(path: Path, groups: dict[str, dict[str, Any]]) -> Path:
    with h5py.File(path, "w") as handle:
        for name, arrays in groups.items():
            group = handle.create_group(name)
            for key, value in arrays.items():
                _put(group, key, value)
    return path


def _put(group: Any, key: str, value: np.ndarray) -> None:
    """``group[key] = value``, a type HDF5 does not store (unicode, dates) as bytes, Python objects left out."""
    if value.dtype == object:
        return
    try:
        group[key] = value
    except TypeError:
        group[key] = value.astype("S")


def test_the_base_rollout_is_accepted(base: Base) -> None:
    assert base.read(write_npz(base.path(".npz"), base.arrays)) is None
    assert base.read(write_hdf5(base.path(".h5"), {"run0": base.arrays, "run1": base.arrays})) is None
    assert base.record(write_npz(base.path(".npz"), base.arrays), 3) is None


# ---------------------------------------------------------------- mutated arrays

_DTYPES = st.sampled_from(["<f8", "<f4", "<f2", ">f8", "<i8", "|u1", "|b1", "<c16", "<U3", "|S3", "<M8[s]"])
_RANDOM_ARRAY = st.one_of(
    hnp.arrays(_DTYPES, hnp.array_shapes(min_dims=0, max_dims=3, min_side=0, max_side=7)),
    st.sampled_from(
        [
            np.zeros(0),
            np.zeros((0, 14)),
            np.float64(0.0),
            np.zeros((ROWS, 14, 1)),
            np.zeros(ROWS, dtype=[("a", "<f8"), ("b", "<i4")]),
            np.array([None, 1, "x"], dtype=object),
            np.full((ROWS, 14), np.nan),
            np.full((ROWS, 12), 1e308),
        ]
    ),
)
_SPECIAL = st.sampled_from([np.nan, np.inf, -np.inf, 1e308, -1e308, 0.0, 1e-320, 2.0**63])


@np.errstate(all="ignore")
def mutate(arrays: dict[str, np.ndarray], data: st.DataObject) -> dict[str, np.ndarray]:
    """``arrays`` after one to three edits: removed, replaced, reshaped, retyped, poisoned, cut short."""
    arrays = {name: value.copy() for name, value in arrays.items()}
    for _ in range(data.draw(st.integers(1, 3), label="edits")):
        names = sorted(arrays) or ["time"]
        name = data.draw(st.sampled_from([*names, "extra"]), label="array")
        edit = data.draw(
            st.sampled_from(["remove", "random", "reshape", "dtype", "special", "rows", "order", "transpose"]),
            label="edit",
        )
        value = arrays.get(name, np.zeros(ROWS))
        if edit == "remove":
            arrays.pop(name, None)
        elif edit == "random":
            arrays[name] = data.draw(_RANDOM_ARRAY)
        elif edit == "reshape" and value.ndim:
            axis = data.draw(st.integers(0, value.ndim - 1))
            if data.draw(st.booleans()) or value.shape[axis] == 0:
                arrays[name] = np.take(value, range(max(0, value.shape[axis] - 1)), axis=axis)
            else:
                arrays[name] = np.concatenate([value, np.take(value, [0], axis=axis)], axis=axis)
        elif edit == "dtype":
            dtype = data.draw(_DTYPES)
            with warnings.catch_warnings(), contextlib.suppress(TypeError, ValueError):  # not convertible: kept
                warnings.simplefilter("ignore")
                arrays[name] = value.astype(dtype)
        elif edit == "special" and value.size and value.dtype.kind == "f":
            flat = value.reshape(-1)
            flat[data.draw(st.integers(0, flat.size - 1))] = data.draw(_SPECIAL)
        elif edit == "rows":  # every array cut to the same number of rows
            keep = data.draw(st.integers(0, ROWS - 1))
            arrays = {key: item[:keep] if item.ndim else item for key, item in arrays.items()}
        elif edit == "order" and value.ndim:
            arrays[name] = value[data.draw(st.permutations(range(value.shape[0])))]
        elif edit == "transpose":
            arrays[name] = value.T.copy()
    return arrays


@pytest.mark.slow
@fuzz(300)
@given(data=st.data(), compressed=st.booleans())
def test_mutated_npz_rollouts(base: Base, data: st.DataObject, compressed: bool) -> None:
    base.read(write_npz(base.path(".npz"), mutate(base.arrays, data), compressed=compressed))


@fuzz(200)
@given(data=st.data(), groups=st.integers(1, 3))
def test_mutated_hdf5_rollouts(base: Base, data: st.DataObject, groups: int) -> None:
    runs = {f"run{index}": dict(base.arrays) for index in range(groups)}
    runs[f"run{data.draw(st.integers(0, groups - 1))}"] = mutate(base.arrays, data)
    base.read(write_hdf5(base.path(data.draw(st.sampled_from([".h5", ".hdf5", ".H5"]))), runs))


def _hdf5_layout(handle: Any, arrays: dict[str, np.ndarray], layout: str) -> None:
    """Write one HDF5 layout, valid or not."""
    group = handle.create_group("run0")
    for key, value in arrays.items():
        _put(group, key, value)
    if layout == "dataset at the top":
        handle["time"] = np.zeros(ROWS)
    elif layout == "nested group":
        group.create_group("inner")["qpos"] = np.zeros((ROWS, 14))
    elif layout == "attributes":
        group.attrs["qpos"] = np.zeros(3)
        handle.attrs["format"] = "something else"
    elif layout == "dangling soft link":
        group.pop("qvel", None)
        group["qvel"] = h5py.SoftLink("/nowhere")
    elif layout == "dangling group link":
        handle["run1"] = h5py.SoftLink("/missing")
    elif layout == "external link":
        group.pop("qpos", None)
        group["qpos"] = h5py.ExternalLink("missing.h5", "/qpos")
    elif layout == "hard link":
        handle["run1"] = group
    elif layout == "empty dataset":
        group.pop("time", None)
        group.create_dataset("time", data=h5py.Empty("f8"))
    elif layout == "strings":
        group.pop("time", None)
        group.create_dataset("time", data=["a", "b"], dtype=h5py.string_dtype())
    elif layout == "compound":
        group.pop("qvel", None)
        group["qvel"] = np.zeros(ROWS, dtype=[("a", "<f8"), ("b", "<i4")])
    elif layout == "scalar time":
        group.pop("time", None)
        group["time"] = 0.5
    elif layout == "no groups":
        del handle["run0"]
    elif layout == "empty group":
        handle.create_group("run1")
    elif layout == "chunked and compressed":
        group.pop("qpos", None)
        group.create_dataset("qpos", data=arrays["qpos"], compression="gzip")
    elif layout == "booleans":
        group.pop("qvel", None)
        group["qvel"] = np.zeros((ROWS, 12), dtype=bool)


LAYOUTS = [
    "valid",
    "dataset at the top",
    "nested group",
    "attributes",
    "dangling soft link",
    "dangling group link",
    "external link",
    "hard link",
    "empty dataset",
    "strings",
    "compound",
    "scalar time",
    "no groups",
    "empty group",
    "chunked and compressed",
    "booleans",
]


@pytest.mark.parametrize("layout", LAYOUTS)
def test_hdf5_layouts(base: Base, layout: str) -> None:
    path = base.path(".h5")
    with h5py.File(path, "w") as handle:
        _hdf5_layout(handle, base.arrays, layout)
    error = base.read(path)
    if layout in ("valid", "nested group", "attributes", "hard link", "chunked and compressed"):
        assert error is None, error
    else:
        assert error is not None


@fuzz(100)
@given(layout=st.sampled_from(LAYOUTS), data=st.data())
def test_mutated_hdf5_layouts(base: Base, layout: str, data: st.DataObject) -> None:
    path = base.path(".h5")
    with h5py.File(path, "w") as handle:
        _hdf5_layout(handle, mutate(base.arrays, data) if data.draw(st.booleans()) else base.arrays, layout)
    if data.draw(st.booleans()):  # and then cut short or damaged
        content = bytearray(path.read_bytes())
        index = data.draw(st.integers(0, len(content) - 1))
        if data.draw(st.booleans()):
            content = content[:index]
        else:
            content[index] ^= data.draw(st.integers(1, 255))
        path.write_bytes(bytes(content))
    base.read(path)


# ---------------------------------------------------------------- random bytes, truncated and damaged files


@fuzz(100)
@given(content=st.binary(max_size=600), suffix=st.sampled_from([".npz", ".h5", ".hdf5", ".npy", ""]))
@example(content=b"", suffix=".npz")
@example(content=b"", suffix=".h5")
@example(content=b"PK\x05\x06" + b"\0" * 18, suffix=".npz")  # an empty zip archive
@example(content=b"\x89HDF\r\n\x1a\n", suffix=".h5")  # the HDF5 signature alone
@example(content=b"\x93NUMPY\x01\x00v\x00{'descr': '<f8', 'fortran_order': False, 'shape': (3,), }", suffix=".npz")
def test_random_bytes_as_rollout(base: Base, content: bytes, suffix: str) -> None:
    path = base.path(suffix)
    path.write_bytes(content)
    assert base.read(path) is not None


def _stored(arrays: dict[str, np.ndarray], kind: str) -> bytes:
    buffer = io.BytesIO()
    if kind == "h5":
        with h5py.File(buffer, "w") as handle:
            group = handle.create_group("run0")
            for key, value in arrays.items():
                group[key] = value
    else:
        (np.savez_compressed if kind == "compressed" else np.savez)(buffer, **arrays)
    return buffer.getvalue()


@fuzz(200)
@given(
    kind=st.sampled_from(["stored", "compressed", "h5"]),
    edit=st.sampled_from(["truncate", "byte", "block"]),
    position=st.floats(0.0, 1.0, exclude_max=True),
    value=st.integers(0, 255),
)
def test_truncated_or_damaged_rollout(base: Base, kind: str, edit: str, position: float, value: int) -> None:
    content = damaged(_stored(base.arrays, kind), edit, position, value, width=64)
    path = base.path(".h5" if kind == "h5" else ".npz")
    path.write_bytes(content)
    base.read(path)


def _npy(shape: tuple[int, ...], descr: str = "<f8", data: bytes = b"") -> bytes:
    buffer = io.BytesIO()
    np.lib.format.write_array_header_1_0(buffer, {"descr": descr, "fortran_order": False, "shape": shape})
    return buffer.getvalue() + data


@pytest.mark.parametrize(
    "member",
    [
        _npy((10**9, 10**9)),  # a huge declared shape: not allocated
        _npy((ROWS, 14), data=b"\0" * 10),  # its data cut short
        _npy((ROWS, 14), descr="|O"),  # Python objects
        _npy((-1, 14)),
        b"\x93NUMPY\x01\x00\xff\xff" + b"{" * 100,
        b"not an npy member",
    ],
)
def test_hostile_npz_members(base: Base, member: bytes) -> None:
    import zipfile

    path = base.path(".npz")
    with zipfile.ZipFile(path, "w") as archive:
        for key, value in base.arrays.items():
            if key != "qpos":
                stream = io.BytesIO()
                np.lib.format.write_array(stream, value)
                archive.writestr(f"{key}.npy", stream.getvalue())
        archive.writestr("qpos.npy", member)
    error = base.read(path)
    assert error is not None and "qpos" in str(error)


# ---------------------------------------------------------------- the whole record command


@pytest.mark.slow
@fuzz(120)
@given(data=st.data(), frames=st.integers(1, ROWS + 1))
@example(data=None, frames=3)
def test_record_with_mutated_values(base: Base, data: st.DataObject | None, frames: int) -> None:
    """Values a reader accepts (odd quaternions, huge positions, uneven times) through the whole record."""
    arrays = {name: value.copy() for name, value in base.arrays.items()}
    if data is not None:
        for _ in range(data.draw(st.integers(1, 3), label="edits")):
            name = data.draw(st.sampled_from(sorted(arrays)), label="array")
            if arrays[name].size == 0:
                continue
            flat = arrays[name].reshape(-1)
            index = data.draw(st.integers(0, flat.size - 1))
            flat[index] = data.draw(st.floats(-1e300, 1e300) | _SPECIAL | st.sampled_from([0.0, 1.0, -1.0]))
        if data.draw(st.booleans()):
            arrays.pop(data.draw(st.sampled_from(["ctrl", "mocap_pos", "mocap_quat"])), None)
    base.record(write_npz(base.path(".npz"), arrays), frames)
