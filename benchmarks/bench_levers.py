"""Levers on the cost of a frame, paired on the authors' frames: docs/results/performance.md's "Levers examined".

For every frame (every ``--every``-th of their 10-object pushing set, 300 expansions, seed 0, the
tree's own success), each variant of :data:`VARIANTS` analyses it one after the other in this one
process; the time is the thread's CPU time (so another job on the machine slows every variant
alike). A variant changes a task setting (the contact model, the time step), an ``AnalyzerConfig``
field, or one MuJoCo option of the analysis model (``model.opt``). Per variant: its CPU time per
frame against the default's (ratio of the means), the mean expansions, and how far its capture and
success scores move from the default's (largest and mean absolute change).

    python benchmarks/bench_levers.py --out docs/figures/bench_levers.json [--every 11] [--variants NAME ...]

Without ``../shared`` it prints one ``skip:`` line.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import mujoco

from bench_analysis import machine
from energy_margin import AnalyzerConfig, analyze_frame
from energy_margin.analysis.frame import frame_seeds
from energy_margin.data.reference import import_reference
from energy_margin.runs.versions import engine_versions
from energy_margin.sim import make_simulator
from energy_margin.tasks import get_task, with_contacts
from engine_versions import REFERENCE_DATA
from results_document import write_document

__all__ = ["VARIANTS", "Variant", "summarise"]

FRAMES = REFERENCE_DATA / "planepush-10objects"


@dataclass(frozen=True)
class Variant:
    """One lever: task settings, analyzer fields and MuJoCo options (``model.opt`` attribute: value)."""

    title: str
    task: dict[str, Any] = field(default_factory=dict)
    analyzer: dict[str, Any] = field(default_factory=dict)
    options: dict[str, Any] = field(default_factory=dict)


VARIANTS: dict[str, Variant] = {
    "default": Variant("default (rim contacts, 300 expansions)"),
    "footprint": Variant("`--set ground_contact='\"footprint\"'`", task={"ground_contact": "footprint"}),
    "sphere": Variant("`--set lateral_contact='\"sphere\"'` (sphere stand-ins)", task={"lateral_contact": "sphere"}),
    "fast": Variant("`--contacts fast` (footprints and spheres)", analyzer={"contacts": "fast"}),
    "converge_0.03": Variant("`--converge 0.03`", analyzer={"converge": 0.03}),
    "timestep_60": Variant("time step 1/60 s", task={"timestep": 1 / 60}),
    "sparse": Variant("MuJoCo `jacobian` sparse", options={"jacobian": mujoco.mjtJacobian.mjJAC_SPARSE}),
    "tolerance": Variant("MuJoCo `tolerance` 1e-5", options={"tolerance": 1e-5}),
    "ls_iterations": Variant("MuJoCo `ls_iterations` 10", options={"ls_iterations": 10}),
    "cg": Variant("MuJoCo CG solver", options={"solver": mujoco.mjtSolver.mjSOL_CG}),
    "pgs": Variant("MuJoCo PGS solver", options={"solver": mujoco.mjtSolver.mjSOL_PGS}),
}


def summarise(rows: dict[str, list[dict[str, float]]]) -> list[dict[str, Any]]:
    """Per variant: CPU per frame, its ratio to ``default``'s, mean expansions, score changes from ``default``."""
    base = rows["default"]
    base_cpu = statistics.fmean(row["cpu_s"] for row in base)
    summary = []
    for name, found in rows.items():
        capture = [abs(row["capture"] - other["capture"]) for row, other in zip(found, base, strict=True)]
        success = [abs(row["success"] - other["success"]) for row, other in zip(found, base, strict=True)]
        cpu = statistics.fmean(row["cpu_s"] for row in found)
        summary.append({
            "name": name, "title": VARIANTS[name].title, "cpu_s": cpu, "ratio": cpu / base_cpu,
            "expansions": statistics.fmean(row["expansions"] for row in found),
            "capture_change_max": max(capture), "capture_change_mean": statistics.fmean(capture),
            "success_change_max": max(success), "success_change_mean": statistics.fmean(success),
        })  # fmt: skip
    return summary


def _analyse(variant: Variant, dataset: Any, index: int, seed: Any) -> dict[str, float]:
    trajectory, frame = divmod(index, dataset.n_frames)
    task = get_task("pushing", {**dataset.task.config.to_dict(), **variant.task})
    config = AnalyzerConfig(expansions=300, **variant.analyzer)
    friction = float(dataset.arrays["friction"][trajectory])
    drive = dataset.arrays["drive"][trajectory]
    simulator = make_simulator(with_contacts(task, config.contacts).build_scene(dataset.n_objects, friction, drive))
    for option, value in variant.options.items():
        setattr(simulator.model.opt, option, value)  # type: ignore[attr-defined]
    started = time.thread_time()
    scores, _ = analyze_frame(
        task, dataset.frame(trajectory, frame), friction=friction, drive=drive, seed=seed, config=config,
        start_time=float(dataset.arrays["frame_time"][trajectory, frame]), simulator=simulator,
    )  # fmt: skip
    return {
        "frame": index, "cpu_s": time.thread_time() - started, "expansions": scores.expansions,
        "capture": scores.capture_score, "success": scores.success_score,
    }  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n", 1)[0])
    parser.add_argument("--out", type=Path, required=True, help="the JSON file to write")
    parser.add_argument("--every", type=int, default=11, help="every N-th of their 200 frames (default 11)")
    parser.add_argument("--variants", nargs="+", choices=list(VARIANTS), default=list(VARIANTS))
    args = parser.parse_args()
    if not FRAMES.is_dir():
        print(f"skip: the authors' frames are not at {FRAMES}")
        sys.exit(0)
    names = ["default", *(name for name in args.variants if name != "default")]
    scratch = Path(tempfile.mkdtemp(prefix="bench-levers-"))
    load_before = os.getloadavg()[0]
    try:
        dataset = import_reference(FRAMES, scratch / "frames", with_scores=False)
        total = dataset.n_trajectories * dataset.n_frames
        seeds = frame_seeds(0, total)
        rows: dict[str, list[dict[str, float]]] = {name: [] for name in names}
        for index in range(0, total, args.every):
            for name in names:
                rows[name].append(_analyse(VARIANTS[name], dataset, index, seeds[index]))
            print(f"frame {index}: " + ", ".join(f"{name} {rows[name][-1]['cpu_s']:.3f} s" for name in names))
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    summary = summarise(rows)
    print("| variant | CPU per frame | ratio | expansions | max |Δ capture| | max |Δ success| |")
    for row in summary:
        print(
            f"| {row['title']} | {row['cpu_s']:.3f} s | {row['ratio']:.2f}× | {row['expansions']:.0f} "
            f"| {row['capture_change_max']:.3f} | {row['success_change_max']:.3f} |"
        )
    write_document(args.out, {
        "command": "python benchmarks/bench_levers.py --out FILE",
        "machine": machine(), "versions": engine_versions(), "load_before": load_before,
        "load_after": os.getloadavg()[0], "every": args.every, "frames": len(rows["default"]),
        "summary": summary, "rows": rows,
    })  # fmt: skip


if __name__ == "__main__":
    main()
