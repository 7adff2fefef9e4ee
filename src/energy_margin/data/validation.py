"""Checks run before long jobs and by ``energy-margin check``.

Each problem names the file, the field and the row. ``check_dataset`` lists them all; ``analyze``
and ``evaluate`` run the same checks first and stop on the first problem, before writing anything.

Checks: the format and schema version of ``dataset.json`` (a later schema version is refused),
its sizes and task configuration; every array of ``frames.npz`` against n_o, T, K (shapes read
from the headers before any allocation), NaN or infinite values, unit quaternions, labels in
{0, 1}; objects outside their task's frame box or faster than its speed bound
(:mod:`energy_margin.data.physical`); objects interpenetrating each other, the end-effector or an
obstacle at a frame; and,
when present, ``scores.csv`` (header, malformed lines, rows outside the dataset, duplicated or
missing frames, scores outside [0, 1]). ``check`` also lists, as warnings, engine versions other
than the installed ones or unknown (:mod:`energy_margin.data.provenance`).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from energy_margin.data.dataset import FRAMES_FILE, Dataset, Problem, raise_first, read_dataset
from energy_margin.data.physical import frame_violations, state_problems
from energy_margin.data.provenance import version_findings
from energy_margin.data.scores_file import (
    COLUMNS,
    INTEGER_COLUMNS,
    SCORES_FILE,
    UNKNOWN_COUNT,
    current_names,
    file_columns,
)
from energy_margin.sim import Simulator
from energy_margin.world.scene import Scene
from energy_margin.world.state import FrameState

#: Interpenetration deeper than this fraction of an object's largest half-extent, and deeper than
#: :data:`OVERLAP_FLOOR`, is an overlap. Soft contacts leave some penetration in valid frames: up to
#: about 10 mm between the 5 cm-radius pushing cylinders under the pusher's load, and up to 3.4 mm
#: between 1 cm scooping boxes pressed into the blades or into each other (the task's own generated
#: sets: the 100-trajectory seed-14 set at the default design, and designs of docs/howto/sweep.md).
OVERLAP_FRACTION = 0.5
#: Smallest overlap limit, m: how deep a soft contact goes depends on its stiffness and load, not on
#: the object's size, so small objects get this much (4 mm) whatever their size.
OVERLAP_FLOOR = 0.004
_MAX_PER_KIND = 5


def overlap_limits(scene: Scene) -> list[float]:
    """Each object's overlap limit, m: :data:`OVERLAP_FRACTION` of its largest half-extent, at least the floor."""
    return [max(OVERLAP_FRACTION * max(obj.geom.size), OVERLAP_FLOOR) for obj in scene.objects]


def deep_overlaps(simulator: Simulator, limits: list[float]) -> list[tuple[int, int, float, float]]:
    """Pairs of the simulator's current state that overlap deeper than their limit.

    Args:
        simulator: a simulator holding the state to check (after ``reset``).
        limits: :func:`overlap_limits` of its scene, m.

    Returns:
        ``(object, other, depth, limit)`` per overlapping pair, the deepest of its contact points,
        sorted: ``other`` is another object's index or -1 for the end-effector or an obstacle;
        ``depth`` and ``limit`` in metres.
    """
    deepest: dict[tuple[int, int], float] = {}
    for obj, other, depth in simulator.object_penetrations():
        pair = (min(obj, other), max(obj, other)) if other >= 0 else (obj, other)
        deepest[pair] = max(depth, deepest.get(pair, 0.0))
    found = []
    for (obj, other), depth in sorted(deepest.items()):
        if other < 0:
            obj, other = max(obj, other), -1
        limit = limits[obj] if other < 0 else min(limits[obj], limits[other])
        if depth > limit:
            found.append((obj, other, depth, limit))
    return found


def trajectory_simulator(dataset: Dataset, trajectory: int) -> tuple[Simulator, list[float]]:
    """A simulator of one trajectory's own scene (its friction and drive) and its :func:`overlap_limits`, m."""
    arrays = dataset.arrays
    simulator = dataset.task.make_simulator(
        dataset.n_objects,
        float(arrays["friction"][trajectory]),
        arrays["drive"][trajectory],
        str(dataset.metadata.get("engine", "mujoco")),
    )
    return simulator, overlap_limits(simulator.scene)


def overlaps_at(simulator: Simulator, limits: list[float], state: FrameState) -> list[tuple[int, int, float, float]]:
    """:func:`deep_overlaps` of ``state``, which ``simulator`` is reset to."""
    simulator.reset(state)
    return deep_overlaps(simulator, limits)


def describe_overlap(obj: int, other: int, depth: float, limit: float) -> str:
    """One overlap of :func:`deep_overlaps` in words."""
    what = f"object {other}" if other >= 0 else "the end-effector or an obstacle"
    return f"object {obj} overlaps {what} by {1000 * depth:.1f} mm (limit {1000 * limit:.1f} mm)"


