"""``check`` finds every corruption of a sound dataset: 1,000 of them, none missed, no other exception.

Each case corrupts one copy of a small generated pushing set in one way (a NaN, an object outside
the task's frame box, an object too fast, two objects overlapping, an array of the wrong shape)
and checks that :func:`check_dataset` names it: the array, and the trajectory, frame and object.
"""

from __future__ import annotations

import json
import shutil
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from energy_margin.data.dataset import FRAMES_FILE, METADATA_FILE, load_dataset
from energy_margin.data.generate import generate_dataset
from energy_margin.data.validation import check_dataset

CASES = 1000
KINDS = ("nan", "outside", "too_fast", "overlap", "shape")


@pytest.fixture(scope="module")
def sound(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("fuzz") / "sound"
    generate_dataset("pushing", n_objects=2, n_trajectories=2, n_frames=3, seed=3, out=out)
    assert check_dataset(out) == []
    return out


def _corrupt(arrays: dict[str, np.ndarray], kind: str, rng: np.random.Generator, box: object) -> tuple[str, str]:
    """Corrupt ``arrays`` in place; return the field and the location a problem must name."""
    t, k, n = arrays["object_pos"].shape[:3]
    trajectory, frame, obj = int(rng.integers(t)), int(rng.integers(k)), int(rng.integers(n))
    where = f"trajectory {trajectory}, frame {frame}, object {obj}"
    if kind == "nan":
        name = str(rng.choice(["object_pos", "object_quat", "object_vel"]))
        arrays[name][trajectory, frame, obj, int(rng.integers(arrays[name].shape[-1]))] = rng.choice(
            [np.nan, np.inf, -np.inf]
        )
        return name, where
    if kind == "outside":
        axis = int(rng.integers(3))
        low, high = box.low[axis], box.high[axis]  # type: ignore[attr-defined]
        arrays["object_pos"][trajectory, frame, obj, axis] = (
            low - rng.uniform(1e-3, 1e6) if rng.random() < 0.5 else high + rng.uniform(1e-3, 1e6)
        )
        return "object_pos", where
    if kind == "too_fast":
        direction = rng.normal(size=3)
        speed = box.max_speed * rng.uniform(1.001, 1e4)  # type: ignore[attr-defined]
        arrays["object_vel"][trajectory, frame, obj, :3] = speed * direction / np.linalg.norm(direction)
        return "object_vel", where
    if kind == "overlap":
        # The other cylinder (radius 5 cm) 3 to 7 cm from this one's axis: 30 to 70 mm deep, past
        # the 25 mm limit. (Nearly coincident cylinders are left out: MuJoCo 3.3's convex
        # collision finds no contact between them.)
        other = 1 - obj
        angle, distance = rng.uniform(0.0, 2.0 * np.pi), rng.uniform(0.03, 0.07)
        offset = distance * np.array([np.cos(angle), np.sin(angle)])
        arrays["object_pos"][trajectory, frame, other, :2] = arrays["object_pos"][trajectory, frame, obj, :2] + offset
        return "object_pos", f"trajectory {trajectory}, frame {frame}"
    name = str(rng.choice(["object_pos", "object_vel", "robot_q", "captured", "frame_time"]))
    array = arrays[name]
    axis = int(rng.integers(array.ndim))
    arrays[name] = np.delete(array, 0, axis=axis) if rng.random() < 0.5 else np.concatenate([array, array], axis=axis)
    return name, "has shape"


def test_check_finds_every_corruption(sound: Path, tmp_path: Path) -> None:
    box = load_dataset(sound).task.frame_box
    with np.load(sound / FRAMES_FILE) as archive:
        original = {name: archive[name] for name in archive.files}
    rng = np.random.default_rng(2026)
    found: Counter[str] = Counter()
    missed: list[str] = []
    for case in range(CASES):
        kind = KINDS[case % len(KINDS)]
        arrays = {name: value.copy() for name, value in original.items()}
        field, where = _corrupt(arrays, kind, rng, box)
        folder = tmp_path / f"case{case}"
        folder.mkdir()
        shutil.copy(sound / METADATA_FILE, folder / METADATA_FILE)
        np.savez(folder / FRAMES_FILE, **arrays)
        problems = [str(problem) for problem in check_dataset(folder)]
        if any(field in text and where in text for text in problems):
            found[kind] += 1
        else:
            missed.append(f"{kind} {field} [{where}]: {problems}")
        shutil.rmtree(folder)
    assert missed == []
    assert sum(found.values()) == CASES
    assert set(found) == set(KINDS)
    print(json.dumps({"corruptions": CASES, "found": dict(found), "missed": len(missed)}))


def test_check_counts_what_it_does_not_list(sound: Path, tmp_path: Path) -> None:
    with np.load(sound / FRAMES_FILE) as archive:
        arrays = {name: archive[name] for name in archive.files}
    arrays["object_pos"][:, :, :, 0] = 1e7  # every object of every frame: 12, five listed
    folder = tmp_path / "far"
    folder.mkdir()
    shutil.copy(sound / METADATA_FILE, folder / METADATA_FILE)
    np.savez(folder / FRAMES_FILE, **arrays)
    problems = [str(problem) for problem in check_dataset(folder, overlaps=False)]
    assert len(problems) == 6
    assert problems[-1] == "frames.npz: object_pos: 7 more object(s) outside the bounds in other frames"


def test_check_says_where_it_stopped_looking_for_overlaps(
    sound: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr("energy_margin.data.validation._MAX_PER_KIND", 2)
    with np.load(sound / FRAMES_FILE) as archive:
        arrays = {name: archive[name] for name in archive.files}
    arrays["object_pos"][:, :, 1, :2] = arrays["object_pos"][:, :, 0, :2] + [0.05, 0.0]  # every frame overlaps
    folder = tmp_path / "crowded"
    folder.mkdir()
    shutil.copy(sound / METADATA_FILE, folder / METADATA_FILE)
    np.savez(folder / FRAMES_FILE, **arrays)
    problems = check_dataset(folder)
    assert len(problems) == 3 and all("overlaps object" in problem.message for problem in problems[:2])
    trajectory, frame = (int(part.split()[-1]) for part in problems[1].row.split(", "))
    left = 2 * 3 - (trajectory * 3 + frame + 1)
    assert str(problems[-1]) == f"frames.npz: object_pos: not looked for in the {left} frame(s) after these"
    assert left > 0
