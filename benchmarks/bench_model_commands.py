"""Seconds per frame of a scene's analysis with its motion commanded in batches against row by row.

Usage::

    python benchmarks/bench_model_commands.py [--scenes examples/*/*.toml] [--datasets DIR ...]
        [--trajectories 2] [--frames 4] [--expansions 300] [--seed 100] [--out FILE]

A scene file's robot moves by model commands (its motion's controls and mocap poses). Batched
propagations (a continuation of the motion from a tree's nodes, a batched tree's rounds) take one
command per control period of every row; they were evaluated one row and one period at a time
(``SceneTask.model_command``), and are now evaluated for every row at once
(``SceneTask.batched_model_command``, the same numbers to the last bit). For each scene file a small
dataset is generated (``--trajectories`` x ``--frames``, generation seed ``--seed``); of each
``--datasets`` folder (a recorded one, e.g. a stack example's ``OUT/dataset``) the first
``--trajectories`` roll-outs are used, with ``--frames`` frames spread over each.
Every frame is analysed twice in this one process at ``analyze``'s defaults (the motion continued:
16 draws) with ``--expansions``, alternating frame by frame (so both sides see the same machine
state): row by row ("before") and in batches ("after"), then once more with the tree's own success
score alone (``--continuation 0``: what the continuation adds). It prints per scene the seconds
per frame of each side (the whole call's wall time), their ratio, how many frames scored the same
to the last bit, and the tree alone. Examples whose model is written from another package's assets
are skipped (one ``skip:`` line) until their ``write_model.py`` has run.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import os
import statistics
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.analysis.continuation_rule import default_continuation
from energy_margin.analysis.frame import AnalyzerConfig, analyze_frame, frame_seeds
from energy_margin.data.dataset import Dataset, load_dataset
from energy_margin.data.generate import generate_dataset
from energy_margin.errors import EnergyMarginError
from energy_margin.tasks import get_task
from energy_margin.tasks.scene_task import SceneTask

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_analysis import machine as describe_machine  # the machine line of the other benchmarks

__all__: list[str] = []

ROOT = Path(__file__).resolve().parents[1]
SCENES = sorted(str(path.relative_to(ROOT)) for path in ROOT.glob("examples/*/*.toml"))
SIDES = ("before", "after")


@contextlib.contextmanager
def _row_by_row() -> Iterator[None]:
    """Scene tasks without their batched command while inside: the propagator's path before."""
    batched = SceneTask.batched_model_command
    SceneTask.batched_model_command = lambda self, drives, times: None  # type: ignore[method-assign]
    try:
        yield
    finally:
        SceneTask.batched_model_command = batched  # type: ignore[method-assign]


def _places(dataset: Dataset, args: argparse.Namespace) -> list[tuple[int, list[int]]]:
    """The first ``--trajectories`` roll-outs, each with ``--frames`` frames spread over it (all, if fewer)."""
    frames = np.unique(np.linspace(0, dataset.n_frames - 1, min(args.frames, dataset.n_frames)).round().astype(int))
    return [(t, frames.tolist()) for t in range(min(args.trajectories, dataset.n_trajectories))]


def _timed(
    dataset: Dataset, t: int, k: int, seed: int, simulator: Any, config: AnalyzerConfig
) -> tuple[tuple[float, float], float]:
    """Frame ``k`` of roll-out ``t`` analysed with ``config``: its capture and success scores and the call's seconds.

    The roll-out's simulator is built beforehand and shared by every call, so no side pays for building it.
    """
    started = time.perf_counter()
    result, _ = analyze_frame(
        dataset.task,
        dataset.frame(t, k),
        friction=float(dataset.arrays["friction"][t]),
        drive=dataset.arrays["drive"][t],
        seed=seed,
        config=config,
        simulator=simulator,
        start_time=float(dataset.arrays["frame_time"][t, k]),
    )
    return (result.capture_score, result.success_score), time.perf_counter() - started


