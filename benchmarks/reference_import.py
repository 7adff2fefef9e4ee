"""The reference import's constants and the measured facts of its mapping onto this project's tasks.

docs/results/reference.md describes how ``energy-margin import-reference`` maps the authors' frames
(``../shared/reference/energy_margin_workshop``) onto this project's pushing and scooping tasks; it
quotes every figure of that mapping from the file this benchmark writes:

* ``constants``: read from the code, nothing measured: the constants of
  ``energy_margin.data.reference_convert``, the resting box height in their units, the pushing
  drive factor, the success band, the scooping script's finger target at their first frame;
* ``pushing``: imported with ``import-reference`` (their scores too): their friction and the
  effective one, the nominal drive, this project's regions against their labels (capture per
  frame, success at the last frame), the ``current_state`` success baseline of ``evaluate --json``;
* ``scooping``: the same import: their heights, the base's acceleration per trajectory, the
  capture region against their label with the import's blades and with this task's default
  blades, the farthest captured box off the centre line, the imported thresholds, the columns
  of their scores, the ``distance`` baseline;
* ``blade_widths``: this analyzer (300 expansions, seed 0, ``--continuation 0 --capture-gate
  none``, ``evaluate --weights uniform --success-frames 10``) on their 200 scooping frames with
  this task's **scripted** gripper motion instead of their recorded one, per blade half width.
  The import as it is (their recorded motion) is measured by ``table_one_reference.py``.

Every set and analysis stays under ``--work`` (a rerun resumes). Without ``../shared`` it prints one
``skip:`` line and exits 0.

    python benchmarks/reference_import.py --work runs/reference-import --out docs/figures/reference_import.json
"""

from __future__ import annotations

import csv
import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.data import reference_convert
from energy_margin.data.dataset import Dataset, load_dataset
from energy_margin.data.dataset_files import write_directory
from energy_margin.data.reference import read_reference
from energy_margin.data.scores_file import SCORES_FILE
from energy_margin.runs.versions import engine_versions
from energy_margin.tasks import PushingTask, ScoopingTask, Task, get_task
from energy_margin.tasks.pushing_config import PushingConfig
from energy_margin.tasks.scooping_config import ScoopingConfig
from energy_margin.tasks.scooping_script import script_targets
from engine_versions import REFERENCE_DATA
from results_document import document_head, energy_margin, work_arguments, write_document

__all__ = [
    "ANALYZE",
    "BLADE_HALF_WIDTHS",
    "FOLDERS",
    "PROTOCOL",
    "agreement",
    "base_accelerations",
    "blade_row",
    "capture_scores_at",
    "constants",
    "farthest_offset",
    "height_label",
    "scripted_config",
    "with_blades",
]

FOLDERS = {"pushing": "planepush-10objects", "scooping": "gripper-5objects"}
#: Their Table I protocol, as ``evaluate`` options (``--json``, no bootstrap).
PROTOCOL = ("--weights", "uniform", "--success-frames", "10", "--json", "--resamples", "0")
#: The analysis of the blade-width rows: that of ``table_one_reference.py`` (300 expansions, seed 0,
#: the tree's own success, ungated capture), one worker.
ANALYZE = ("--expansions", "300", "--seed", "0", "--continuation", "0", "--capture-gate", "none", "--no-progress")
#: Facts of the authors' files, carried over (not code): their URDF's tip inertia gives a blade about
#: 4.4 cm long along the hinge axis, i.e. this half width (m) (the mesh is not in their repository's text).
THEIR_URDF_BLADE_HALF_WIDTH = 0.022
#: Their scripted push (``pomp/bullet/scriptedmovement.py``): a force of mu_b / 0.3 * U(7, 11) N per step.
THEIR_PUSH_FORCE_RANGE = (7.0, 11.0)
THEIR_PUSH_FRICTION_REFERENCE = 0.3
#: Blade half widths (m) of the scripted-motion rows: the task's default, their URDF's, between, the import's.
BLADE_HALF_WIDTHS = (
    ScoopingConfig().tip_half_width,
    THEIR_URDF_BLADE_HALF_WIDTH,
    0.025,
    reference_convert.SCOOP_BLADE_HALF_WIDTH,
)