def overlap_problems(dataset: Dataset) -> list[Problem]:
    """Frames where objects overlap each other, the end-effector or an obstacle."""
    problems: list[Problem] = []
    for trajectory in range(dataset.n_trajectories):
        try:
            simulator, limits = trajectory_simulator(dataset, trajectory)
        except (ValueError, OverflowError, FloatingPointError, ZeroDivisionError) as error:
            return [
                Problem("dataset.json", "task_config", "", f"cannot build the scene ({' '.join(str(error).split())})")
            ]
        for frame in range(dataset.n_frames):
            for overlap in overlaps_at(simulator, limits, dataset.frame(trajectory, frame)):
                problems.append(
                    Problem(
                        FRAMES_FILE, "object_pos", f"trajectory {trajectory}, frame {frame}", describe_overlap(*overlap)
                    )
                )
                if len(problems) >= _MAX_PER_KIND:
                    checked = trajectory * dataset.n_frames + frame + 1
                    left = dataset.n_trajectories * dataset.n_frames - checked
                    if left:
                        problems.append(
                            Problem(FRAMES_FILE, "object_pos", "", f"not looked for in the {left} frame(s) after these")
                        )
                    return problems
    return problems


def unphysical_trajectories(dataset: Dataset) -> dict[int, str]:
    """The trajectories of ``dataset`` with a physically impossible frame, each with its first one in words.

    The checks of :func:`check_dataset`, per trajectory up to its first failing frame: every object
    inside the task's frame box and under its speed bound, and no objects interpenetrating deeper
    than :func:`overlap_limits` allow (each trajectory's own scene: its friction and drive).

    Returns:
        ``{trajectory: "frame k: what is wrong"}``, empty when every frame is possible.

    """
    box = dataset.task.frame_box
    found: dict[int, str] = {}
    for trajectory in range(dataset.n_trajectories):
        simulator, limits = trajectory_simulator(dataset, trajectory)
        for frame in range(dataset.n_frames):
            state = dataset.frame(trajectory, frame)
            violations = frame_violations(box, state)
            if violations:
                found[trajectory] = f"frame {frame}: {violations[0].message}"
                break
            overlapping = overlaps_at(simulator, limits, state)
            if overlapping:
                found[trajectory] = f"frame {frame}: {describe_overlap(*overlapping[0])}"
                break
    return found


def scores_problems(path: Path | str, dataset: Dataset) -> list[Problem]:
    """Problems of ``scores.csv`` in the dataset directory ``path`` (which must exist)."""
    scores_path = Path(path) / SCORES_FILE
    try:
        text = scores_path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as error:
        return [Problem(SCORES_FILE, "file", "", f"cannot be read ({error})")]
    lines = text.splitlines()
    columns = file_columns(lines[0] if lines else "")
    if columns is None:
        return [Problem(SCORES_FILE, "header", "line 1", f"expected {','.join(COLUMNS)}")]
    columns = current_names(columns)
    problems: list[Problem] = []
    seen: dict[tuple[int, int], int] = {}
    for number, line in enumerate(lines[1:], start=2):
        fields = line.split(",")
        if len(fields) != len(columns):
            problems.append(
                Problem(SCORES_FILE, "row", f"line {number}", f"has {len(fields)} fields, expected {len(columns)}")
            )
            continue
        row: dict[str, float] = {"rejected": UNKNOWN_COUNT, "diverged": UNKNOWN_COUNT, "tree_capture_score": math.nan}
        for name, value in zip(columns, fields, strict=True):
            try:
                row[name] = int(value) if name in INTEGER_COLUMNS else float(value)
            except ValueError:
                problems.append(Problem(SCORES_FILE, name, f"line {number}", f"{value[:40]!r} is not a number"))
                break
        else:
            problems.extend(_row_problems(row, number, dataset, seen))
        if len(problems) >= _MAX_PER_KIND:
            return problems
    for trajectory in range(dataset.n_trajectories):
        for frame in range(dataset.n_frames):
            if (trajectory, frame) not in seen:
                problems.append(Problem(SCORES_FILE, "row", f"trajectory {trajectory}, frame {frame}", "is missing"))
                if len(problems) >= _MAX_PER_KIND:
                    return problems
    return problems


