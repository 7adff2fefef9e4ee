"""Render time per picture and per second of video, and the size of a view and a video.

Usage::

    python benchmarks/bench_render.py [--out /tmp/bench-render] [--repeats 10] [--json docs/figures/bench_render.json]

For pushing (10 objects) and scooping (5 objects) a one-trajectory dataset is generated and
analysed (300 iterations); the script times MuJoCo's offscreen picture of the middle frame without
and with its tree (640 x 480, ``repeats`` pictures after one warm-up), the video of the roll-out at
30 pictures per second (MP4 and GIF), and the interactive view; it prints one JSON line per task
and, with ``--json``, writes them with the machine and the versions as a results file.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import statistics
import time
from pathlib import Path
from typing import Any

os.environ.setdefault("MUJOCO_GL", "egl")

from bench_analysis import machine
from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.run import analyze
from energy_margin.data.generate import generate_dataset
from energy_margin.data.scores_file import load_scores
from energy_margin.report.frame_tree import analysed_tree
from energy_margin.report.render import dataset_renderer
from energy_margin.report.video import render_video
from energy_margin.report.view import write_view
from energy_margin.runs.versions import engine_versions


def results_file(rows: dict[str, dict[str, Any]], repeats: int) -> dict[str, Any]:
    """What ``--json`` writes: the rows by task, with the command, date, machine and versions."""
    return {
        "command": "python benchmarks/bench_render.py --json FILE",
        "date": datetime.date.today().isoformat(),
        "machine": machine(),
        "versions": engine_versions(),
        "repeats": repeats,
        "tasks": rows,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", default="/tmp/bench-render")
    parser.add_argument("--repeats", type=int, default=10)
    parser.add_argument("--json", type=Path, help="also write the rows, machine and versions here")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows: dict[str, dict[str, Any]] = {}
    for task, n_objects in (("pushing", 10), ("scooping", 5)):
        directory = out / task
        dataset = generate_dataset(task, n_objects=n_objects, n_trajectories=1, n_frames=5, seed=0, out=directory)
        analyze(directory, AnalyzerConfig(expansions=300), seed=0, workers=1, progress=False)
        tree = analysed_tree(directory, 0, 2)
        with dataset_renderer(dataset, 0) as renderer:
            tick = time.perf_counter()
            renderer.render(tree.frame)
            first = time.perf_counter() - tick
            plain, with_tree = [], []
            for _ in range(args.repeats):
                tick = time.perf_counter()
                renderer.render(tree.frame)
                plain.append(time.perf_counter() - tick)
                tick = time.perf_counter()
                renderer.render(tree.frame, field=tree.field, likelihoods=tree.likelihoods)
                with_tree.append(time.perf_counter() - tick)
            backend = renderer.backend
        scores = load_scores(directory)
        mp4 = render_video(dataset, 0, out / f"{task}.mp4", scores=scores)
        gif = render_video(dataset, 0, out / f"{task}.gif", scores=scores)
        tick = time.perf_counter()
        view = write_view(tree, out / f"{task}-view.html")
        view_s = time.perf_counter() - tick
        rows[task] = {
            "task": task,
            "objects": n_objects,
            "backend": backend,
            "tree_nodes": tree.field.nodes,
            "first_picture_s": round(first, 3),
            "picture_s": round(statistics.median(plain), 4),
            "picture_with_tree_s": round(statistics.median(with_tree), 4),
            "video_pictures": mp4.frames,
            "mp4_s_per_video_s": round(mp4.total_s / mp4.seconds, 2),
            "mp4_drawing_s_per_video_s": round(mp4.render_s / mp4.seconds, 2),
            "mp4_bytes": mp4.path.stat().st_size,
            "mp4_kb": mp4.path.stat().st_size / 1e3,
            "gif_s_per_video_s": round(gif.total_s / gif.seconds, 2),
            "gif_bytes": gif.path.stat().st_size,
            "gif_kb": gif.path.stat().st_size / 1e3,
            "view_s": round(view_s, 2),
            "view_bytes": view.stat().st_size,
            "view_mb": view.stat().st_size / 1e6,
        }
        print(json.dumps(rows[task]), flush=True)
    if args.json is not None:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(results_file(rows, args.repeats), indent=2) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