def constants() -> dict[str, Any]:
    """What the code holds (no data needed): the import's constants and the task settings the page quotes."""
    imported = {
        name: value
        for name, value in vars(reference_convert).items()
        if name.isupper() and isinstance(value, (int, float)) and not isinstance(value, bool)
    }
    scooping = ScoopingTask()
    band = get_task("pushing").success_region()
    first = reference_convert.SCOOP_FIRST_FRAME
    finger = script_targets(scooping.config, scooping.contact_height, scooping.closed_travel, first)[1]
    return {
        "reference_convert": imported,
        # Their box centre resting on their table top, in their (10x) units.
        "scoop_rest_sim": reference_convert.SCOOP_TABLE_TOP
        + scooping.config.box_half_edge * reference_convert.SCOOP_SCALE,
        "drive_factor_mean": float(np.mean(PushingConfig().drive_factor)),
        "push_success_band": [float(band.low), float(band.high)],
        "scoop_script_finger_at_first_frame_cm": 100.0 * float(finger),
        "scoop_closed_travel_cm": 100.0 * scooping.closed_travel,
        "their_urdf_blade_half_width_m": THEIR_URDF_BLADE_HALF_WIDTH,
        "their_urdf_blade_half_width_cm": 100.0 * THEIR_URDF_BLADE_HALF_WIDTH,
        "their_urdf_blade_length_cm": 200.0 * THEIR_URDF_BLADE_HALF_WIDTH,
        "scoop_blade_half_width_cm": 100.0 * reference_convert.SCOOP_BLADE_HALF_WIDTH,
        "blade_half_widths": [float(width) for width in BLADE_HALF_WIDTHS],
    }


def agreement(ours: np.ndarray, theirs: np.ndarray) -> dict[str, int]:
    """How many labels agree, and each side's positives (two boolean arrays of one shape)."""
    ours, theirs = np.asarray(ours, dtype=bool), np.asarray(theirs, dtype=bool)
    return {
        "count": int(ours.size),
        "agree": int(np.sum(ours == theirs)),
        "ours_positive": int(ours.sum()),
        "theirs_positive": int(theirs.sum()),
        "ours_only": int(np.sum(ours & ~theirs)),
        "theirs_only": int(np.sum(theirs & ~ours)),
    }


def farthest_offset(object_pos: np.ndarray, captured: np.ndarray) -> float:
    """The largest |y| (off the centre line y = 0) of any object in a captured frame, m.

    ``object_pos`` (T, K, n, 3), ``captured`` (T, K); 0 when no frame is captured.
    """
    offsets = np.abs(np.asarray(object_pos)[np.asarray(captured, dtype=bool)][..., 1])
    return float(offsets.max()) if offsets.size else 0.0


def base_accelerations(times: np.ndarray, heights: np.ndarray) -> np.ndarray:
    """Per trajectory, the constant acceleration of a quadratic fit of height against time, (T,)."""
    return np.array([2.0 * np.polyfit(t, z, 2)[0] for t, z in zip(np.asarray(times), np.asarray(heights), strict=True)])


def with_blades(task_config: dict[str, Any], width: float) -> dict[str, Any]:
    """``task_config`` with its blades and finger plates ``width`` half wide (m), as the import widens them."""
    plates = list(task_config["finger_half_extents"])
    plates[1] = width
    return {**task_config, "tip_half_width": width, "finger_half_extents": plates}


def height_label(object_pos: np.ndarray, object_vel: np.ndarray, rest: float, margin: float, fall: float) -> np.ndarray:
    """Their capture test in SI: every object ``margin`` above ``rest`` and not sinking faster than ``fall``."""
    return np.all((object_pos[..., 2] > rest + margin) & (object_vel[..., 2] > -fall), axis=-1)


def scripted_config(task_config: dict[str, Any], width: float) -> dict[str, Any]:
    """:func:`with_blades` and the task's scripted gripper motion instead of a recorded one."""
    return {**with_blades(task_config, width), "recorded_waypoints": 0}


def blade_row(width: float, motion: str, evaluated: dict[str, Any]) -> dict[str, Any]:
    """One row of the blade-width table from ``evaluate --json``."""
    keys = ("capture_ap", "capture_ap_window2", "success_ap", "success_ap_first_half", "runtime_per_frame_s")
    return {"blade_half_width_m": width, "motion": motion, **{key: evaluated[key] for key in keys}}


def _evaluated(path: Path) -> dict[str, Any]:
    """``evaluate PATH`` under their Table I protocol, as JSON."""
    found = json.loads(energy_margin("evaluate", str(path), *PROTOCOL))
    assert isinstance(found, dict)
    return found


