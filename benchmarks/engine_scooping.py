"""Scooping in MuJoCo and in PyBullet: what each engine's roll-outs lift, and one frame's analysis time.

A smoke comparison of the two engines on the scooping task at its defaults (5 boxes): the same
generation seed in each engine (``generate --task scooping --objects 5 --trajectories 4 --frames 5
--seed 0 --engine E``), then, per engine, the boxes whose centre ends at least ``success_height``
above resting on the table (lifted), their heights above the table top, the successful
trajectories, and the time to analyse each trajectory's middle frame with 300 expansions (the
tree's own success, one process). The roll-outs of a scoop are chaotic: trajectory by trajectory
the engines' outcomes differ, so the counts, not the trajectories, are compared.

    python benchmarks/engine_scooping.py --work runs/engine-scooping --out docs/figures/engine_scooping.json

Without PyBullet it prints one ``skip:`` line.
"""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.analysis.frame import AnalyzerConfig, FrameAnalyzer
from energy_margin.data.dataset import Dataset
from energy_margin.data.generate import generate_dataset
from energy_margin.runs.versions import engine_versions
from results_document import document_head, work_arguments, write_document

__all__ = ["lifted"]

ENGINES = ("mujoco", "pybullet")
SIZE = {"n_objects": 5, "n_trajectories": 4, "n_frames": 5, "seed": 0}
EXPANSIONS = 300


def lifted(heights: np.ndarray, *, resting: float, success_height: float) -> np.ndarray:
    """Which boxes are lifted: centre at least ``success_height`` above ``resting``.

    Args:
        heights: centre heights of the boxes, m, any shape.
        resting: centre height of a box resting on the table, m.
        success_height: how far above resting a lifted box is, m.
    """
    return np.asarray(heights) >= resting + success_height


def _generated(work: Path, engine: str) -> Dataset:
    """``generate --task scooping ... --engine E``, generated anew on every run (its outcomes are measured)."""
    out = work / f"scoop-{engine}"
    return generate_dataset("scooping", out=out, engine=engine, overwrite=True, **SIZE)


def _outcomes(dataset: Dataset) -> dict[str, Any]:
    """Lifted boxes at the last frame, their heights above the table top, successful trajectories."""
    config = dataset.task.config
    resting = config.table_top + config.box_half_edge
    heights = dataset.arrays["object_pos"][:, -1, :, 2]
    up = lifted(heights, resting=resting, success_height=config.success_height)
    above_table = heights[up] - config.table_top
    return {
        "boxes": int(heights.size),
        "lifted": int(up.sum()),
        "lifted_height_min_cm": float(100 * above_table.min()) if up.any() else None,
        "lifted_height_max_cm": float(100 * above_table.max()) if up.any() else None,
        "successful_trajectories": int(np.sum(dataset.arrays["in_success"][:, -1])),
        "trajectories": int(dataset.n_trajectories),
    }


def _analysis_times(dataset: Dataset, engine: str) -> list[float]:
    """Wall time [s] of each trajectory's middle frame, 300 expansions, the tree's own success.

    Each frame as ``analyze --seed 0`` scores it (:class:`FrameAnalyzer`: its per-frame seed, one
    simulator per roll-out).
    """
    analyzer = FrameAnalyzer(
        dataset, AnalyzerConfig(engine=engine, expansions=EXPANSIONS, continuation=0, capture_gate="none"), seed=0
    )
    middles = [trajectory * dataset.n_frames + dataset.n_frames // 2 for trajectory in range(dataset.n_trajectories)]
    return [analyzer(index)["runtime_s"] for index in middles]


def main() -> None:
    parser = work_arguments(__doc__, workers=False, work_help="where the generated sets go")
    args = parser.parse_args()
    if importlib.util.find_spec("pybullet") is None:
        print("skip: PyBullet is not installed (pip install 'energy-margin[pybullet]')")
        return
    engines: dict[str, Any] = {}
    for engine in ENGINES:
        dataset = _generated(args.work, engine)
        times = _analysis_times(dataset, engine)
        engines[engine] = {
            **_outcomes(dataset),
            "frame_s": times,
            "frame_s_min": min(times),
            "frame_s_max": max(times),
        }
        print(f"{engine}: {json.dumps(engines[engine])}", flush=True)
    figures = {
        **document_head("engine_scooping.py"),
        "versions": {**engine_versions(), **engine_versions("pybullet")},
        "size": SIZE,
        "expansions": EXPANSIONS,
        "engines": engines,
    }
    write_document(args.out, figures)


if __name__ == "__main__":
    main()