def measure(name: str, dataset: Dataset, args: argparse.Namespace) -> dict[str, Any]:
    """Both sides on the frames of ``dataset`` that :func:`_places` picks."""
    seeds = frame_seeds(args.seed, dataset.n_trajectories * dataset.n_frames)
    # analyze's default continuation, as analyze resolves it (analyze_frame itself takes None as 0).
    config = AnalyzerConfig(expansions=args.expansions, continuation=default_continuation("mujoco"))
    tree_only = dataclasses.replace(config, continuation=0)
    times: dict[str, list[float]] = {side: [] for side in (*SIDES, "tree")}
    same = 0
    for t, frames in _places(dataset, args):
        friction, drive = float(dataset.arrays["friction"][t]), dataset.arrays["drive"][t]
        simulator = dataset.task.make_simulator(dataset.n_objects, friction, drive)
        for k in frames:
            frame = (dataset, t, k, seeds[t * dataset.n_frames + k], simulator)
            scores = {}
            for side in SIDES:
                with _row_by_row() if side == "before" else contextlib.nullcontext():
                    scores[side], seconds = _timed(*frame, config)
                times[side].append(seconds)
            same += scores["before"] == scores["after"]
            times["tree"].append(_timed(*frame, tree_only)[1])
    before, after = statistics.mean(times["before"]), statistics.mean(times["after"])
    return {
        "scene": name,
        "frames": len(times["after"]),
        "before_s": before,
        "after_s": after,
        "speedup": before / after,
        "same_scores": same,
        "tree_s": statistics.mean(times["tree"]),
    }


def _generated(scene: str, args: argparse.Namespace, workdir: Path) -> Dataset:
    task = get_task("scene", {"scene_file": str(ROOT / scene)})
    out = workdir / Path(scene).stem
    generate_dataset(
        task, n_objects=None, n_trajectories=args.trajectories, n_frames=args.frames, seed=args.seed, out=out
    )
    return load_dataset(out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenes", nargs="*", default=SCENES)
    parser.add_argument("--datasets", nargs="*", type=Path, default=[])
    parser.add_argument("--trajectories", type=int, default=2)
    parser.add_argument("--frames", type=int, default=4)
    parser.add_argument("--expansions", type=int, default=300)
    parser.add_argument("--seed", type=int, default=100)
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    machine = f"{describe_machine()}; load average {os.getloadavg()[0]:.2f} before"
    print(f"machine: {machine}")
    rows = []
    with tempfile.TemporaryDirectory() as workdir:
        sources = [(scene, lambda s=scene: _generated(s, args, Path(workdir))) for scene in args.scenes]
        sources += [(str(folder), lambda f=folder: load_dataset(f)) for folder in args.datasets]
        for name, source in sources:
            try:
                row = measure(name, source(), args)
            except EnergyMarginError as error:
                # Examples whose model comes from another package's assets (see their README).
                print(f"skip: {name}: {error}", flush=True)
                continue
            rows.append(row)
            print(
                f"{row['scene']}: before {row['before_s']:.4f} s, after {row['after_s']:.4f} s, "
                f"{row['speedup']:.2f}x, same scores {row['same_scores']}/{row['frames']}",
                flush=True,
            )
    print()
    print(
        "| scene | frames | row by row [s / frame] | batched [s / frame] | ratio | same scores "
        "| tree alone [s / frame] |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|")
    for row in rows:
        print(
            f"| {row['scene']} | {row['frames']} | {row['before_s']:.4f} | {row['after_s']:.4f} | "
            f"{row['speedup']:.2f}x | {row['same_scores']} / {row['frames']} | {row['tree_s']:.4f} |"
        )
    if args.out:
        settings = {key: getattr(args, key) for key in ("trajectories", "frames", "expansions", "seed")}
        results = {"machine": machine, "settings": settings, "load_after": os.getloadavg()[0], "scenes": rows}
        args.out.write_text(json.dumps(results, indent=2) + "\n")
        print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