def _imported(task: str, out: Path, *arguments: str) -> Dataset:
    """``import-reference`` of their ``task`` folder into ``out`` (kept when already there)."""
    if not (out / "frames.npz").exists():
        energy_margin(
            "import-reference", str(REFERENCE_DATA / FOLDERS[task]), "--out", str(out), "--overwrite", *arguments
        )
    return load_dataset(out)


def _only(values: np.ndarray) -> float:
    """The one value of an array that holds a single value repeated."""
    found = np.unique(np.asarray(values, dtype=float))
    assert found.size == 1, found
    return float(found[0])


def _labels(dataset: Dataset, task: Task) -> tuple[np.ndarray, np.ndarray]:
    """``task``'s capture label of every frame (T, K) and success label of every last frame (T,)."""
    frames = [[dataset.frame(t, k) for k in range(dataset.n_frames)] for t in range(dataset.n_trajectories)]
    captured = np.array([[task.is_captured(frame) for frame in row] for row in frames])
    return captured, np.array([task.is_successful(row[-1]) for row in frames])


def pushing(work: Path) -> dict[str, Any]:
    """Their pushing frames imported: friction, drive, this project's regions against their labels."""
    dataset = _imported("pushing", work / "push10-theirs")
    ref = read_reference(REFERENCE_DATA / FOLDERS["pushing"], with_scores=False)
    assert isinstance(dataset.task, PushingTask)
    per_body = _only(ref.friction_per_body)
    captured, success = _labels(dataset, dataset.task)
    scale = per_body / THEIR_PUSH_FRICTION_REFERENCE
    times = dataset.arrays["frame_time"]
    return {
        "friction_per_body": per_body,
        "friction": _only(dataset.arrays["friction"]),
        "drive_force_n": _only(dataset.arrays["drive"][:, 1]),
        "their_push_force_n": {"low": scale * THEIR_PUSH_FORCE_RANGE[0], "high": scale * THEIR_PUSH_FORCE_RANGE[1]},
        "their_push_force_mean_n": scale * float(np.mean(THEIR_PUSH_FORCE_RANGE)),
        "frame_times_s": [float(v) for v in times[0]],
        "last_frame_s": float(times[0, -1]),
        "capture_agreement": agreement(captured, ref.capture_label),
        "success_agreement": agreement(success, ref.success_label),
        "current_state_success_ap": _evaluated(dataset.path)["baselines"]["current_state"]["success_ap"],
        "their_scores": _their_scores(dataset.path),
    }


def _their_scores(path: Path) -> dict[str, float]:
    """The single value of each constant column of an imported ``scores.csv``."""
    with (path / SCORES_FILE).open(encoding="utf-8") as file:
        rows = list(csv.DictReader(file))
    columns = ("nodes", "expansions", "physics_s", "seed")
    return {column: _only(np.array([float(row[column]) for row in rows])) for column in columns}


def scooping(work: Path) -> dict[str, Any]:
    """Their scooping frames imported: heights, base motion, capture region per blade width, thresholds."""
    dataset = _imported("scooping", work / "scoop5-theirs")
    ref = read_reference(REFERENCE_DATA / FOLDERS["scooping"], with_scores=False)
    config = dict(dataset.metadata["task_config"])
    narrow = get_task(dataset.metadata["task"], with_blades(config, ScoopingConfig().tip_half_width))
    captured, _ = _labels(dataset, dataset.task)
    captured_narrow, _ = _labels(dataset, narrow)
    task = dataset.task
    assert isinstance(task, ScoopingTask)
    arrays = dataset.arrays
    own = height_label(
        arrays["object_pos"], arrays["object_vel"], task.rest_height, task.config.capture_margin, task.config.fall_speed
    )
    n_objects = dataset.n_objects
    boxes = ref.states[..., : 12 * n_objects].reshape(*ref.states.shape[:2], n_objects, 12)
    rejected = ref.capture_label & ~captured_narrow
    accelerations = base_accelerations(dataset.arrays["frame_time"], dataset.arrays["robot_q"][..., 0])
    baselines = _evaluated(dataset.path)["baselines"]
    times = dataset.arrays["frame_time"][0]
    offset = farthest_offset(dataset.arrays["object_pos"], ref.capture_label)
    return {
        "highest_box_sim": float(boxes[..., 2].max()),
        "base_acceleration_m_s2": {"min": float(accelerations.min()), "max": float(accelerations.max())},
        "height_label_agreement": agreement(own, ref.capture_label),
        "capture_agreement": agreement(captured, ref.capture_label),
        "capture_agreement_default_blades": agreement(captured_narrow, ref.capture_label),
        "rejected_trajectories": [int(t) for t in np.flatnonzero(rejected.any(axis=1))],
        "rejected_frames": [[int(t), int(k)] for t, k in np.argwhere(rejected)],
        "farthest_captured_offset_m": offset,
        "farthest_captured_offset_cm": 100.0 * offset,
        "tip_half_width": config["tip_half_width"],
        "recorded_waypoints": config["recorded_waypoints"],
        "imported_drive": dataset.metadata["imported_drive"],
        "success_height": config["success_height"],
        "capture_margin": config["capture_margin"],
        "capture_margin_mm": 1000.0 * config["capture_margin"],
        "fall_speed": config["fall_speed"],
        "frame_times_s": [float(v) for v in times],
        "second_frame_s": float(times[1]),
        "last_frame_s": float(times[-1]),
        "their_scores": _their_scores(dataset.path),
        "current_state_success_ap": baselines["current_state"]["success_ap"],
        "distance_baseline": {key: baselines["distance"][key] for key in ("capture_ap", "capture_ap_window2")},
    }