def _row_problems(
    row: dict[str, float], number: int, dataset: Dataset, seen: dict[tuple[int, int], int]
) -> list[Problem]:
    where = f"line {number}"
    key = (int(row["trajectory"]), int(row["frame"]))
    if not (0 <= key[0] < dataset.n_trajectories and 0 <= key[1] < dataset.n_frames):
        return [Problem(SCORES_FILE, "trajectory", where, f"frame {key} is outside the dataset")]
    if key in seen:
        return [
            Problem(SCORES_FILE, "row", where, f"duplicates line {seen[key]} (trajectory {key[0]}, frame {key[1]})")
        ]
    seen[key] = number
    problems = []
    for name in ("capture_score", "success_score"):
        value = row[name]
        if not (math.isfinite(value) and 0.0 <= value <= 1.0):
            problems.append(Problem(SCORES_FILE, name, where, f"{value!r} is outside [0, 1]"))
    tree_capture = row["tree_capture_score"]
    if not (math.isnan(tree_capture) or 0.0 <= tree_capture <= 1.0):
        problems.append(
            Problem(SCORES_FILE, "tree_capture_score", where, f"{tree_capture!r} is outside [0, 1] (nan: unknown)")
        )
    for name in ("runtime_s", "physics_s"):
        if not (math.isfinite(row[name]) and row[name] >= 0):
            problems.append(Problem(SCORES_FILE, name, where, f"{row[name]!r} is not a non-negative time"))
    if not (1 <= row["nodes"] < 2**63 and 0 <= row["expansions"] < 2**63 and 0 <= row["seed"] < 2**64):
        problems.append(Problem(SCORES_FILE, "nodes", where, "nodes, expansions or seed out of range"))
    for name in ("rejected", "diverged"):
        if not UNKNOWN_COUNT <= row[name] < 2**63:
            problems.append(Problem(SCORES_FILE, name, where, f"{row[name]!r} is not a count (-1: unknown)"))
    return problems


def check_dataset(
    path: Path | str, *, overlaps: bool = True, scores: bool | None = None, warnings: list[Problem] | None = None
) -> list[Problem]:
    """Every problem of a dataset directory.

    Args:
        path: dataset directory.
        overlaps: also look for overlapping objects (builds the scenes; a fraction of a second).
        scores: check ``scores.csv``: ``True`` requires it, ``None`` checks it when present,
            ``False`` skips it.
        warnings: receives the overlaps of a dataset whose overlaps are expected
            (:func:`overlaps_expected`) and the engine versions of a dataset generated under
            another version, or unknown (:func:`~energy_margin.data.provenance.version_findings`),
            which are warnings, not problems.
    """
    return _check(path, overlaps=overlaps, scores=scores, warnings=warnings)[1]


def overlaps_expected(metadata: dict[str, Any]) -> bool:
    """Whether overlapping objects are expected in a dataset with this ``dataset.json`` content.

    Three kinds of set hold them by construction: an imported set (``imported_from``: the authors'
    frames were recorded with their own robot model, which this project's scene only
    approximates), a perturbed copy drawn with the authors' protocol (``perturbation.protocol``
    ``"paper"``: their draw lets objects interpenetrate), and a recorded set (``recorded_from``:
    the frames are the states of the user's own simulation, whose contacts may be as soft as its
    model makes them: Gymnasium Pusher's 8 mg puck is pushed 4 to 6 cm deep by the arm).
    """
    perturbation = metadata.get("perturbation")
    paper = isinstance(perturbation, dict) and perturbation.get("protocol") == "paper"
    return bool(metadata.get("imported_from")) or bool(metadata.get("recorded_from")) or paper


def _check(
    path: Path | str, *, overlaps: bool, scores: bool | None, warnings: list[Problem] | None = None
) -> tuple[Dataset | None, list[Problem]]:
    dataset, problems = read_dataset(path)
    if dataset is None or problems:
        return dataset, problems
    if warnings is not None:
        warnings.extend(version_findings(path, dataset.metadata))
    problems.extend(state_problems(dataset))
    if overlaps:
        found = overlap_problems(dataset)
        if overlaps_expected(dataset.metadata):
            if warnings is not None:
                warnings.extend(found)
        else:
            problems.extend(found)
    scores_path = Path(path) / SCORES_FILE
    if scores is True and not scores_path.is_file():
        problems.append(Problem(SCORES_FILE, "file", "", "does not exist; run `energy-margin analyze` first"))
    elif scores is not False and scores_path.is_file():
        problems.extend(scores_problems(path, dataset))
    return dataset, problems


def require_valid(path: Path | str, *, overlaps: bool = True, scores: bool | None = False) -> Dataset:
    """Load the dataset at ``path`` after :func:`check_dataset`; raise on the first problem."""
    dataset, problems = _check(path, overlaps=overlaps, scores=scores)
    raise_first(path, problems)
    assert dataset is not None
    return dataset


__all__ = [
    "OVERLAP_FLOOR",
    "OVERLAP_FRACTION",
    "Problem",
    "check_dataset",
    "deep_overlaps",
    "describe_overlap",
    "overlap_limits",
    "overlap_problems",
    "overlaps_expected",
    "require_valid",
    "scores_problems",
    "unphysical_trajectories",
]
