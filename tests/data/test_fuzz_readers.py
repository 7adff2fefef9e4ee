"""Fuzzing the readers: garbage, truncated, corrupted and hostile dataset and scores files.

Every reader must answer bad input quickly with problems (``read_dataset``, ``check_dataset``) or
an :class:`EnergyMarginError` (``load_dataset``, ``evaluate``), never another exception, and must
not allocate what a hostile header declares.
"""

from __future__ import annotations

import io
import json
import shutil
import subprocess
import sys
import tempfile
import textwrap
import time
import zipfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, example, given, settings
from hypothesis import strategies as st

from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.run import analyze
from energy_margin.data.dataset import FRAMES_FILE, METADATA_FILE, Problem, load_dataset, read_dataset
from energy_margin.data.scores_file import COLUMNS, SCORES_FILE
from energy_margin.data.validation import check_dataset
from energy_margin.errors import EnergyMarginError
from energy_margin.evaluation.metrics import evaluate

# A reader that hangs or loops on a hostile input fails; a slow machine does not (the readers take
# well under a second here when the machine is quiet, 5-8 s with four other processes on 2 cores).
FAST = 30.0  # seconds any reader may take on these tiny inputs
FUZZ = settings(
    max_examples=50,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
SIZE_KEYS = ("n_trajectories", "n_frames", "n_objects", "n_robot_dofs", "n_drive")


# ---------------------------------------------------------------- fixtures and helpers


@pytest.fixture(scope="module")
def scored(tiny_dataset_source: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A valid tiny dataset with its scores.csv: the base every fuzzed copy starts from."""
    target = tmp_path_factory.mktemp("fuzz") / "scored"
    shutil.copytree(tiny_dataset_source, target)
    analyze(target, AnalyzerConfig(expansions=5), seed=0, progress=False)
    for name in ("analysis.json", "scores.journal.csv"):
        (target / name).unlink()
    return target


@pytest.fixture(scope="module")
def workdir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("fuzz-work")


@pytest.fixture(scope="module")
def stored_frames(scored: Path) -> bytes:
    """frames.npz of the base dataset rewritten uncompressed, so corruptions hit the .npy headers."""
    with np.load(scored / FRAMES_FILE) as archive:
        arrays = {name: archive[name] for name in archive.files}
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    return buffer.getvalue()


class Copy:
    """Fresh private copies of the base dataset, one per hypothesis example."""

    def __init__(self, base: Path, root: Path) -> None:
        self.base, self.root = base, root

    def __call__(self, **files: bytes) -> Path:
        directory = Path(tempfile.mkdtemp(dir=self.root))
        for source in self.base.iterdir():
            shutil.copy(source, directory / source.name)
        for name, content in files.items():
            (directory / name.replace("_", ".", 1)).write_bytes(content)
        return directory


@pytest.fixture(scope="module")
def copy(scored: Path, workdir: Path) -> Iterator[Copy]:
    yield Copy(scored, workdir)


def _timed(function: Any, *args: Any, **kwargs: Any) -> Any:
    started = time.perf_counter()
    try:
        return function(*args, **kwargs)
    finally:
        elapsed = time.perf_counter() - started
        assert elapsed < FAST, f"{function.__name__} took {elapsed:.1f} s"


def assert_readers_cope(directory: Path, *, with_evaluate: bool = True) -> list[Problem]:
    """Every reader on ``directory``: problems or EnergyMarginError only, each within FAST seconds."""
    dataset, problems = _timed(read_dataset, directory)
    assert isinstance(problems, list)
    assert all(isinstance(p, Problem) for p in problems)
    assert all("\n" not in str(p) for p in problems)
    assert (dataset is None) <= bool(problems)
    try:
        listed = _timed(check_dataset, directory)
    except EnergyMarginError:
        listed = None
    else:
        assert all(isinstance(p, Problem) for p in listed)
        if problems:
            assert listed == problems  # check lists the reader's problems first and stops there
    try:
        _timed(load_dataset, directory)
    except EnergyMarginError as error:
        assert problems, error
        assert "\n" not in str(error)
    else:
        assert not problems
    if with_evaluate:
        try:
            result = _timed(evaluate, directory)
        except EnergyMarginError as error:
            assert "\n" not in str(error)
        else:
            assert not problems
            assert listed == []
            assert result.n_frames == 6
    shutil.rmtree(directory)
    return problems


def _npy(shape: tuple[int, ...], descr: str = "<f8", data: bytes = b"\0" * 64, version: int = 1) -> bytes:
    """A .npy member with an arbitrary header and whatever data follows it."""
    buffer = io.BytesIO()
    header = {"descr": descr, "fortran_order": False, "shape": shape}
    if version == 1:
        np.lib.format.write_array_header_1_0(buffer, header)
    else:
        np.lib.format.write_array_header_2_0(buffer, header)
    buffer.write(data)
    return buffer.getvalue()


def _frames_with(scored: Path, compression: int = zipfile.ZIP_STORED, **members: bytes) -> bytes:
    """frames.npz of the base dataset with some members replaced by raw bytes."""
    with np.load(scored / FRAMES_FILE) as archive:
        arrays = {name: archive[name] for name in archive.files}
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", compression=compression) as out:
        for name, array in arrays.items():
            if name in members:
                out.writestr(f"{name}.npy", members.pop(name))
            else:
                stream = io.BytesIO()
                np.lib.format.write_array(stream, array, allow_pickle=False)
                out.writestr(f"{name}.npy", stream.getvalue())
        for name, content in members.items():
            out.writestr(name, content)
    return buffer.getvalue()


def _metadata(scored: Path) -> dict[str, Any]:
    return json.loads((scored / METADATA_FILE).read_text())


def test_the_base_dataset_is_valid(scored: Path, copy: Copy) -> None:
    assert assert_readers_cope(copy()) == []


# ---------------------------------------------------------------- random bytes


@FUZZ
@given(content=st.binary(max_size=3000))
@example(content=b"")
@example(content=b"\xff\xfe\x00")
@example(content=b"null")
@example(content=b"[]")
@example(content=b'{"format": "energy-margin-dataset"}')
@example(content=b'{"format": "energy-margin-dataset", "schema_version": 1}')
@example(content=b"NaN")
@example(content=b"1e999")
def test_random_bytes_as_dataset_json(copy: Copy, content: bytes) -> None:
    problems = assert_readers_cope(copy(dataset_json=content))
    assert problems
    assert problems[0].file == METADATA_FILE


@FUZZ
@given(content=st.binary(max_size=3000))
@example(content=b"")
@example(content=b"PK\x03\x04")
@example(content=b"PK\x05\x06" + b"\0" * 18)  # an empty zip archive
@example(content=b"\x93NUMPY\x01\x00v\x00{'descr': '<f8', 'fortran_order': False, 'shape': (3,), }")
def test_random_bytes_as_frames_npz(copy: Copy, content: bytes) -> None:
    problems = assert_readers_cope(copy(frames_npz=content))
    assert problems
    assert all(p.file == FRAMES_FILE for p in problems)


@FUZZ
@given(content=st.binary(max_size=2000))
@example(content=b"")
@example(content=b"\xff" * 10)
@example(content=(",".join(COLUMNS) + "\n").encode())
def test_random_bytes_as_scores_csv(copy: Copy, content: bytes) -> None:
    directory = copy(scores_csv=content)
    assert any(p.file == SCORES_FILE for p in check_dataset(directory))
    assert_readers_cope(directory)


_FIELD = st.one_of(
    st.integers(-(2**63), 2**63 - 1).map(str),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.text(alphabet="0123456789.-+eE_ naif,x", max_size=18),
)


@FUZZ
@given(data=st.data())
def test_mutated_scores_rows(copy: Copy, scored: Path, data: st.DataObject) -> None:
    """scores.csv with rows dropped, duplicated, reordered or with fields replaced."""
    lines = (scored / SCORES_FILE).read_text().splitlines()
    header, rows = lines[0], [line.split(",") for line in lines[1:]]
    rows = data.draw(st.permutations(rows))
    rows = rows[: data.draw(st.integers(0, len(rows)))]
    if rows and data.draw(st.booleans()):
        rows.append(list(data.draw(st.sampled_from(rows))))
    for _ in range(data.draw(st.integers(0, 4))):
        if rows:
            row = data.draw(st.sampled_from(rows))
            row[data.draw(st.integers(0, len(COLUMNS) - 1))] = data.draw(_FIELD)
    newline = data.draw(st.sampled_from(["\n", "\r\n"]))
    text = newline.join([header, *(",".join(r) for r in rows)]) + data.draw(st.sampled_from(["", newline]))
    assert_readers_cope(copy(scores_csv=text.encode()))


# ---------------------------------------------------------------- truncated and corrupted copies


@FUZZ
@given(name=st.sampled_from([METADATA_FILE, FRAMES_FILE, SCORES_FILE]), fraction=st.floats(0.0, 1.0))
def test_truncated_files(copy: Copy, scored: Path, name: str, fraction: float) -> None:
    content = (scored / name).read_bytes()
    cut = int(fraction * (len(content) - 1))  # always at least one byte short
    directory = copy(**{name.replace(".", "_"): content[:cut]})
    problems = assert_readers_cope(directory)
    if name != SCORES_FILE and cut < len(content.rstrip()):  # dataset.json may lose its final newline
        assert problems


@FUZZ
@given(position=st.floats(0.0, 1.0, exclude_max=True), value=st.integers(0, 255))
def test_single_byte_corruption_of_the_compressed_archive(
    copy: Copy, scored: Path, position: float, value: int
) -> None:
    content = bytearray((scored / FRAMES_FILE).read_bytes())
    index = int(position * len(content))
    assume(content[index] != value)
    content[index] = value
    assert_readers_cope(copy(frames_npz=bytes(content)))


@FUZZ
@given(position=st.floats(0.0, 1.0, exclude_max=True), value=st.integers(0, 255))
def test_single_byte_corruption_of_a_stored_archive(
    copy: Copy, stored_frames: bytes, position: float, value: int
) -> None:
    content = bytearray(stored_frames)
    index = int(position * len(content))
    assume(content[index] != value)
    content[index] = value
    assert_readers_cope(copy(frames_npz=bytes(content)))


@pytest.mark.parametrize("block", [1, 64])
def test_corrupting_every_region_of_the_npy_headers(copy: Copy, stored_frames: bytes, block: int) -> None:
    """Overwrite each .npy header of the stored archive in turn (deterministic sweep)."""
    starts = [i for i in range(len(stored_frames)) if stored_frames.startswith(b"\x93NUMPY", i)]
    assert len(starts) == 10
    for start in starts:
        for offset in range(0, 128, 16):
            content = bytearray(stored_frames)
            content[start + offset : start + offset + block] = bytes([0x41 ^ offset & 0xFF]) * block
            assert_readers_cope(copy(frames_npz=bytes(content)))


# ---------------------------------------------------------------- hostile metadata


@pytest.mark.parametrize("key", SIZE_KEYS)
@pytest.mark.parametrize(
    "value",
    [10**12, 10**400, -1, "3", 3.5, 2.0, None, [3], {"n": 3}, True, float("inf"), float("nan")],
    ids=repr,
)
def test_wrong_sizes_in_dataset_json(copy: Copy, scored: Path, key: str, value: Any) -> None:
    metadata = _metadata(scored)
    metadata[key] = value
    problems = assert_readers_cope(copy(dataset_json=json.dumps(metadata).encode()))
    assert [p.field for p in problems] == [key]
    assert "must be an integer" in str(problems[0])


@pytest.mark.parametrize("value", [0, 2, "1", None, [1], {"v": 1}, 10**30, -1])
def test_unsupported_schema_version(copy: Copy, scored: Path, value: Any) -> None:
    metadata = _metadata(scored)
    metadata["schema_version"] = value
    problems = assert_readers_cope(copy(dataset_json=json.dumps(metadata).encode()))
    assert [p.field for p in problems] == ["schema_version"]
    assert "is not supported" in problems[0].message


@pytest.mark.parametrize("value", [None, "energy-margin", 1, ["energy-margin-dataset"]])
def test_wrong_format(copy: Copy, scored: Path, value: Any) -> None:
    metadata = _metadata(scored)
    metadata["format"] = value
    problems = assert_readers_cope(copy(dataset_json=json.dumps(metadata).encode()))
    assert [p.field for p in problems] == ["format"]


@pytest.mark.parametrize("value", [None, 3, "", "PUSHING", ["pushing"], {"name": "pushing"}])
def test_wrong_task(copy: Copy, scored: Path, value: Any) -> None:
    metadata = _metadata(scored)
    metadata["task"] = value
    problems = assert_readers_cope(copy(dataset_json=json.dumps(metadata).encode()))
    assert [p.field for p in problems] == ["task_config"]
    assert "unknown task" in problems[0].message


def test_missing_keys_are_all_listed(copy: Copy, scored: Path) -> None:
    metadata = {k: v for k, v in _metadata(scored).items() if k not in ("task", "n_frames", "n_drive")}
    problems = assert_readers_cope(copy(dataset_json=json.dumps(metadata).encode()))
    assert [(p.field, p.message) for p in problems] == [(k, "is missing") for k in ("task", "n_frames", "n_drive")]


_JSON_NOT_A_NUMBER = st.recursive(
    st.none() | st.booleans() | st.text(max_size=8),
    lambda children: st.lists(children, max_size=3) | st.dictionaries(st.text(max_size=4), children, max_size=3),
    max_leaves=6,
)
_ANY_JSON = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=8),
    lambda children: st.lists(children, max_size=3) | st.dictionaries(st.text(max_size=4), children, max_size=3),
    max_leaves=6,
)


@FUZZ
@given(data=st.data())
def test_task_config_with_wrong_types(copy: Copy, scored: Path, data: st.DataObject) -> None:
    metadata = _metadata(scored)
    config = metadata["task_config"]
    for key in data.draw(st.lists(st.sampled_from(sorted(config)), min_size=1, max_size=4, unique=True)):
        config[key] = data.draw(_JSON_NOT_A_NUMBER)
    problems = assert_readers_cope(copy(dataset_json=json.dumps(metadata).encode()))
    assert [p.field for p in problems] == ["task_config"]


@FUZZ
@given(task_config=_ANY_JSON.filter(lambda v: not isinstance(v, dict) or v))
def test_task_config_that_is_not_a_settings_object(copy: Copy, scored: Path, task_config: Any) -> None:
    metadata = _metadata(scored)
    metadata["task_config"] = task_config
    problems = assert_readers_cope(copy(dataset_json=json.dumps(metadata).encode()))
    if task_config is not None:  # None means "the task's defaults"
        assert [p.field for p in problems] == ["task_config"]


@FUZZ
@given(
    key=st.sampled_from(["format", "schema_version", "task", "engine", "seed", "package_version", "extra", *SIZE_KEYS]),
    value=_ANY_JSON,
)
def test_any_top_level_value(copy: Copy, scored: Path, key: str, value: Any) -> None:
    metadata = _metadata(scored)
    metadata[key] = value
    assert_readers_cope(copy(dataset_json=json.dumps(metadata).encode()))


# ---------------------------------------------------------------- hostile archives


def test_huge_declared_shape_is_not_allocated(copy: Copy, scored: Path) -> None:
    frames = _frames_with(scored, object_pos=_npy((10**9, 10**9)), robot_q=_npy((10**9, 10**9), version=2))
    problems = assert_readers_cope(copy(frames_npz=frames))
    assert [(p.field, p.message) for p in problems] == [
        ("object_pos", "has shape (1000000000, 1000000000), expected (2, 3, 2, 3)"),
        ("robot_q", "has shape (1000000000, 1000000000), expected (2, 3, 4)"),
    ]


@pytest.mark.parametrize(
    "member",
    [
        _npy((2, 3, 2, 3), data=b"\0" * 10),  # the expected shape, its data cut short
        _npy((2, 3, 2, 3), descr="<f8", data=b""),
        _npy((2, 3, 2, 3), descr="|V100000", data=b"\0" * 10),  # a huge item size
        _npy((2, 3, 2, 3), descr="|O"),  # Python objects
        b"\x93NUMPY\x01\x00\x10\x00{'descr': ''}\n",  # a broken header
        b"\x93NUMPY\x09\x00\x10\x00" + b" " * 16,  # an unknown version
        b"\x93NUMPY\x01\x00\xff\xff" + b"{" * 100,  # a header longer than the member
        b"not an npy file at all",
        b"",
    ],
)
def test_hostile_members(copy: Copy, scored: Path, member: bytes) -> None:
    problems = assert_readers_cope(copy(frames_npz=_frames_with(scored, object_pos=member)))
    assert [p.field for p in problems] == ["object_pos"]


def test_non_array_members_are_ignored_or_named(copy: Copy, scored: Path) -> None:
    # Unknown members are ignored; a directory entry or a text file under an array's name is named.
    frames = _frames_with(scored, **{"notes.txt": b"hello", "nested/": b"", "object_pos.npy.bak": b"x"})
    assert assert_readers_cope(copy(frames_npz=frames)) == []
    frames = _frames_with(scored, friction=b"0.1,0.2\n")
    problems = assert_readers_cope(copy(frames_npz=frames))
    assert [p.field for p in problems] == ["friction"]


@pytest.mark.filterwarnings("ignore:Duplicate name")
def test_member_named_twice(copy: Copy, scored: Path) -> None:
    frames = _frames_with(scored, **{"friction.npy": _npy((7,))})  # a second, wrong friction member
    assert_readers_cope(copy(frames_npz=frames))


def test_encrypted_flag(copy: Copy, scored: Path) -> None:
    content = bytearray(_frames_with(scored))
    # Set the "encrypted" bit of every central-directory entry.
    index = content.find(b"PK\x01\x02")
    while index >= 0:
        content[index + 8] |= 0x01
        index = content.find(b"PK\x01\x02", index + 4)
    problems = assert_readers_cope(copy(frames_npz=bytes(content)))
    assert problems
    assert all("corrupt" in p.message for p in problems)


def test_bzip2_compressed_members_are_read(copy: Copy, scored: Path) -> None:
    assert assert_readers_cope(copy(frames_npz=_frames_with(scored, zipfile.ZIP_BZIP2))) == []


# ---------------------------------------------------------------- known defects


def _json_case(scored: Path, case: str) -> bytes:
    if case == "deeply nested":
        return b"[" * 100_000 + b"]" * 100_000
    metadata = json.dumps(_metadata(scored))
    return metadata.replace('"n_frames": 3', '"n_frames": 1' + "0" * 5000).encode()


@pytest.mark.parametrize("case", ["deeply nested", "integer with 5001 digits"])
def test_json_that_python_refuses_to_parse(copy: Copy, scored: Path, case: str) -> None:
    problems = assert_readers_cope(copy(dataset_json=_json_case(scored, case)))
    assert [p.field for p in problems] == ["file"]


def test_damaged_lzma_member(copy: Copy, scored: Path) -> None:
    content = bytearray(_frames_with(scored, zipfile.ZIP_LZMA))
    info = zipfile.ZipFile(io.BytesIO(bytes(content))).infolist()[0]
    data = info.header_offset + 30 + len(info.filename)
    for i in range(data + 4, data + 40):  # keep the 4-byte LZMA properties header, damage the stream
        content[i] ^= 0xFF
    problems = assert_readers_cope(copy(frames_npz=bytes(content)))
    assert problems[0].field == "object_pos"


def test_header_declaring_the_largest_allowed_shape(copy: Copy, scored: Path) -> None:
    metadata = _metadata(scored)
    metadata.update(n_trajectories=1_000_000, n_frames=100_000, n_objects=1)
    frames = _frames_with(scored, object_pos=_npy((1_000_000, 100_000, 1, 3)))
    problems = assert_readers_cope(copy(dataset_json=json.dumps(metadata).encode(), frames_npz=frames))
    assert problems[0].field == "object_pos"


@pytest.mark.parametrize(("key", "value"), [("object_radius", 1e300), ("object_mass", 1e-300)])
def test_extreme_task_settings(copy: Copy, scored: Path, key: str, value: float) -> None:
    metadata = _metadata(scored)
    metadata["task_config"][key] = value
    assert_readers_cope(copy(dataset_json=json.dumps(metadata).encode()))


def test_robot_dofs_that_do_not_match_the_task(copy: Copy, scored: Path) -> None:
    metadata = _metadata(scored)
    metadata["n_robot_dofs"] = 2
    with np.load(scored / FRAMES_FILE) as archive:
        arrays = {name: archive[name] for name in archive.files}
    arrays["robot_q"] = arrays["robot_q"][..., :2].copy()
    arrays["robot_v"] = arrays["robot_v"][..., :2].copy()
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    problems = assert_readers_cope(copy(dataset_json=json.dumps(metadata).encode(), frames_npz=buffer.getvalue()))
    assert problems[0].field == "n_robot_dofs"


@pytest.mark.parametrize("column", ["nodes", "expansions"])
def test_counts_beyond_int64_in_scores(copy: Copy, scored: Path, column: str) -> None:
    lines = (scored / SCORES_FILE).read_text().splitlines(keepends=True)
    fields = lines[1].split(",")
    fields[COLUMNS.index(column)] = str(2**63)
    lines[1] = ",".join(fields)
    assert_readers_cope(copy(scores_csv="".join(lines).encode()))


def test_memory_stays_bounded_on_hostile_headers(copy: Copy, scored: Path) -> None:
    """Under a 2 GiB address-space limit the reader still answers a header that declares 4 GB."""
    # 2 trajectories of a 2 GB item each: the member matches the metadata's shape (2,) for friction.
    frames = _frames_with(scored, friction=_npy((2,), descr="|V2000000000", data=b"\0" * 64))
    directory = copy(frames_npz=frames)
    script = textwrap.dedent(
        f"""
        import resource
        from energy_margin.data.dataset import read_dataset
        soft = int(open("/proc/self/statm").read().split()[0]) * resource.getpagesize() + (2 << 30)
        resource.setrlimit(resource.RLIMIT_AS, (soft, resource.RLIM_INFINITY))
        dataset, problems = read_dataset({str(directory)!r})
        print([p.field for p in problems])
        """
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60, check=False)
    shutil.rmtree(directory)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "['friction']"
