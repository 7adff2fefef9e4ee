"""The authors' frames in both engines: AP against their labels and agreement frame by frame.

Their 10-object pushing frames and their 5-box scooping frames (``../shared/reference``) are
imported without their scores, once per run, and analysed with MuJoCo and with PyBullet (the
tree's own success, ``--continuation 0``, as the authors' planner scores; two workers), then
evaluated with their Table I protocol (``--weights uniform --success-frames 10``):

* pushing, 300 expansions: PyBullet with this project's nominal push and with the pusher
  coasting (``import-reference --drive coast``), analysis seeds 0 and 1; MuJoCo at their time
  step of 1/240 s (the imported task's ``timestep``; the project's is 1/120 s), seed 0; and MuJoCo
  at 1/120 s, seed 0, the side the frame-by-frame agreement is measured against;
* scooping, 30 expansions, seed 0, both engines: AP and agreement.

Agreement of two analyses of the same frames with the same seeds: Pearson and Spearman
correlation of the frame scores, frames scoring exactly 0 in both, mean and largest absolute
difference, frames on the same side of 0.5, and for success the trajectories' scores (uniform
mean of their frames). Every analysis resumes from ``--work``.

    python benchmarks/engine_parity.py --work runs/engine-parity --out docs/figures/engine_parity.json

Without ``../shared`` it prints one ``skip:`` line; without PyBullet, one ``skip:`` line too.
"""

from __future__ import annotations

import importlib.util
import json
import time
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats

from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.run import analyze
from energy_margin.data.reference import import_reference
from energy_margin.data.scores_file import load_scores
from energy_margin.runs.versions import engine_versions
from engine_versions import REFERENCE_DATA
from results_document import document_head, work_arguments, write_document
from table_one_reference import PROTOCOL, protocol_row

__all__ = ["agreement"]

FOLDERS = {"pushing": "planepush-10objects", "scooping": "gripper-5objects"}
EXPANSIONS = {"pushing": 300, "scooping": 30}
#: Their simulation's time step [s] (the project's pushing task steps at 1/120 s).
THEIR_TIMESTEP = 1.0 / 240.0
#: (engine, drive, analysis seed, time step or None for the imported task's) of the pushing rows.
PUSHING_RUNS = (
    ("mujoco", "nominal", 0, None),
    ("mujoco", "nominal", 0, THEIR_TIMESTEP),
    ("pybullet", "nominal", 0, None),
    ("pybullet", "nominal", 1, None),
    ("pybullet", "coast", 0, None),
    ("pybullet", "coast", 1, None),
)


def _imported(task: str, out: Path, *, drive: str = "nominal", timestep: float | None = None) -> Path:
    """The authors' frames of ``task`` as a dataset without their scores (resumed when there).

    With ``timestep``, the imported task's time step is set to it in ``dataset.json`` (the task
    configuration the analysis builds its scene from).
    """
    if not (out / "frames.npz").exists():
        import_reference(REFERENCE_DATA / FOLDERS[task], out, with_scores=False, drive=drive, overwrite=True)
        if timestep is not None:
            meta_path = out / "dataset.json"
            meta = json.loads(meta_path.read_text(encoding="utf-8"))
            meta["task_config"]["timestep"] = timestep
            meta_path.write_text(json.dumps(meta, indent=1, sort_keys=True) + "\n", encoding="utf-8")
    return out


def _analysed(path: Path, *, engine: str, expansions: int, seed: int, workers: int) -> Path:
    """``analyze PATH --engine E --expansions N --seed S --continuation 0`` (resumes)."""
    config = AnalyzerConfig(engine=engine, expansions=expansions, continuation=0, capture_gate="none")
    analyze(path, config, seed=seed, workers=workers, progress=False)
    return path


def _grid(scores: dict[str, np.ndarray], column: str) -> np.ndarray:
    """One score column as (trajectories, frames), from the rows of ``scores.csv``."""
    trajectories, frames = scores["trajectory"].astype(int), scores["frame"].astype(int)
    grid = np.full((trajectories.max() + 1, frames.max() + 1), np.nan)
    grid[trajectories, frames] = scores[column]
    return grid


