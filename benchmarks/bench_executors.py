"""Throughput of the executors and resident memory over a long run.

Usage::

    python benchmarks/bench_executors.py [--objects 5] [--trajectories 4] [--frames 10]
        [--expansions 100] [--ray] [--memory-frames 1000] [--out docs/figures/bench_executors.json]

Part 1 analyses the same dataset with ``analyze`` and the local executor with 1 and 2 workers (and
Ray with 2 workers when ``--ray`` is given), each into a fresh copy, and prints frames per second
and the per-frame overhead of the executor: ``wall time x workers / frames - mean frame runtime``
(start-up, dataset loading, validation, process or actor start, result transport, journal writes).

Part 2 analyses ``--memory-frames`` frames one after another in this process with one
``FrameAnalyzer`` and prints the resident set size along the way and its peak.

``--out`` keeps both tables, the machine and the load average before the run.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

from bench_analysis import machine
from checkout import write_figures
from energy_margin.analysis.frame import AnalyzerConfig, FrameAnalyzer
from energy_margin.analysis.run import analyze
from energy_margin.data.dataset import load_dataset
from energy_margin.data.generate import generate_dataset
from energy_margin.data.scores_file import load_scores


def resident_mb() -> float:
    with open("/proc/self/statm", encoding="ascii") as stream:
        pages = int(stream.read().split()[1])
    return pages * resource.getpagesize() / 2**20


def time_executors(args: argparse.Namespace, work: Path) -> list[dict[str, Any]]:
    """Part 1: one row per executor and worker count, each analysing a fresh copy of one dataset."""
    source = work / "source"
    generate_dataset(
        "pushing", n_objects=args.objects, n_trajectories=args.trajectories, n_frames=args.frames, seed=0, out=source
    )
    config = AnalyzerConfig(expansions=args.expansions)
    runs = [("local", 1), ("local", 2)] + ([("ray", 2)] if args.ray else [])
    frames = args.trajectories * args.frames
    print(
        f"pushing, n_o = {args.objects}, {frames} frames, {args.expansions} iterations per frame\n\n"
        "| executor | workers | wall [s] | frames/s | mean frame runtime [s] | executor overhead per frame [ms] |\n"
        "|---|---:|---:|---:|---:|---:|"
    )
    rows: list[dict[str, Any]] = []
    reference = None
    for kind, workers in runs:
        target = work / f"{kind}-{workers}"
        shutil.copytree(source, target)
        started = time.perf_counter()
        analyze(target, config, seed=0, workers=workers, executor=kind, progress=False)
        wall = time.perf_counter() - started
        scores = load_scores(target)
        runtime = statistics.fmean(scores["runtime_s"])
        overhead = wall * workers / frames - runtime
        same = (
            ""
            if reference is None
            else (" (same scores)" if (scores["capture_score"] == reference).all() else " (DIFFERENT)")
        )
        reference = scores["capture_score"] if reference is None else reference
        row = {
            "executor": f"{kind}{same}",
            "workers": workers,
            "wall_s": wall,
            "frames_per_s": frames / wall,
            "frame_runtime_s": runtime,
            "overhead_ms": 1000 * overhead,
        }
        rows.append(row)
        print(
            f"| {row['executor']} | {workers} | {wall:.2f} | {frames / wall:.1f} | {runtime:.4f} | "
            f"{1000 * overhead:.1f} |"
        )
    return rows


def track_memory(args: argparse.Namespace, work: Path) -> list[dict[str, Any]]:
    """Part 2: the resident set size of this process while one analyzer scores frame after frame."""
    print(
        f"\nresident memory over {args.memory_frames} frames (n_o = {args.memory_objects}, "
        f"{args.memory_iterations} iterations, one process)\n"
    )
    memory_set = work / "memory"
    generate_dataset("pushing", n_objects=args.memory_objects, n_trajectories=10, n_frames=10, seed=1, out=memory_set)
    dataset = load_dataset(memory_set)
    analyzer = FrameAnalyzer(dataset, AnalyzerConfig(expansions=args.memory_iterations), seed=0)
    total = dataset.n_trajectories * dataset.n_frames
    rows = [{"frames": 0, "resident_mib": resident_mb()}]
    for count in range(1, args.memory_frames + 1):
        analyzer(count % total)
        if count in (10, 100, 250, 500, 750, 1000) or count == args.memory_frames:
            rows.append({"frames": count, "resident_mib": resident_mb()})
    print("| frames analysed | resident [MiB] |\n|---:|---:|")
    for row in rows:
        print(f"| {row['frames']} | {row['resident_mib']:.1f} |")
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--objects", type=int, default=5)
    parser.add_argument("--trajectories", type=int, default=4)
    parser.add_argument("--frames", type=int, default=10)
    parser.add_argument("--expansions", type=int, default=100)
    parser.add_argument("--ray", action="store_true", help="also measure the Ray executor")
    parser.add_argument("--memory-frames", type=int, default=1000)
    parser.add_argument("--memory-objects", type=int, default=10)
    parser.add_argument("--memory-iterations", type=int, default=50)
    parser.add_argument("--out", type=Path, help="results JSON")
    args = parser.parse_args()
    figures: dict[str, Any] = {
        "command": "python benchmarks/bench_executors.py --ray --out FILE",
        "machine": machine(),
        "load_before": os.getloadavg()[0],
        "settings": {key: value for key, value in vars(args).items() if key != "out"},
    }
    work = Path(tempfile.mkdtemp(prefix="bench-executors-"))
    try:
        figures["executors"] = time_executors(args, work)
        figures["memory"] = track_memory(args, work)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    figures["peak_resident_mib"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"\npeak resident memory of this process: {figures['peak_resident_mib']:.1f} MiB")
    write_figures(args.out, figures)


if __name__ == "__main__":
    main()