def _scripted(source: Path, out: Path, width: float) -> Path:
    """A copy of the imported set ``source`` with the task's scripted motion and blades ``width`` (kept if there)."""
    if (out / "frames.npz").exists():
        return out
    dataset = load_dataset(source)
    metadata, arrays = dict(dataset.metadata), dict(dataset.arrays)
    task = get_task(metadata["task"], scripted_config(metadata["task_config"], width))
    metadata["task_config"] = task.config.to_dict()
    # The script's drive is the finger stiffness alone, without the recorded waypoints.
    arrays["drive"] = np.ascontiguousarray(arrays["drive"][:, :1])
    metadata["n_drive"] = 1
    metadata["imported_drive"] = "script"
    write_directory(out, metadata, arrays, overwrite=True)
    return out


def capture_scores_at(path: Path, frames: list[list[int]]) -> list[float]:
    """The capture scores of ``frames`` ([trajectory, frame] pairs) in the ``scores.csv`` of ``path``."""
    with (path / SCORES_FILE).open(encoding="utf-8") as file:
        scores = {
            (int(row["trajectory"]), int(row["frame"])): float(row["capture_score"]) for row in csv.DictReader(file)
        }
    return [scores[(t, k)] for t, k in frames]


def blade_widths(work: Path, workers: int, rejected: list[list[int]]) -> list[dict[str, Any]]:
    """This analyzer on their true scooping frames with the scripted motion, per blade half width.

    ``rejected``: their captured frames that this task's default blades do not carry; the row of
    those blades also gives these frames' highest capture score.
    """
    source = work / "scoop5"
    _imported("scooping", source, "--no-scores")
    rows = []
    for width in BLADE_HALF_WIDTHS:
        path = _scripted(source, work / f"script-{width:.3f}", width)
        started = time.perf_counter()
        energy_margin("analyze", str(path), *ANALYZE, "--workers", str(workers))
        rows.append(blade_row(width, "script", _evaluated(path)))
        if width == ScoopingConfig().tip_half_width and rejected:
            rows[-1]["rejected_capture_score_max"] = max(capture_scores_at(path, rejected))
        print(f"blade half width {width:.3f} m, script: {rows[-1]} ({time.perf_counter() - started:.0f} s)", flush=True)
    return rows


def main() -> None:
    parser = work_arguments(__doc__)
    args = parser.parse_args()
    if not REFERENCE_DATA.is_dir():
        print(f"skip: the authors' data is not at {REFERENCE_DATA}")
        return
    started = time.perf_counter()
    args.work.mkdir(parents=True, exist_ok=True)
    document = {
        **document_head("reference_import.py"),
        "versions": engine_versions(),
        "analyze": [*ANALYZE, "--workers", str(args.workers)],
        "protocol": list(PROTOCOL),
        "constants": constants(),
        "pushing": pushing(args.work),
        "scooping": scooping(args.work),
    }
    document["blade_widths"] = blade_widths(args.work, args.workers, document["scooping"]["rejected_frames"])
    document["wall_s"] = round(time.perf_counter() - started, 1)
    write_document(args.out, document)
    print(json.dumps({key: document[key] for key in ("pushing", "scooping")}, indent=1)[:4000])


if __name__ == "__main__":
    main()