def agreement(first: np.ndarray, second: np.ndarray) -> dict[str, float | int]:
    """How two analyses' scores of the same frames agree.

    Args:
        first: scores, shape (n_trajectories, n_frames), in [0, 1].
        second: the other analysis's scores of the same frames, same shape.

    Returns:
        Pearson and Spearman correlation of the frames, frames exactly 0 in both, mean and largest
        absolute difference, frames on the same side of 0.5, the frame count, and the Pearson and
        Spearman correlation of the trajectories' uniform means.
    """
    a, b = first.ravel(), second.ravel()
    means_a, means_b = first.mean(axis=1), second.mean(axis=1)
    difference = np.abs(a - b)
    return {
        "frames": int(a.size),
        "pearson": float(stats.pearsonr(a, b).statistic),
        "spearman": float(stats.spearmanr(a, b).statistic),
        "zero_in_both": int(np.sum((a == 0.0) & (b == 0.0))),
        "mean_abs_difference": float(difference.mean()),
        "max_abs_difference": float(difference.max()),
        "same_side_of_half": int(np.sum((a >= 0.5) == (b >= 0.5))),
        "trajectory_pearson": float(stats.pearsonr(means_a, means_b).statistic),
        "trajectory_spearman": float(stats.spearmanr(means_a, means_b).statistic),
    }


def _agreements(first: Path, second: Path) -> dict[str, Any]:
    """Capture and success agreement of two analysed copies of the same frames."""
    one, other = load_scores(first), load_scores(second)
    return {
        score: agreement(_grid(one, f"{score}_score"), _grid(other, f"{score}_score"))
        for score in ("capture", "success")
    }


def pushing(work: Path, workers: int) -> dict[str, Any]:
    """Every pushing run of ``PUSHING_RUNS``, and PyBullet's agreement with MuJoCo at seed 0."""
    runs: list[dict[str, Any]] = []
    paths: dict[tuple[str, str, int, float | None], Path] = {}
    for engine, drive, seed, timestep in PUSHING_RUNS:
        step = "" if timestep is None else f"-dt{round(1 / timestep)}"
        path = _imported("pushing", work / f"push10-{engine}-{drive}-seed{seed}{step}", drive=drive, timestep=timestep)
        _analysed(path, engine=engine, expansions=EXPANSIONS["pushing"], seed=seed, workers=workers)
        paths[engine, drive, seed, timestep] = path
        meta = json.loads((path / "dataset.json").read_text(encoding="utf-8"))
        dt = meta["task_config"]["timestep"]
        runs.append({"engine": engine, "drive": drive, "seed": seed, "timestep_s": dt, **protocol_row(path)})
        print(f"pushing, {engine} {drive} seed {seed}, time step 1/{round(1 / dt)} s: done", flush=True)
    agreed = _agreements(paths["mujoco", "nominal", 0, None], paths["pybullet", "nominal", 0, None])
    return {"expansions": EXPANSIONS["pushing"], "runs": runs, "agreement": agreed}


def scooping(work: Path, workers: int) -> dict[str, Any]:
    """Their scooping frames in both engines, seed 0: AP, time per frame and agreement."""
    paths = {}
    rows = {}
    for engine in ("mujoco", "pybullet"):
        path = _imported("scooping", work / f"scoop5-{engine}")
        paths[engine] = _analysed(path, engine=engine, expansions=EXPANSIONS["scooping"], seed=0, workers=workers)
        rows[engine] = protocol_row(path)
        print(f"scooping, {engine}: done", flush=True)
    mujoco, pybullet = rows["mujoco"]["runtime_per_frame_s"], rows["pybullet"]["runtime_per_frame_s"]
    return {
        "expansions": EXPANSIONS["scooping"],
        "engines": rows,
        "ratio_pybullet_mujoco": pybullet / mujoco,
        "agreement": _agreements(paths["mujoco"], paths["pybullet"]),
    }


def main() -> None:
    parser = work_arguments(__doc__)
    parser.add_argument("--tasks", nargs="+", choices=tuple(FOLDERS), default=list(FOLDERS))
    args = parser.parse_args()
    if not REFERENCE_DATA.is_dir():
        print(f"skip: the authors' data is not at {REFERENCE_DATA}")
        return
    if importlib.util.find_spec("pybullet") is None:
        print("skip: PyBullet is not installed (pip install 'energy-margin[pybullet]')")
        return
    started = time.perf_counter()
    measure = {"pushing": pushing, "scooping": scooping}
    found = {task: measure[task](args.work, args.workers) for task in args.tasks}
    figures = {
        **document_head("engine_parity.py"),
        "versions": {**engine_versions(), **engine_versions("pybullet")},
        "protocol": PROTOCOL,
        "workers": args.workers,
        "wall_s": round(time.perf_counter() - started, 1),
        **found,
    }
    write_document(args.out, figures)
    print(json.dumps(found, indent=1)[:4000])


if __name__ == "__main__":
    main()
